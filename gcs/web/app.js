// The map page: place buoys, plan, fly, watch the vehicle live and each buoy's inspection, browse history. This
// module wires the parts: api.js (the service), state.js (what is shown), map.js (Leaflet), charts.js (uPlot),
// panel.js and history.js (the text around the map), inspections.js (the records fetched), findings.js (the
// inspection list), gallery.js (a buoy's frames), the map's overlays atons.js (the AIS AtoNs) and register.js
// (the buoy register), alarms.js (the register's off-station alarms, in the panel), controls.js (the control bar:
// mission status, vehicle, Fly and the commands in flight, each confirmed in confirm.js's dialog) and alerts.js (the
// event log, the banner and the beep). Leaflet and uPlot are served locally (no CDN), so it works offline.
import { EventLog, Severity, Watch } from "./alerts.js";
import { AlarmList } from "./alarms.js";
import { ApiError, GcsApi } from "./api.js";
import { AtonLayer } from "./atons.js";
import { FlightCharts } from "./charts.js";
import { confirmAction } from "./confirm.js";
import { ControlBar, statusWords, vehicleName } from "./controls.js";
import { byId } from "./dom.js";
import { showInspections } from "./findings.js";
import { closeGallery, refreshGallery, showGallery, wireGallery } from "./gallery.js";
import { showHistory } from "./history.js";
import { InspectionFeed } from "./inspections.js";
import { MissionMap } from "./map.js";
import * as panel from "./panel.js";
import { RegisterLayer } from "./register.js";
import { sortieLook } from "./sorties.js";
import { buoyMarkings, buoysEditable, inspectionRows, state } from "./state.js";
import { defineMissionStatus, isFinished, isUnderway, MissionStatus } from "./status.js";
import { clockTime, vehicleInstant } from "./times.js";
import { VehicleChoice } from "./vehicles.js";

const FALLBACK_DEPOT = { lat: 38.921, lon: 121.663 }; // when the service cannot tell the vehicle's home
const ALARM_ZOOM = 16; // an alarm's buoy is shown at least this close: a buoy among the register's many

const api = new GcsApi(panel.token);
const map = new MissionMap("map");
const charts = new FlightCharts(window.uPlot);
const events = new EventLog();
const watch = new Watch(events);

// A failed request: shown in the message line. Anything else is a bug: shown and rethrown.
function showRequestError(error) {
  panel.say(error.message);
  if (!(error instanceof ApiError)) throw error;
}

// Run an action, showing a failed request (showRequestError); the answer, or `fallback` when it failed.
function showingErrors(action, fallback = undefined) {
  return async (...args) => {
    try {
      return await action(...args);
    } catch (error) {
      showRequestError(error);
      return fallback;
    }
  };
}

// ----- placing
function setDepot(depot) {
  state.depot = { lat: depot.lat, lon: depot.lon };
  map.setDepot(state.depot);
  invalidatePlan();
}

// charted: what a file or chart says of the buoy besides where it is (kind, light, swing radius, region), sent
// with it so the mission checks the buoy against it
function addBuoy(lat, lon, id = null, charted = {}) {
  const buoy = { id, lat, lon, charted };
  map.addBuoy(buoy, clickBuoy);
  state.buoys.push(buoy);
  invalidatePlan();
}

// A click on a buoy's marker: a buoy of the mission shown with an inspection record shows its frames; any other
// is removed (while the buoys may be edited).
function clickBuoy(buoy) {
  const index = state.buoys.indexOf(buoy);
  const row = inspectionRows().find((r) => r.index === index);
  if (row && row.record) showGallery(row);
  else removeBuoy(buoy);
}

function removeBuoy(buoy) {
  if (!buoysEditable()) return;
  map.removeBuoy(buoy);
  state.buoys = state.buoys.filter((b) => b !== buoy);
  invalidatePlan();
}

function clearBuoys() {
  map.clearBuoys();
  state.buoys = [];
}

function invalidatePlan() {
  supersedeRequests(); // the buoys or depot a request in flight was made for are not the page's any more
  state.plan = null;
  map.clearRoute();
  panel.clearPlanSummary();
  closeGallery();
  relabelBuoys();
}

