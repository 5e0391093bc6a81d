// A buoy's camera frames, over the map's right side: its best frame large with what its inspection found, and its
// burst as a strip of lazy-loaded thumbnails (at most MAX_THUMBNAILS, spread evenly over the burst, with how many
// more there are); a thumbnail clicked shows large. Opened by a click on a buoy's marker or its inspection row.
import { byId, h } from "./dom.js";
import { findingText, recordLines, verdictBadge, verdictLook } from "./verdicts.js";

export const MAX_THUMBNAILS = 40;

let shown = null; // {index, recordText, large}: the buoy shown, its record as shown (JSON), the frame shown large

// At most `max` of `items`, the first and the last among them, evenly spread (all of them when there are no more).
export function spreadEvenly(items, max) {
  if (items.length <= max) return items.map((item, position) => ({ item, position }));
  return Array.from({ length: max }, (_, k) => {
    const position = Math.round((k * (items.length - 1)) / (max - 1));
    return { item: items[position], position };
  });
}

// The frame a record opens on: its best, else its first (null: it has none).
const firstShown = (record) => record.best_frame ?? record.frames[0] ?? null;

// row: {index, id, label, verdict, record} (state.inspectionRows); opens the gallery on it, its best frame large.
export function showGallery(row) {
  const record = row.record;
  shown = { index: row.index, recordText: JSON.stringify(record), large: firstShown(record) };
  draw(row);
  byId("gallery").hidden = false;
}

// The rows anew (a record may have grown, e.g. judged since): the gallery's buoy redrawn if its record changed,
// keeping the frame shown large when it is still one of its frames; closed when the buoy has no record any more.
export function refreshGallery(rows) {
  if (shown === null) return;
  const row = rows.find((r) => r.index === shown.index);
  if (!row || !row.record) return closeGallery();
  const recordText = JSON.stringify(row.record);
  if (recordText === shown.recordText) return;
  const keep = row.record.frames.includes(shown.large);
  shown = { index: row.index, recordText, large: keep ? shown.large : firstShown(row.record) };
  draw(row);
}

export function closeGallery() {
  shown = null;
  byId("gallery").hidden = true;
  byId("gallery-large").removeAttribute("src");
  byId("gallery-strip").replaceChildren();
}

export function wireGallery() {
  byId("gallery-close").addEventListener("click", closeGallery);
}

function draw(row) {
  const record = row.record;
  const look = verdictLook(record.verdict);
  byId("gallery-title").replaceChildren(verdictBadge(record.verdict), ` ${row.label} ${record.buoy}: ${look.word}`);
  const lines = [...record.findings.map(findingText), ...recordLines(record)];
  byId("gallery-details").replaceChildren(...lines.map((line) => h("li", {}, line)));
  drawStrip(record);
  showLarge(record, shown.large);
}

function drawStrip(record) {
  const frames = record.frames;
  const thumbnails = spreadEvenly(frames, MAX_THUMBNAILS).map(({ item: url, position }) => {
    const alt = `frame ${position + 1} of ${frames.length}`;
    const image = h("img", { src: url, loading: "lazy", alt, width: 64, height: 36 });
    const button = h("button", { type: "button", class: "thumbnail", "data-frame": url, title: alt }, image);
    button.addEventListener("click", () => showLarge(record, url));
    return button;
  });
  byId("gallery-strip").replaceChildren(...thumbnails);
  const rest = frames.length - thumbnails.length;
  byId("gallery-more").textContent =
    frames.length === 0
      ? "no frame of this buoy was stored"
      : `${frames.length} ${frames.length === 1 ? "frame" : "frames"}` +
        (rest > 0 ? `: ${thumbnails.length} shown, ${rest} more not shown` : "");
}

// Frame `url` large (null: none), its thumbnail marked.
function showLarge(record, url) {
  shown.large = url;
  const large = byId("gallery-large");
  large.hidden = url == null;
  if (url == null) large.removeAttribute("src");
  else large.src = url;
  const position = record.frames.indexOf(url);
  const best = url != null && url === record.best_frame ? " (the best)" : "";
  large.alt = url == null ? "" : `frame ${position + 1} of ${record.frames.length} of buoy ${record.buoy}`;
  byId("gallery-caption").textContent = url == null ? "" : `frame ${position + 1} of ${record.frames.length}${best}`;
  for (const button of byId("gallery-strip").children) {
    const selected = button.dataset.frame === url;
    button.classList.toggle("selected", selected);
    button.setAttribute("aria-pressed", String(selected));
  }
}
