// The map page: place buoys, plan, fly, watch the vehicle live, browse history. Talks to the gcs REST API
// and the /ws stream; Leaflet and uPlot are served locally (no CDN).
import { FlightCharts } from "./charts.js";
import { metricGridLayer, tilesReachable } from "./grid.js";

const $ = (id) => document.getElementById(id);
const OSM_URL = "https://tile.openstreetmap.org/{z}/{x}/{y}.png";

const state = {
  depot: null, // L.LatLng
  buoys: [], // {id, lat, lon, marker}
  plan: null, // POST /plans answer
  missionId: null,
  mission: null, // latest GET /missions/{id}
  progress: null,
  firstBuoySeq: 2,
  trackPoints: [],
};

// ----- map
const map = L.map("map", { zoomControl: true });
const layers = { route: L.layerGroup().addTo(map), buoys: L.layerGroup().addTo(map) };
const track = L.polyline([], { color: "#c2185b", weight: 3 }).addTo(map);
const routeLine = L.polyline([], { color: "#1f6fb2", weight: 3, dashArray: "8 6" }).addTo(layers.route);
let depotMarker = null;
let vehicleMarker = null;
const charts = new FlightCharts(window.uPlot);

function token() {
  return $("token").value.trim();
}

async function api(method, path, body, contentType = "application/json") {
  const headers = {};
  if (token()) headers.Authorization = `Bearer ${token()}`;
  if (body !== undefined) headers["Content-Type"] = contentType;
  const payload = body === undefined || contentType !== "application/json" ? body : JSON.stringify(body);
  const response = await fetch(path, { method, headers, body: payload });
  const text = await response.text();
  const data = text ? JSON.parse(text) : null;
  if (!response.ok) {
    const detail = data && data.detail;
    const message = Array.isArray(detail)
      ? detail.map((e) => `${e.loc.slice(1).join(".")}: ${e.msg}`).join("\n")
      : detail || response.statusText;
    throw new Error(`${response.status}: ${message}`);
  }
  return data;
}

function say(text, ok = false) {
  $("message").textContent = text;
  $("message").className = ok ? "ok" : "";
}

function buoyIcon(label, cls = "") {
  return L.divIcon({ className: "", html: `<div class="buoy-icon ${cls}">${label}</div>`, iconSize: [22, 22], iconAnchor: [11, 11] });
}

function setDepot(latlng) {
  state.depot = L.latLng(latlng);
  const icon = L.divIcon({ className: "", html: '<div class="depot-icon" title="depot"></div>', iconSize: [20, 20], iconAnchor: [10, 10] });
  if (depotMarker) depotMarker.setLatLng(state.depot);
  else depotMarker = L.marker(state.depot, { icon, title: "depot", zIndexOffset: 500 }).addTo(map);
  invalidatePlan();
}

function addBuoy(lat, lon, id = null) {
  const buoy = { id, lat, lon };
  buoy.marker = L.marker([lat, lon], { icon: buoyIcon(state.buoys.length + 1), title: id || "buoy" });
  buoy.marker.on("click", () => removeBuoy(buoy));
  buoy.marker.addTo(layers.buoys);
  state.buoys.push(buoy);
  invalidatePlan();
}

function removeBuoy(buoy) {
  if (state.missionId && state.mission && ["uploading", "uploaded", "flying"].includes(state.mission.status)) return;
  layers.buoys.removeLayer(buoy.marker);
  state.buoys = state.buoys.filter((b) => b !== buoy);
  invalidatePlan();
}

function invalidatePlan() {
  state.plan = null;
  routeLine.setLatLngs([]);
  $("plan-summary").textContent = "";
  relabelBuoys();
}

