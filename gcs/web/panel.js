// The side panel and header: the battery gauge, the flight settings form (with the battery options), messages,
// the plan summary, the watched mission's status, progress, tracking figures and per-sortie energy table, and the
// vehicle badge. Every text from the service or the vehicle goes in as text.
import { byId, h } from "./dom.js";
import { energyErrorPct, hasFlown, hasSortieFigures, routeLook, swatch } from "./sorties.js";
import { MissionStatus } from "./status.js";
import { duration } from "./times.js";

export const formatNumber = (value, digits = 1) => (value == null ? "–" : Number(value).toFixed(digits));
const km = (metres) => (metres / 1000).toFixed(3);

// Shown under the buttons: an error (red) or, with ok, a progress note (green).
export function say(text, ok = false) {
  byId("message").textContent = text;
  byId("message").className = ok ? "ok" : "";
}

// While a plan or mission request is in flight: Plan disabled (Fly too, by the control bar), and "<note> N s"
// beside them, counting (a
// plan takes up to its time limit; the message line below keeps the last result). Returns what ends it.
export function showBusy(note) {
  const started = performance.now();
  const indicator = byId("busy");
  const buttons = [byId("plan")]; // Fly is the control bar's: it follows state.busy (controls.js)
  const tick = () => {
    indicator.textContent = `${note} ${Math.floor((performance.now() - started) / 1000)} s`;
  };
  tick();
  const timer = setInterval(tick, 1000);
  indicator.hidden = false;
  buttons.forEach((button) => (button.disabled = true));
  return () => {
    clearInterval(timer);
    indicator.hidden = true;
    buttons.forEach((button) => (button.disabled = false));
  };
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
    ...batterySettings(),
  };
}

// A field left empty: null (the service's default), else its number as typed (the service checks the range
// and answers a 422 naming the field).
function optionalNumber(id) {
  const text = byId(id).value.trim();
  return text === "" ? null : Number(text);
}

// With "plan sorties" ticked: battery (reserve empty: the vehicle's low-battery threshold; capacity empty: the
// vehicle's pack) and, with a wind speed, the forecast wind. Unticked: one tour, no energy planning.
function batterySettings() {
  if (!byId("plan-sorties").checked) return {};
  const reserve = optionalNumber("reserve");
  const capacity = optionalNumber("capacity");
  const battery = { reserve_pct: reserve ?? "vehicle", ...(capacity == null ? {} : { capacity_mah: capacity }) };
  const windSpeed = optionalNumber("wind-speed");
  if (windSpeed == null) return { battery };
  return { battery, wind: { speed_m_s: windSpeed, from_deg: optionalNumber("wind-from") ?? 0 } };
}

// The battery fields are editable only with "plan sorties" ticked.
export function wireBatteryOptions() {
  const box = byId("plan-sorties");
  const sync = () => byId("battery-fields").toggleAttribute("disabled", !box.checked);
  box.addEventListener("change", sync);
  sync();
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
    ...energySummary(plan),
    ...fleetSummary(plan),
  );
}

// A fleet's plan (POST /plans with vehicles): how the buoys are shared and when the last vehicle is home.
function fleetSummary(plan) {
  const fleet = plan.fleet;
  if (!fleet) return [];
  const shares = fleet.shares.map((s) => `vehicle ${s.sysid}: ${s.buoys.length}`).join(", ");
  const home = `all home in about ${duration(fleet.makespan_s)}`;
  return [h("br"), h("b", {}, `${fleet.shares.length} vehicles`), ` (${shares} buoys); ${home}`];
}

// With energy planning: how many sorties, their predicted total and the battery they were planned for.
function energySummary(plan) {
  const e = plan.energy;
  if (!e) return [];
  const total = plan.sorties.reduce((sum, s) => sum + (s.predicted_energy_wh ?? 0), 0);
  const pack = `${formatNumber(e.pack.capacity_mah, 0)} mAh pack (${e.pack_source})`;
  const { speed_m_s: speed, from_deg: from } = e.wind;
  const wind = speed ? `wind ${formatNumber(speed)} m/s from ${formatNumber(from, 0)}°` : "calm";
  return [
    h("br"),
    h("b", {}, `${plan.sorties.length} ${plan.sorties.length === 1 ? "sortie" : "sorties"}`),
    `, ${formatNumber(total)} Wh predicted; budget ${formatNumber(e.budget_wh)} Wh a sortie, ` +
      `reserve ${formatNumber(e.reserve_pct, 0)} %, margin ${formatNumber(e.margin_pct, 0)} %, ${pack}, ${wind}`,
  ];
}

export function clearPlanSummary() {
  byId("plan-summary").replaceChildren();
}

// A fleet mission's closest approach of two vehicles in the air, once it has ended (gcs.missions.fleet_missions).
function separationLines(fleet) {
  const s = fleet.separation;
  if (s.min_distance_m == null) return [];
  return [
    `closest approach ${formatNumber(s.min_distance_m)} m (horizontal ${formatNumber(s.min_horizontal_m)} m, ` +
      `vertical ${formatNumber(s.min_vertical_m)} m; layers ${formatNumber(fleet.layer_gap_m)} m apart)`,
  ];
}

