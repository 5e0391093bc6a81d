// The words and looks of a buoy's inspection (GET /missions/{id}/inspections: InspectionOut): each verdict's symbol,
// word and class (told apart by the symbol as well as by the colour), and each finding in plain words with its
// figures. The report says the same (gcs/reports/inspection_report.py, describe_finding).
import { h } from "./dom.js";

// "pending": the mission is under way and the buoy not judged yet (no record)
const VERDICTS = {
  ok: { symbol: "✓", word: "ok" },
  defect: { symbol: "✗", word: "defect" },
  not_inspected: { symbol: "?", word: "not inspected" },
  pending: { symbol: "…", word: "pending" },
};
export const VERDICT_ORDER = ["ok", "defect", "not_inspected", "pending"];

// verdict -> {key, symbol, word}; a verdict the page does not know keeps its own name as its word
export function verdictLook(verdict) {
  if (Object.hasOwn(VERDICTS, verdict)) return { key: verdict, ...VERDICTS[verdict] };
  return { key: "unknown", symbol: "?", word: String(verdict) };
}

// The verdict as a small round badge: its symbol in its colour (style.css .verdict-<key>), its word on hover and
// for screen readers, the verdict itself in data-verdict.
export function verdictBadge(verdict) {
  const look = verdictLook(verdict);
  const attributes = { class: `verdict-badge verdict-${look.key}`, "data-verdict": String(verdict) };
  return h("span", { ...attributes, title: look.word, "aria-label": look.word, role: "img" }, look.symbol);
}

const fixed = (value, digits = 1) => (typeof value === "number" ? value.toFixed(digits) : "?");
const colours = (value) => (Array.isArray(value) ? value.join("/") : String(value));

// One finding ({code, ...figures}) in plain words: "off station: 7.3 m from its charted position, bearing 45° (swing
// radius 3.0 m)". A code the page does not know: its name and its figures as given.
export function findingText(finding) {
  const f = finding;
  switch (f.code) {
    case "off_station":
      return (
        `off station: ${fixed(f.offset_m)} m from its charted position, bearing ${fixed(f.bearing_deg, 0)}° ` +
        `(swing radius ${fixed(f.swing_radius_m)} m)`
      );
    case "light_out":
      return `light out: charted ${f.charted}, seen ${f.seen}`;
    case "wrong_character":
      return `wrong light character: charted ${f.charted}, seen ${f.seen}`;
    case "wrong_period":
      return `wrong light period: charted ${fixed(f.charted_period_s)} s, seen ${fixed(f.seen_period_s)} s`;
    case "wrong_colour":
      return `wrong light colour: charted ${f.charted}, seen ${f.seen}`;
    case "wrong_body_colour":
      return `wrong body colour: ${colours(f.expected)} expected, ${colours(f.seen)} seen`;
    case "not_found":
      return `not found in any of its ${f.frames} frames (${f.why})`;
    default: {
      const figures = Object.entries(f).filter(([name]) => name !== "code");
      const text = figures.map(([name, value]) => `${name} ${colours(value)}`).join(", ");
      return text ? `${f.code}: ${text}` : String(f.code);
    }
  }
}

// What else a record says, as lines: the light charted and read, how far from its charted position it was seen,
// and why it was not inspected.
export function recordLines(record) {
  const lines = [];
  const charted = record.charted.light ?? "unlit";
  if (record.light_seen != null) lines.push(`light: charted ${charted}, read ${record.light_seen}`);
  if (record.offset_m != null) lines.push(`seen ${fixed(record.offset_m)} m from its charted position`);
  if (record.reason) lines.push(`why: ${record.reason}`);
  return lines;
}