function relabelBuoys() {
  $("buoy-count").textContent = `${state.buoys.length} buoys`;
  const visitRank = new Map();
  if (state.plan) state.plan.order.forEach((index, rank) => visitRank.set(index, rank));
  const visited = new Set();
  let current = null;
  if (state.progress && state.plan) {
    for (const seq of state.progress.reached_seqs || []) {
      const rank = seq - state.firstBuoySeq;
      if (rank >= 0 && rank < state.plan.order.length) visited.add(state.plan.order[rank]);
    }
    const rank = (state.progress.current_seq ?? -1) - state.firstBuoySeq;
    if (rank >= 0 && rank < state.plan.order.length) current = state.plan.order[rank];
    // the vehicle sequences past an item only after reaching it
    state.plan.order.slice(0, Math.max(0, rank)).forEach((index) => visited.add(index));
  }
  state.buoys.forEach((buoy, index) => {
    const label = visitRank.has(index) ? visitRank.get(index) + 1 : index + 1;
    const cls = visited.has(index) ? "visited" : index === current ? "current" : "";
    buoy.marker.setIcon(buoyIcon(label, cls));
  });
}

map.on("click", (event) => {
  const mode = document.querySelector('input[name="place"]:checked').value;
  if (mode === "depot") setDepot(event.latlng);
  else addBuoy(event.latlng.lat, event.latlng.lng);
});

// ----- requests
function request() {
  const number = (id) => Number($(id).value);
  return {
    depot: state.depot ? { lat: state.depot.lat, lon: state.depot.lng } : null,
    buoys: state.buoys.map((b) => ({ id: b.id, lat: b.lat, lon: b.lon })),
    altitude_m: number("altitude"),
    speed_m_s: number("speed"),
    dwell_s: number("dwell"),
    acceptance_radius_m: number("radius"),
    planner: { method: $("method").value, seed: 0, time_limit_s: 2.0 },
  };
}

function showPlan(plan) {
  state.plan = plan;
  routeLine.setLatLngs(plan.route);
  map.fitBounds(routeLine.getBounds(), { padding: [30, 30] });
  $("plan-summary").innerHTML =
    `Route <b>${(plan.length_m / 1000).toFixed(3)} km</b> (${plan.method}, ${plan.elapsed_s.toFixed(2)} s)<br>` +
    `input order ${(plan.input_order_length_m / 1000).toFixed(3)} km: <b>${plan.improvement_pct.toFixed(1)} % shorter</b>`;
  relabelBuoys();
}

$("plan").addEventListener("click", async () => {
  if (!state.buoys.length) return say("Place at least one buoy first.");
  say("planning…", true);
  try {
    showPlan(await api("POST", "/plans", request()));
    say("planned", true);
  } catch (error) {
    say(error.message);
  }
});

$("fly").addEventListener("click", async () => {
  if (!state.buoys.length) return say("Place at least one buoy first.");
  say("creating mission…", true);
  try {
    const mission = await api("POST", "/missions", { ...request(), start: true });
    startWatching(mission);
    say(`mission ${mission.id} created`, true);
    refreshHistory();
  } catch (error) {
    say(error.message);
  }
});

$("abort").addEventListener("click", async () => {
  if (!state.missionId) return say("No mission to abort.");
  try {
    showMission(await api("POST", `/missions/${state.missionId}/abort`));
  } catch (error) {
    say(error.message);
  }
});

$("clear").addEventListener("click", () => {
  layers.buoys.clearLayers();
  state.buoys = [];
  track.setLatLngs([]);
  charts.clear();
  invalidatePlan();
});

$("import").addEventListener("change", async (event) => {
  const file = event.target.files[0];
  if (!file) return;
  try {
    const body = await file.text();
    const type = file.name.toLowerCase().endsWith(".csv") ? "text/csv" : "application/geo+json";
    const answer = await api("POST", `/imports?filename=${encodeURIComponent(file.name)}`, body, type);
    answer.buoys.forEach((b) => addBuoy(b.lat, b.lon, b.id));
    map.fitBounds(L.latLngBounds(state.buoys.map((b) => [b.lat, b.lon])).pad(0.2));
    say(`imported ${answer.buoys.length} buoys`, true);
  } catch (error) {
    say(error.message);
  }
  event.target.value = "";
});