// The lines of tracking figures of a mission that has flown (none before).
function figureLines(mission) {
  if (mission.fleet) return separationLines(mission.fleet);
  const t = mission.tracking;
  if (!t) return [];
  const reached = mission.buoy_results.filter((b) => b.reached).length;
  // plain words first; the technical names and exact figures in the line's title (figureLine)
  return [
    [
      `off the route ${formatNumber(t.rms_cross_track_m, 2)} m on average, ` +
        `${formatNumber(t.max_cross_track_m, 2)} m at most`,
      `RMS cross-track error ${formatNumber(t.rms_cross_track_m, 3)} m, ` +
        `maximum ${formatNumber(t.max_cross_track_m, 3)} m`,
    ],
    [
      `flown ${formatNumber(t.distance_flown_m, 0)} m of ${formatNumber(t.planned_length_m, 0)} m planned, ` +
        `in ${duration(t.flight_time_s)}`,
      `flight time ${formatNumber(t.flight_time_s)} s`,
    ],
    `buoys reached ${reached} / ${mission.buoy_results.length}`,
  ];
}

// mission: a GET /missions/{id} answer. Its reason may quote the vehicle's STATUSTEXT: text only.
export function showMission(mission) {
  const reason = mission.reason ? ` – ${mission.reason}` : "";
  byId("mission-status").textContent = `#${mission.id}: ${mission.status}${reason}`;
  // between sorties, the mission waits for the operator: the status asks for attention until the swap
  byId("mission-status").classList.toggle("attention", mission.status === MissionStatus.waiting_for_battery);
  const progress = mission.progress || {};
  byId("preflight").textContent = (progress.preflight || []).map(preflightLine).join("\n");
  byId("progress").max = Math.max(1, progress.buoys || mission.order.length);
  byId("progress").value = progress.visited || 0;
  byId("sortie-progress").textContent = sortieProgress(mission);
  // a line is its text, or [text, its technical detail] (shown on hover)
  const lines = figureLines(mission).map((line) =>
    Array.isArray(line) ? h("span", { title: line[1] }, line[0]) : line,
  );
  byId("figures").replaceChildren(...lines.flatMap((line, i) => (i ? [h("br"), line] : [line])));
  showSortieTable(mission);
}

// "sortie 2 of 3" while one flies (or flew last); "3 sorties" before; nothing for a single tour. A fleet
// mission: how many vehicles share it.
function sortieProgress(mission) {
  if (mission.fleet) return `${mission.fleet.shares.length} vehicles`;
  const { sortie, sorties } = mission.progress || {};
  if (!(sorties > 1)) return "";
  return sortie == null ? `${sorties} sorties` : `sortie ${sortie + 1} of ${sorties}`;
}

// [heading, what it means (the heading's tooltip)]
const SORTIE_COLUMNS = [
  ["#", "sortie"],
  ["buoys", "the sortie's buoys"],
  ["pred. Wh", "energy predicted by the energy model"],
  ["used Wh", "energy the vehicle reported consumed (BATTERY_STATUS)"],
  ["err. %", "(used - predicted) / used"],
  ["margin %", "budget left after the predicted energy"],
  ["landing %", "charge at landing: predicted / measured"],
  ["warn.", "battery warning: the worst battery state the vehicle reported in the sortie"],
];

const FLEET_COLUMNS = [
  ["vehicle", "its system id"],
  ["buoys", "its share of the buoys"],
  ["inspected", "its buoys inspected so far"],
  ["status", "its part mission"],
  ["pred. s", "predicted flight time, take-off to landing"],
  ["layer m", "its altitude"],
];

// A fleet mission: a row per vehicle's share, in its route's colour.
function showFleetTable(mission) {
  const row = (share, index) =>
    h(
      "tr",
      {},
      h("td", {}, swatch(routeLook(mission, index)), String(share.sysid)),
      ...[
        String(share.buoys.length),
        String(share.visited_buoys.length),
        share.status,
        formatNumber(share.predicted_time_s, 0),
        formatNumber(share.altitude_m, 0),
      ].map((text) => h("td", {}, text)),
    );
  const head = h("thead", {}, h("tr", {}, ...FLEET_COLUMNS.map(([name, title]) => h("th", { title }, name))));
  const rows = mission.fleet.shares.map(row);
  byId("sortie-table").replaceChildren(head, h("tbody", {}, ...rows));
}