// The markers (visiting rank, progress, sortie, verdict) and the inspection list, from what the page knows now.
function relabelBuoys() {
  panel.showBuoyCount(state.buoys.length);
  const markings = buoyMarkings();
  map.markBuoys(state.buoys, markings);
  const id = state.missionId;
  const exports = {
    csv: api.missionFileUrl(id, "inspections.csv"),
    geojson: api.missionFileUrl(id, "inspections.geojson"),
  };
  const camera = state.progress ? state.progress.camera : null;
  const open = (row) => row.record && showGallery(row);
  const rows = inspectionRows(markings).map((row) => ({ ...row, reached: reachedText(row) }));
  showInspections(rows, `${id} ${state.inspectionsSeq}`, camera, exports, open);
}

// A buoy's arrival as the operator reads it: when the service heard it (arrival_at), else the wall-clock time
// when it can be told exactly (times.js vehicleInstant: a mission stored before arrival_at was), else the vehicle's
// own seconds, said as such.
function reachedText({ arrival_s, arrival_at }) {
  if (arrival_at) return `at ${clockTime(Date.parse(arrival_at))}`;
  if (arrival_s == null) return null;
  const instant = vehicleInstant(arrival_s, state.mission, consoleVehicle());
  return instant === null ? `at vehicle time ${arrival_s.toFixed(1)} s` : `at ${clockTime(instant)}`;
}

// The vehicles, and which one Plan and Fly use (or the fleet); invalidatePlan: a plan was made for another choice
const vehicleChoice = new VehicleChoice(byId("vehicles-section"), byId("vehicle-list"), byId("vehicle-choice"), () =>
  invalidatePlan(),
);

function flightRequest() {
  return {
    ...(vehicleChoice.isFleet() ? {} : { depot: state.depot }), // a fleet flies from its vehicles' homes
    buoys: state.buoys.map((b) => ({ ...b.charted, id: b.id, lat: b.lat, lon: b.lon })),
    ...panel.flightSettings(),
    ...vehicleChoice.request(),
  };
}

function showPlan(plan) {
  state.plan = plan;
  map.showRoute(plan);
  panel.showPlanSummary(plan);
  relabelBuoys();
}

// ----- plan and fly requests
// One at a time (Plan and Fly are disabled while one is in flight), and only the latest one's answer may change
// the page: a change of what is shown since it was sent (a buoy placed or removed, the depot moved, Clear, a
// mission shown from the history) supersedes it, and its late answer is dropped. A plan can take its whole time
// limit, and a slow answer must not replace what the operator has moved on to.
let requestSeq = 0; // the latest request's number; bumped by every request and by what supersedes one

function supersedeRequests() {
  requestSeq += 1;
}

// The answer of `call()` (a plan or mission request), or null when the request was superseded while in flight,
// its error too: the page has moved on and must not show it.
async function latestAnswer(note, call) {
  const seq = ++requestSeq;
  const done = panel.showBusy(note);
  state.busy = true;
  updateConsole();
  try {
    const answer = await call();
    return seq === requestSeq ? answer : null;
  } catch (error) {
    if (seq === requestSeq) throw error;
    return null;
  } finally {
    done();
    state.busy = false;
    updateConsole();
  }
}

// A mission under way on the page (its route, its visited marks) is what the operator watches: a plan never
// replaces it. Says so and returns true when one is.
function watchingFlight() {
  if (buoysEditable()) return false;
  panel.say(`Mission ${state.missionId} is under way: its route stays shown (abort it or show another first).`);
  return true;
}

// ----- inspections: the watched mission's records, fetched when it is opened and as its progress changes
let recordsText = null; // the latest answer as fetched, so that an unchanged one redraws nothing
let liveProgressText = null; // the latest progress the live stream brought

const inspectionFeed = new InspectionFeed(
  (id) => api.inspections(id),
  (_id, records) => {
    const text = JSON.stringify(records);
    if (text === recordsText) return;
    recordsText = text;
    state.inspections = new Map(records.map((record) => [record.index, record]));
    state.inspectionsSeq += 1;
    relabelBuoys();
    refreshGallery(inspectionRows());
    alarms.refresh(); // a record stored may have opened an off_station defect: its alarm
  },
  showRequestError,
);

function watchInspections(missionId) {
  state.inspections = new Map();
  state.inspectionsSeq += 1;
  recordsText = null;
  closeGallery();
  inspectionFeed.watch(missionId);
}

