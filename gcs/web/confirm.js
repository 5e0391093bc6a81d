// The confirmation of a consequential action, in the page's own <dialog> (index.html #confirm-dialog) rather than
// window.confirm: a modal the browser keeps keyboard-accessible (focus inside it, Escape cancels), styled as the
// page, and one that kiosk browsers and Playwright do not auto-answer or block. Cancel has the focus first, so a
// stray Enter does not launch anything. Texts go in as text.
import { byId } from "./dom.js";

// {title, text, warning (optional), confirm: the confirming button's label} -> a promise of true (confirmed) or
// false (Cancel, Escape, or the dialog closed any other way)
export function confirmAction({ title, text, warning = "", confirm }) {
  const dialog = byId("confirm-dialog");
  if (dialog.open) return Promise.resolve(false); // one question at a time: a second click asks nothing
  byId("confirm-title").textContent = title;
  byId("confirm-text").textContent = text;
  byId("confirm-warning").textContent = warning;
  byId("confirm-warning").hidden = !warning;
  byId("confirm-ok").textContent = confirm;
  dialog.returnValue = "";
  return new Promise((resolve) => {
    // form method=dialog sets returnValue to the button's value; Escape closes with it left ""
    dialog.addEventListener("close", () => resolve(dialog.returnValue === "confirm"), { once: true });
    dialog.showModal();
    byId("confirm-cancel").focus();
  });
}