// Predicted against used energy, a row per sortie (none for a plain single tour). Error: (used - predicted) / used.
function showSortieTable(mission) {
  const table = byId("sortie-table");
  if (mission.fleet) return showFleetTable(mission);
  if (!hasSortieFigures(mission)) return table.replaceChildren();
  const onBoard = mission.status === MissionStatus.flying ? mission.progress.sortie : null;
  const row = (s) => {
    const cells = [
      h("td", {}, swatch(routeLook(mission, s.index)), String(s.index + 1)),
      ...[
        String(s.order.length),
        formatNumber(s.predicted_energy_wh),
        formatNumber(s.used_energy_wh),
        formatNumber(energyErrorPct(s)),
        formatNumber(s.margin_pct, 0),
        `${formatNumber(s.predicted_landing_charge_pct, 0)} / ${formatNumber(s.landing_charge_pct, 0)}`,
        s.battery_warning ?? (hasFlown(s) ? "none" : "–"),
      ].map((text) => h("td", {}, text)),
    ];
    return h("tr", s.index === onBoard ? { class: "on-board" } : {}, ...cells);
  };
  const head = h("thead", {}, h("tr", {}, ...SORTIE_COLUMNS.map(([name, title]) => h("th", { title }, name))));
  table.replaceChildren(head, h("tbody", {}, ...mission.sorties.map(row)));
}

// A sortie's pre-flight check: the charge it needed against what the vehicle reported before arming.
function preflightLine(check) {
  const sortie = `pre-flight, sortie ${check.sortie + 1}: `;
  const need = `needs ${formatNumber(check.needed_pct, 0)} % (${formatNumber(check.energy_wh, 1)} Wh)`;
  if (check.remaining_pct == null) return `${sortie}${need}; no charge reported, not checked`;
  const had = `, the vehicle had ${formatNumber(check.remaining_pct, 0)} %`;
  const how = check.override ? " – flown short by override" : check.swapped ? " after a swap" : "";
  return `${sortie}${need}${had}${how}`;
}

// MAV_BATTERY_CHARGE_STATE by value: the name shown and the look (style.css .charge-*)
const CHARGE_STATES = {
  1: ["ok", "ok"],
  2: ["low", "low"],
  3: ["critical", "critical"],
  4: ["emergency", "emergency"],
  5: ["battery failed", "emergency"],
  6: ["unhealthy", "critical"],
  7: ["charging", "ok"],
};

const LOOK_RANK = { unknown: -1, ok: 0, low: 1, critical: 2, emergency: 3 };

// The badge: the worse of the vehicle's own charge state and where its charge stands against its own warning
// levels (BAT_LOW_THR, BAT_CRIT_THR, when it told them): never a fixed colour of the page's choosing.
function chargeLook(v) {
  const [name, look] = CHARGE_STATES[v.battery_charge_state] ?? ["state unknown", "unknown"];
  const pct = v.battery_remaining_pct;
  if (pct == null || v.battery_low_pct == null || v.battery_critical_pct == null) return [name, look];
  const byLevel = pct <= v.battery_critical_pct ? "critical" : pct <= v.battery_low_pct ? "low" : "ok";
  return LOOK_RANK[look] >= LOOK_RANK[byLevel] ? [name, look] : [byLevel, byLevel];
}

// vehicle: the live stream's vehicle part; its first battery's state, or "no battery report".
export function showBattery(vehicle) {
  const v = vehicle.connected ? vehicle : {};
  const reported = [v.battery_remaining_pct, v.battery_voltage_v, v.battery_current_a].some((x) => x != null);
  const [name, look] = chargeLook(v);
  const meter = byId("battery-meter");
  meter.hidden = v.battery_remaining_pct == null;
  meter.value = v.battery_remaining_pct ?? 0;
  const charge = byId("battery-charge");
  charge.textContent = reported ? `${formatNumber(v.battery_remaining_pct, 0)} %` : "no battery report";
  const state = byId("battery-state");
  state.textContent = reported ? name : "";
  state.className = `badge charge-${look}`;
  state.title =
    v.battery_low_pct == null
      ? "the vehicle's own charge state"
      : `low at ${formatNumber(v.battery_low_pct, 0)} %, critical at ${formatNumber(v.battery_critical_pct, 0)} % ` +
        "(the vehicle's BAT_LOW_THR, BAT_CRIT_THR)";
  byId("battery-figures").textContent = reported
    ? `${formatNumber(v.battery_voltage_v, 2)} V, ${formatNumber(v.battery_current_a)} A, ` +
      `${formatNumber(v.battery_consumed_wh, 2)} Wh used`
    : "";
}

// vehicle: the live stream's vehicle part (connected, armed, mode); name: how the page names it ("vehicle 1
// (ARDUPILOTMEGA QUADROTOR)"), so that the header says which vehicle it speaks of
export function showVehicleLink(vehicle, name) {
  byId("vehicle-name").textContent = vehicle.sysid == null ? "" : name;
  byId("battery-vehicle").textContent = vehicle.sysid == null ? "" : `of vehicle ${vehicle.sysid}`;
  const badge = byId("link-status");
  badge.textContent = vehicle.connected ? `vehicle: ${vehicle.armed ? "armed" : "disarmed"}` : "vehicle: disconnected";
  badge.className = vehicle.connected ? "badge" : "badge off";
  byId("mode").textContent = vehicle.connected ? vehicle.mode : "";
  // the vehicle's latest STATUSTEXT (its own words: text only), the earlier ones on hover
  const texts = (vehicle.connected && vehicle.status_texts) || [];
  byId("vehicle-text").textContent = texts.length ? texts[texts.length - 1] : "";
  byId("vehicle-text").title = texts.join("\n");
}