// ----- a mission: planned route, status, figures
// Watch a mission: its own route (not the plan shown before: the service plans the mission's sorties anew when
// it creates it), then its status and its inspections as they change.
function startWatching(mission) {
  state.missionId = mission.id;
  watchInspections(mission.id);
  map.setTrack([]);
  charts.clear();
  showPlan(mission);
  showMission(mission);
}

function showMission(mission) {
  state.mission = mission;
  state.progress = mission.progress;
  panel.showMission(mission);
  relabelBuoys();
  updateConsole();
}

// ----- the control bar and the alerts: the watched mission's status in plain words, its vehicle, the buttons
// that apply; a change of the mission's status (or of the operator command in force) goes to the event log
let liveVehicles = { first: null, bySysid: new Map() }; // the latest /ws vehicles

// The vehicle the watched mission flies on (a fleet's by its system id), else the service's first vehicle.
function consoleVehicle() {
  const sysid = state.mission ? state.mission.vehicle_sysid : null;
  return (sysid != null && liveVehicles.bySysid.get(sysid)) || liveVehicles.first;
}

// The vehicle a "Pack swapped" is for: a fleet mission's vehicle whose part waits for its battery (the fleet
// mission itself goes on flying), else the watched mission's (null: the service's first vehicle).
function swapVehicle(mission) {
  const waiting = mission?.fleet?.shares?.find((share) => share.status === MissionStatus.waiting_for_battery);
  return waiting ? waiting.sysid : (mission?.vehicle_sysid ?? null);
}

// The status and the operator command in force are the mission document's (the poll's, or an action's answer):
// one source, so that the buttons and the log never flip between it and the stream; the counts are the stream's
// (fresher).
function updateConsole() {
  const command = (state.mission && state.mission.progress && state.mission.progress.command) || null;
  const progress = state.progress ? { ...state.progress, command } : { command };
  const view = { mission: state.mission, progress, buoyCount: state.buoys.length, busy: state.busy };
  controls.show(view, consoleVehicle());
  if (state.mission) watch.missionShown(state.mission, command, statusWords(state.mission, progress));
}

const pollMission = showingErrors(async () => {
  if (!state.missionId) return;
  const mission = await api.mission(state.missionId);
  const wasActive = state.mission && !isFinished(state.mission.status);
  const changed = state.mission && state.mission.id === mission.id && state.mission.updated_at !== mission.updated_at;
  showMission(mission);
  if (changed) inspectionFeed.refresh(); // a record stored (or the mission ended) since
  if (wasActive && isFinished(mission.status)) refreshHistory();
});

// A /ws message: the vehicle's state, every vehicle of a fleet, and, while one runs, the mission's progress and
// latest sample. The stream is the one live path: nothing is polled for the vehicles' positions.
function onLiveMessage(message) {
  const vehicle = message.vehicle;
  panel.showVehicleLink(vehicle, vehicleName(vehicle));
  panel.showBattery(vehicle);
  liveVehicles = { first: vehicle, bySysid: new Map(message.vehicles.map((v) => [v.sysid, v])) };
  vehicleChoice.show(message.vehicles);
  // each vehicle's link, mode and STATUSTEXTs to the event log (a fleet's every one; else the one)
  const watched = message.vehicles.length > 1 ? message.vehicles : [vehicle];
  watched.forEach((v) => watch.vehicle(v, v.sysid == null ? "the vehicle" : `vehicle ${v.sysid}`));
  if (message.vehicles.length > 1) showFleet(message.vehicles);
  else if (vehicle.connected && vehicle.lat != null) {
    map.showVehicle(vehicle.lat, vehicle.lon, ((vehicle.yaw ?? 0) * 180) / Math.PI);
  }
  const mission = message.mission;
  if (!mission || mission.id !== state.missionId) return updateConsole();
  state.firstBuoySeq = mission.first_buoy_seq;
  if (mission.progress) {
    state.progress = mission.progress;
    const text = JSON.stringify(mission.progress);
    if (text !== liveProgressText) inspectionFeed.refresh(); // a buoy passed: its verdict may be in
    liveProgressText = text;
  }
  if (mission.sample && mission.sample.lat != null) {
    map.extendTrack(mission.sample.lat, mission.sample.lon);
    charts.add(mission.sample);
  }
  updateConsole();
}

