// Building page elements from data without HTML strings: children that are strings become text nodes, so a
// buoy name or a vehicle's STATUSTEXT can never turn into markup.

// h("a", {href: url, download: ""}, "text", otherElement) -> <a href=... download>text…</a>
export function h(tag, attributes = {}, ...children) {
  const element = document.createElement(tag);
  for (const [name, value] of Object.entries(attributes)) element.setAttribute(name, value);
  element.append(...children);
  return element;
}

// The same for SVG: svg("line", {x1: 0, stroke: "#000"}) (attributes, never inline style or markup).
export function svg(tag, attributes = {}, ...children) {
  const element = document.createElementNS("http://www.w3.org/2000/svg", tag);
  for (const [name, value] of Object.entries(attributes)) element.setAttribute(name, value);
  element.append(...children);
  return element;
}

export const byId = (id) => document.getElementById(id);
