// A multi-sortie plan as the page draws it: each sortie's look (colour and dash), which buoy flies in which
// sortie, and the words for a sortie. A plan here is a POST /plans answer or a mission: both carry `sorties`
// (SortieOut: index, order, route, predicted_energy_wh, ...) and `energy` (null without energy planning).
import { svg } from "./dom.js";

// Okabe & Ito's colour-blind-safe palette (the report draws with the same, gcs/reports/report.py SORTIE_COLOURS),
// without its yellow and black, which vanish on the map's light grid or read as the vehicle's track.
const PALETTE = ["#0072b2", "#e69f00", "#009e73", "#cc79a7", "#d55e00", "#56b4e9"];
// Past six sorties the colours repeat with another dash, so no two routes look alike.
const DASHES = ["8 6", "2 5", "12 4 2 4"];
const SINGLE_TOUR = { colour: "#1f6fb2", dash: "8 6" }; // one sortie: the route as it always looked

export const isMultiSortie = (plan) => Boolean(plan && plan.sorties && plan.sorties.length > 1);

// Whether the plan has anything per sortie to show: several sorties, or one with an energy prediction.
export const hasSortieFigures = (plan) => isMultiSortie(plan) || Boolean(plan && plan.energy);

// sortie: 0-based index -> {colour, dash} of its route, legend swatch and buoy markers
export function sortieLook(sortie) {
  return {
    colour: PALETTE[sortie % PALETTE.length],
    dash: DASHES[Math.floor(sortie / PALETTE.length) % DASHES.length],
  };
}

// How the plan draws sortie k's route: in the sortie's look, or as the one route always looked.
export const routeLook = (plan, sortie) => (isMultiSortie(plan) ? sortieLook(sortie) : SINGLE_TOUR);

// Map buoy index -> the 0-based sortie that visits it (empty for a single tour, whose buoys keep their look).
export function sortieOfBuoy(plan) {
  const sortieOf = new Map();
  if (isMultiSortie(plan)) plan.sorties.forEach((s) => s.order.forEach((buoy) => sortieOf.set(buoy, s.index)));
  return sortieOf;
}

const wattHours = (value) => (value == null ? "–" : `${Number(value).toFixed(1)} Wh`);

// The legend's line for one sortie: "sortie 2: 5 buoys, predicted 12.1 Wh"; a fleet mission's share (a sortie
// with a vehicle): "vehicle 3: 4 buoys, about 95 s".
export function sortieLabel(sortie) {
  if (sortie.vehicle != null) {
    return `vehicle ${sortie.vehicle}: ${sortie.order.length} buoys, about ${Math.round(sortie.predicted_time_s)} s`;
  }
  const predicted = sortie.predicted_energy_wh == null ? "" : `, predicted ${wattHours(sortie.predicted_energy_wh)}`;
  return `sortie ${sortie.index + 1}: ${sortie.order.length} buoys${predicted}`;
}

// The energy model's error on a flown sortie, in % of what was used: (used - predicted) / used.
export function energyErrorPct(sortie) {
  const { used_energy_wh: used, predicted_energy_wh: predicted } = sortie;
  if (used == null || predicted == null || used <= 0) return null;
  return (100 * (used - predicted)) / used;
}

// A sortie has flown once the vehicle's battery figures for it are in.
export const hasFlown = (sortie) => sortie.used_energy_wh != null || sortie.landing_charge_pct != null;

// A short stroke in a sortie's look (an SVG line: its colour and dash are attributes, not inline style, so the
// page's Content-Security-Policy has nothing to allow).
export function swatch(look) {
  const stroke = { stroke: look.colour, "stroke-width": 3, "stroke-dasharray": look.dash };
  const line = svg("line", { x1: 1, y1: 5, x2: 15, y2: 5, ...stroke });
  return svg("svg", { width: 16, height: 10, class: "swatch" }, line);
}