// A fleet (more than one vehicle): every vehicle on the map, in its share's colour while a fleet mission is shown.
function showFleet(vehicles) {
  const shares = (state.mission && state.mission.fleet && state.mission.fleet.shares) || [];
  const colourOf = (sysid) => {
    const index = shares.findIndex((share) => share.sysid === sysid);
    return index < 0 ? null : sortieLook(index).colour;
  };
  map.showVehicles(vehicles, colourOf);
}

// ----- history
const refreshHistory = showingErrors(async () => {
  const missions = await api.missions(50);
  showHistory(api, missions, displayMission);
  return missions;
}, []);

// Draw a stored mission: its buoys, planned route, flown track and charts; a flying one keeps updating live.
const displayMission = showingErrors(async (id) => {
  supersedeRequests(); // the operator chose what to look at: an answer in flight must not replace it
  const mission = await api.mission(id);
  clearBuoys();
  setDepot(mission.depot);
  mission.buoys.forEach((b) => addBuoy(b.lat, b.lon, b.id));
  startWatching(mission);
  const track = await api.track(id);
  map.setTrack(track.points);
  track.series.forEach((s) => charts.add(s));
  charts.redraw();
});

// ----- the control bar's actions (controls.js asks first where an action is consequential)
// A failed request: said beside the buttons (the panel's message line may be scrolled away) and logged, then as
// showingErrors says it (a bug rethrown).
function commanding(name, action) {
  return showingErrors(async () => {
    try {
      await action();
    } catch (error) {
      controls.say(error.message);
      events.add({ severity: Severity.warning, text: `${name} refused: ${error.message}` });
      throw error;
    }
  });
}

// A command to the watched mission in flight: its answer (the mission) shown at once.
const missionCommand = (name, call) =>
  commanding(name, async () => {
    if (!state.missionId) return controls.say("No mission shown.");
    showMission(await call(state.missionId));
    controls.say(`${name}: sent`, true);
  });

const flyMission = commanding("Fly", async () => {
  if (!state.buoys.length) return controls.say("Place at least one buoy first.");
  panel.say("");
  const request = { ...flightRequest(), override: byId("override").checked };
  let created = null;
  const mission = await latestAnswer("planning…", async () => (created = await api.createMission(request)));
  refreshHistory();
  if (created) events.add({ severity: Severity.notice, text: `Mission ${created.id} created and started` });
  if (mission === null) {
    // superseded: the page shows what the operator chose since; the mission flies all the same, so say so
    if (created) panel.say(`mission ${created.id} created and started: "show" it in the history`, true);
    return;
  }
  startWatching(mission);
  panel.say(`mission ${mission.id} created`, true);
  controls.say(`mission ${mission.id} created`, true);
});

const controls = new ControlBar(
  {
    fly: flyMission,
    hold: missionCommand("Hold", (id) => api.holdMission(id)),
    resume: missionCommand("Resume", (id) => api.resumeMission(id)),
    return: missionCommand("Return", (id) => api.returnMission(id)),
    land: missionCommand("Land", (id) => api.landMission(id)),
    abort: missionCommand("Abort", (id) => api.abortMission(id)),
  },
  () => ({
    vehicle: vehicleName(consoleVehicle()).replace(/^./, (c) => c.toUpperCase()), // a sentence's first word
    connected: Boolean(consoleVehicle() && consoleVehicle().connected),
    buoyCount: state.buoys.length,
    altitude_m: panel.flightSettings().altitude_m,
  }),
);

