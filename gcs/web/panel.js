// The side panel and header: the flight settings form, messages, the plan summary, the watched mission's
// status, progress and tracking figures, and the vehicle badge. Every text from the service goes in as text.
import { byId, h } from "./dom.js";

export const formatNumber = (value, digits = 1) => (value == null ? "–" : Number(value).toFixed(digits));
const km = (metres) => (metres / 1000).toFixed(3);

// Shown under the buttons: an error (red) or, with ok, a progress note (green).
export function say(text, ok = false) {
  byId("message").textContent = text;
  byId("message").className = ok ? "ok" : "";
}

export function token() {
  return byId("token").value.trim();
}

// The form's part of a plan or mission request (everything except depot and buoys).
export function flightSettings() {
  const number = (id) => Number(byId(id).value);
  return {
    altitude_m: number("altitude"),
    speed_m_s: number("speed"),
    dwell_s: number("dwell"),
    acceptance_radius_m: number("radius"),
    planner: { method: byId("method").value, seed: 0, time_limit_s: 2.0 },
  };
}

// Which kind of point a click on the map places: "buoy" or "depot".
export function placing() {
  return document.querySelector('input[name="place"]:checked').value;
}

export function showBuoyCount(count) {
  byId("buoy-count").textContent = `${count} buoys`;
}

// plan: a POST /plans answer or a mission (both carry length_m, method, elapsed_s, input_order_length_m, ...)
export function showPlanSummary(plan) {
  byId("plan-summary").replaceChildren(
    "Route ",
    h("b", {}, `${km(plan.length_m)} km`),
    ` (${plan.method}, ${plan.elapsed_s.toFixed(2)} s)`,
    h("br"),
    `input order ${km(plan.input_order_length_m)} km: `,
    h("b", {}, `${plan.improvement_pct.toFixed(1)} % shorter`),
  );
}

export function clearPlanSummary() {
  byId("plan-summary").replaceChildren();
}

// The lines of tracking figures of a mission that has flown (none before).
function figureLines(mission) {
  const t = mission.tracking;
  if (!t) return [];
  const reached = mission.buoy_results.filter((b) => b.reached).length;
  return [
    `RMS cross-track ${formatNumber(t.rms_cross_track_m, 2)} m, max ${formatNumber(t.max_cross_track_m, 2)} m`,
    `flown ${formatNumber(t.distance_flown_m, 0)} m of ${formatNumber(t.planned_length_m, 0)} m planned, ` +
      `${formatNumber(t.flight_time_s)} s`,
    `buoys reached ${reached} / ${mission.buoy_results.length}`,
  ];
}

// mission: a GET /missions/{id} answer. Its reason may quote the vehicle's STATUSTEXT: text only.
export function showMission(mission) {
  const reason = mission.reason ? ` – ${mission.reason}` : "";
  byId("mission-status").textContent = `#${mission.id}: ${mission.status}${reason}`;
  const progress = mission.progress || {};
  byId("progress").max = Math.max(1, progress.buoys || mission.order.length);
  byId("progress").value = progress.visited || 0;
  const lines = figureLines(mission);
  byId("figures").replaceChildren(...lines.flatMap((line, i) => (i ? [h("br"), line] : [line])));
}

// vehicle: the live stream's vehicle part (connected, armed, mode)
export function showVehicleLink(vehicle) {
  const badge = byId("link-status");
  badge.textContent = vehicle.connected ? `vehicle: ${vehicle.armed ? "armed" : "disarmed"}` : "vehicle: disconnected";
  badge.className = vehicle.connected ? "badge" : "badge off";
  byId("mode").textContent = vehicle.connected ? vehicle.mode : "";
  // the vehicle's latest STATUSTEXT (its own words: text only), the earlier ones on hover
  const texts = (vehicle.connected && vehicle.status_texts) || [];
  byId("vehicle-text").textContent = texts.length ? texts[texts.length - 1] : "";
  byId("vehicle-text").title = texts.join("\n");
}
