// The panel's inspection section: the camera the watched mission inspects with, how many buoys have which verdict,
// the links to the inspections' CSV and GeoJSON exports, and a row per buoy (in visiting order, labelled as its
// marker): its verdict, its findings in plain words, its light, why it was not inspected. A row clicked opens the
// buoy's frames (gallery.js). Every text from the service (ids, reasons, readings, the camera's names) is text.
import { byId, h } from "./dom.js";
import { findingText, recordLines, VERDICT_ORDER, verdictBadge, verdictLook } from "./verdicts.js";

let shownKey = null; // what the section shows, so that an unchanged one is not rebuilt (and keeps its focus)

// rows: state.inspectionRows() ([{index, id, label, verdict, record, arrival_s}]; none: the section hides) with
// reached: when the buoy was reached as the operator reads it (null: not reached); key: changes whenever the rows'
// records do; camera: progress.camera (null: none reported); exports: {csv, geojson} URLs; onOpen(row) when a row
// is clicked.
export function showInspections(rows, key, camera, exports, onOpen) {
  const fullKey = JSON.stringify([key, camera, exports, rows.map((r) => [r.index, r.label, r.verdict, r.reached])]);
  if (fullKey === shownKey) return;
  shownKey = fullKey;
  byId("inspection-section").hidden = rows.length === 0;
  byId("inspection-camera").textContent = `camera: ${camera ?? "none reported"}`;
  byId("inspection-counts").textContent = countsLine(rows);
  byId("inspection-exports").replaceChildren(
    "export ",
    h("a", { href: exports.csv, download: "", "data-testid": "inspections-csv" }, "inspections.csv"),
    h("a", { href: exports.geojson, download: "", "data-testid": "inspections-geojson" }, "inspections.geojson"),
  );
  byId("inspection-list").replaceChildren(...rows.map((row) => listRow(row, onOpen)));
}

// "1 ok, 2 defect, 1 not inspected, 3 pending" (only the verdicts present)
function countsLine(rows) {
  const count = (verdict) => rows.filter((row) => row.verdict === verdict).length;
  return VERDICT_ORDER.filter((v) => count(v) > 0)
    .map((v) => `${count(v)} ${verdictLook(v).word}`)
    .join(", ");
}

function listRow(row, onOpen) {
  const look = verdictLook(row.verdict);
  const title = h(
    "button",
    { type: "button", class: "inspection-buoy", title: "show its frames" },
    verdictBadge(row.verdict),
    h("b", {}, `${row.label}`),
    ` ${row.id ?? `buoy ${row.index + 1}`}: ${look.word}`,
  );
  title.addEventListener("click", () => onOpen(row));
  const details = row.record
    ? [...row.record.findings.map(findingText), ...recordLines(row.record)].map((line) => h("li", {}, line))
    : [];
  if (row.reached) {
    const title = `vehicle time ${row.arrival_s.toFixed(1)} s (since its boot)`;
    details.unshift(h("li", { title, "data-testid": "inspection-reached" }, `reached ${row.reached}`));
  }
  const attributes = { class: "inspection-row", "data-testid": "inspection-row", "data-verdict": row.verdict };
  return h("li", attributes, title, h("ul", { class: "findings" }, ...details));
}