// ----- a mission: planned route, status, figures
function startWatching(mission) {
  state.missionId = mission.id;
  state.trackPoints = [];
  track.setLatLngs([]);
  charts.clear();
  showMission(mission);
}

function showMission(mission) {
  state.mission = mission;
  state.progress = mission.progress;
  if (!state.plan || state.plan.route.length !== mission.route.length) showPlan(mission);
  const reason = mission.reason ? ` – ${mission.reason}` : "";
  $("mission-status").textContent = `#${mission.id}: ${mission.status}${reason}`;
  const p = mission.progress || {};
  $("progress").max = Math.max(1, p.buoys || mission.order.length);
  $("progress").value = p.visited || 0;
  $("figures").innerHTML = figuresHtml(mission);
  relabelBuoys();
}

const fmt = (v, digits = 1) => (v == null ? "–" : Number(v).toFixed(digits));

function figuresHtml(mission) {
  const t = mission.tracking;
  if (!t) return "";
  const reached = mission.buoy_results.filter((b) => b.reached).length;
  return `RMS cross-track ${fmt(t.rms_cross_track_m, 2)} m, max ${fmt(t.max_cross_track_m, 2)} m<br>` +
    `flown ${fmt(t.distance_flown_m, 0)} m of ${fmt(t.planned_length_m, 0)} m planned, ${fmt(t.flight_time_s)} s<br>` +
    `buoys reached ${reached} / ${mission.buoy_results.length}`;
}

async function pollMission() {
  if (!state.missionId) return;
  try {
    const mission = await api("GET", `/missions/${state.missionId}`);
    const wasActive = state.mission && !["completed", "aborted", "failed"].includes(state.mission.status);
    showMission(mission);
    if (wasActive && ["completed", "aborted", "failed"].includes(mission.status)) refreshHistory();
  } catch (error) {
    say(error.message);
  }
}
setInterval(pollMission, 1000);

// ----- live stream
function vehicleIcon(yawDeg) {
  const svg = `<svg width="28" height="28" viewBox="-14 -14 28 28" style="transform: rotate(${yawDeg}deg)">` +
    '<path d="M0,-12 L8,10 L0,5 L-8,10 Z" fill="#c2185b" stroke="#fff" stroke-width="1.5"/></svg>';
  return L.divIcon({ className: "vehicle-icon", html: svg, iconSize: [28, 28], iconAnchor: [14, 14] });
}

function onState(message) {
  const v = message.vehicle;
  const badge = $("link-status");
  badge.textContent = v.connected ? `vehicle: ${v.armed ? "armed" : "disarmed"}` : "vehicle: disconnected";
  badge.className = v.connected ? "badge" : "badge off";
  $("mode").textContent = v.connected ? v.mode : "";
  if (v.connected && v.lat != null) {
    const yaw = ((v.yaw ?? 0) * 180) / Math.PI;
    if (!vehicleMarker) vehicleMarker = L.marker([v.lat, v.lon], { icon: vehicleIcon(yaw), zIndexOffset: 1000, title: "vehicle" }).addTo(map);
    else vehicleMarker.setLatLng([v.lat, v.lon]).setIcon(vehicleIcon(yaw));
  }
  const m = message.mission;
  if (m && m.id === state.missionId) {
    state.firstBuoySeq = m.first_buoy_seq;
    if (m.progress) state.progress = m.progress;
    if (m.sample && m.sample.lat != null) {
      const last = state.trackPoints[state.trackPoints.length - 1];
      if (!last || last[0] !== m.sample.lat || last[1] !== m.sample.lon) {
        state.trackPoints.push([m.sample.lat, m.sample.lon]);
        track.addLatLng([m.sample.lat, m.sample.lon]);
      }
      charts.add(m.sample);
    }
  }
}