// ----- controls
function wireControls() {
  panel.wireBatteryOptions();
  wireGallery();
  map.onClick((point) => (panel.placing() === "depot" ? setDepot(point) : addBuoy(point.lat, point.lon)));

  byId("plan").addEventListener(
    "click",
    showingErrors(async () => {
      if (!state.buoys.length) return panel.say("Place at least one buoy first.");
      if (watchingFlight()) return;
      panel.say("");
      const plan = await latestAnswer("planning…", () => api.plan(flightRequest()));
      if (plan === null || watchingFlight()) return; // superseded, or a mission shown since is flying
      showPlan(plan);
      panel.say("route planned", true);
    }),
  );

  byId("battery-swap").addEventListener(
    "click",
    showingErrors(async () => {
      // asked in the page's dialog, as the control bar's actions are (window.confirm is auto-answered or
      // blocked by kiosk browsers)
      const question = {
        title: "Pack swapped?",
        text: "Is a charged pack in the vehicle? The vehicle is told its battery was replaced.",
        confirm: "A charged pack is in",
      };
      if (!(await confirmAction(question))) return;
      const answer = await api.swapBattery(swapVehicle(state.mission));
      const waiting = answer.waiting_mission == null ? "" : `; mission ${answer.waiting_mission} goes on`;
      panel.say(`pack swapped (vehicle: ${answer.vehicle})${waiting}`, true);
      pollMission();
    }),
  );

  byId("clear").addEventListener("click", () => {
    clearBuoys();
    map.setTrack([]);
    charts.clear();
    invalidatePlan();
  });

  const importInput = byId("import");
  importInput.addEventListener(
    "change",
    showingErrors(async () => {
      const file = importInput.files[0];
      if (!file) return;
      importInput.value = ""; // choosing the same file again imports it again
      const answer = await api.importBuoys(file);
      answer.buoys.forEach(({ lat, lon, id, ...charted }) => addBuoy(lat, lon, id, charted));
      if (answer.depot) setDepot(answer.depot); // the file's point whose role is depot
      map.fitBuoys(state.buoys);
      const depot = answer.depot ? " and the depot" : "";
      const unmapped = answer.warnings.length ? ` (${answer.warnings.length} chart warnings)` : "";
      panel.say(`imported ${answer.buoys.length} buoys${depot}${unmapped}`, true);
    }),
  );

  byId("refresh").addEventListener("click", refreshHistory);
}

// ----- the map's overlays: the AIS AtoNs (on at first: nothing to draw without an --ais feed) and the buoy
// register (off at first: hundreds of a chart's buoys over the mission shown, and the view moves to them)
const register = new RegisterLayer(map.map, api, showRequestError);

function showOverlays() {
  map.addOverlay(new AtonLayer(() => api.atons(), showRequestError).layer, "AIS AtoNs", true);
  map.addOverlay(register.layer, "Register buoys", false);
}

// ----- the register's off-station alarms: a click centres the map on the buoy (an alarm has no position: the
// register overlay's, else GET /buoys/{id}) and, while the overlay is on, opens the buoy's popup
const showAlarmBuoy = showingErrors(async (alarm) => {
  const buoy = register.buoyById(alarm.buoy) ?? (await api.buoy(alarm.buoy));
  // not animated: the popup's pan into view starts from the view it ends in
  map.map.setView([buoy.lat, buoy.lon], Math.max(map.map.getZoom(), ALARM_ZOOM), { animate: false });
  register.openBuoy(buoy);
});

const alarms = new AlarmList(() => api.alarms(), showAlarmBuoy, showRequestError);

// ----- start: the service's mission states first (everything else refers to them), then centre on the depot
// (the vehicle's home when it has reported one) and open on what matters: the mission flying now, else the
// latest one (e.g. the one the demo `make run` flew).
async function start() {
  defineMissionStatus(await api.openApi());
  const vehicle = await showingErrors(() => api.vehicle(), null)();
  const depot = vehicle ? vehicle.depot : FALLBACK_DEPOT;
  map.showBaseLayers(depot);
  showingErrors(async () => map.showChart(await api.basemap()))(); // megabytes: drawn when it comes
  showOverlays();
  setDepot(depot);
  wireControls();
  alarms.start();
  // the vehicles, a fleet's every one, as they move; the stream's loss is an event (what is shown goes stale)
  api.openLiveStream(onLiveMessage, (open) => watch.serviceStream(open));
  setInterval(pollMission, 1000);
  setInterval(() => {
    charts.redraw();
    relabelBuoys();
    updateConsole(); // the buoys placed decide whether Fly applies
  }, 250);
  const missions = await refreshHistory();
  // the newest mission when it is under way (a fleet mission: its parts fly on the vehicles), else the one the
  // vehicle flies, else the newest
  const newest = missions.length ? missions[0] : null;
  const underway = newest && isUnderway(newest.status) ? newest.id : null;
  const shown = underway ?? ((vehicle && vehicle.active_mission) || (newest ? newest.id : null));
  if (shown != null) displayMission(shown);
}

start().catch((error) => {
  panel.say(`The page could not start: ${error.message}`);
  throw error;
});
