// The routes a plan flies as the page draws them (its legs): each leg's look (colour and dash), which buoy
// flies in which leg, and the words for a leg. A plan here is a POST /plans answer or a mission: both carry
// `sorties` (SortieOut: index, order, route, predicted_energy_wh, ...) and `energy` (null without energy
// planning); a fleet mission flies none of its own but its `fleet.shares` (FleetShareOut: sysid, buoys, route),
// one leg per vehicle.
import { svg } from "./dom.js";

// Okabe & Ito's colour-blind-safe palette (the report draws with the same, gcs/reports/report.py SORTIE_COLOURS),
// without its yellow and black, which vanish on the map's light grid or read as the vehicle's track.
const PALETTE = ["#0072b2", "#e69f00", "#009e73", "#cc79a7", "#d55e00", "#56b4e9"];
// Past six sorties the colours repeat with another dash, so no two routes look alike.
const DASHES = ["8 6", "2 5", "12 4 2 4"];
const SINGLE_TOUR = { colour: "#1f6fb2", dash: "8 6" }; // one sortie: the route as it always looked

// The plan's legs, [{index, order, route, label}]: a fleet mission's shares, else its sorties (a single tour's
// one sortie is its route).
export function legsOf(plan) {
  if (!plan) return [];
  if (plan.fleet) {
    return plan.fleet.shares.map((share, index) => ({
      index,
      order: share.buoys,
      route: share.route,
      label: `vehicle ${share.sysid}: ${share.buoys.length} buoys, about ${Math.round(share.predicted_time_s)} s`,
    }));
  }
  return plan.sorties.map((sortie) => ({ ...sortie, label: sortieLabel(sortie) }));
}

const severalLegs = (plan) => legsOf(plan).length > 1;

// Whether the plan has anything per leg to show: several legs, or one with an energy prediction.
export const hasSortieFigures = (plan) => severalLegs(plan) || Boolean(plan && plan.energy);

// sortie: 0-based index -> {colour, dash} of its route, legend swatch and buoy markers
export function sortieLook(sortie) {
  return {
    colour: PALETTE[sortie % PALETTE.length],
    dash: DASHES[Math.floor(sortie / PALETTE.length) % DASHES.length],
  };
}

// How the plan draws leg k's route: in the leg's look, or as the one route always looked.
export const routeLook = (plan, leg) => (severalLegs(plan) ? sortieLook(leg) : SINGLE_TOUR);

// Map buoy index -> the 0-based leg that visits it (empty for a single tour, whose buoys keep their look).
export function sortieOfBuoy(plan) {
  const sortieOf = new Map();
  if (severalLegs(plan)) legsOf(plan).forEach((leg) => leg.order.forEach((buoy) => sortieOf.set(buoy, leg.index)));
  return sortieOf;
}

const wattHours = (value) => (value == null ? "–" : `${Number(value).toFixed(1)} Wh`);

// The legend's line for one sortie: "sortie 2: 5 buoys, predicted 12.1 Wh".
function sortieLabel(sortie) {
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