function connectLive() {
  const ws = new WebSocket(`${location.protocol === "https:" ? "wss" : "ws"}://${location.host}/ws`);
  ws.onmessage = (event) => onState(JSON.parse(event.data));
  ws.onclose = () => setTimeout(connectLive, 1000);
}

setInterval(() => { charts.redraw(); relabelBuoys(); }, 250);

// ----- history
async function refreshHistory() {
  let missions;
  try {
    missions = await api("GET", "/missions?limit=50");
  } catch (error) {
    say(error.message);
    return [];
  }
  const rows = missions.map((m) => {
    const t = m.tracking || {};
    const files = ["track.geojson", "plan", "waypoints"].map((f) => `<a href="/missions/${m.id}/${f}" download>${f === "plan" ? ".plan" : f === "waypoints" ? ".waypoints" : f}</a>`).join("") +
      `<a href="/missions/${m.id}/report" target="_blank" data-testid="report-link">report</a>`;
    return `<tr><td>${m.id}</td><td title="${m.reason || ""}">${m.status}${m.reason ? " *" : ""}</td><td>${m.buoys}</td>` +
      `<td>${fmt(m.length_m, 0)}</td><td>${fmt(t.distance_flown_m, 0)}</td><td>${fmt(t.rms_cross_track_m, 2)}</td>` +
      `<td>${fmt(t.max_cross_track_m, 2)}</td><td>${fmt(t.flight_time_s)}</td><td>${files}</td>` +
      `<td><button type="button" data-show="${m.id}">show</button></td></tr>`;
  });
  $("history-rows").innerHTML = rows.join("");
  return missions;
}

$("history-rows").addEventListener("click", (event) => {
  const id = event.target.dataset && event.target.dataset.show;
  if (id) displayMission(id);
});

// Draw a stored mission: its buoys, planned route, flown track and charts; a flying one keeps updating live.
async function displayMission(id) {
  try {
    const mission = await api("GET", `/missions/${id}`);
    loadBuoysOf(mission);
    startWatching(mission);
    const samples = await api("GET", `/missions/${id}/telemetry`);
    const points = samples.filter((s) => s.lat != null).map((s) => [s.lat, s.lon]);
    state.trackPoints = points;
    track.setLatLngs(points);
    samples.forEach((s) => charts.add(s));
    charts.redraw();
  } catch (error) {
    say(error.message);
  }
}

function loadBuoysOf(mission) {
  layers.buoys.clearLayers();
  state.buoys = [];
  setDepot([mission.depot.lat, mission.depot.lon]);
  mission.buoys.forEach((b) => addBuoy(b.lat, b.lon, b.id));
  showPlan(mission);
}

$("refresh").addEventListener("click", refreshHistory);

// ----- start: centre on the depot (the vehicle's home when it has reported one), grid first, OSM if reachable
async function start() {
  let vehicle = null;
  try {
    vehicle = await api("GET", "/vehicle");
  } catch (error) {
    say(error.message);
  }
  const depot = vehicle ? [vehicle.depot.lat, vehicle.depot.lon] : [38.921, 121.663];
  map.setView(depot, 15);
  const grid = metricGridLayer(L, L.latLng(depot)).addTo(map);
  const osm = L.tileLayer(OSM_URL, { maxZoom: 19, attribution: "© OpenStreetMap contributors" });
  L.control.layers({ "Metric grid (offline)": grid, OpenStreetMap: osm }, {}, { position: "topright" }).addTo(map);
  L.control.scale({ metric: true, imperial: false }).addTo(map);
  setDepot(depot);
  connectLive();
  const missions = await refreshHistory();
  // Open on what matters: the mission flying now, else the latest one (e.g. the demo `make run` flew).
  const shown = (vehicle && vehicle.active_mission) || (missions.length ? missions[0].id : null);
  if (shown != null) displayMission(shown);
  tilesReachable(OSM_URL.replace("{z}/{x}/{y}", "0/0/0")).then((online) => {
    if (online) { map.removeLayer(grid); osm.addTo(map); }
  });
}
start();
