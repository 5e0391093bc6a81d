// The history table: one row per stored mission with its date (in the browser's time zone), its figures, its
// files (track, QGC plan, waypoints), its report and a button that shows it on the map. Rows are built element
// by element (no HTML strings).
import { byId, h } from "./dom.js";
import { formatNumber } from "./panel.js";
import { dateTime, duration } from "./times.js";

const DOWNLOADS = [
  ["track.geojson", "track.geojson"],
  ["plan", ".plan"],
  ["waypoints", ".waypoints"],
];

function filesCell(api, mission) {
  const downloads = DOWNLOADS.map(([file, label]) =>
    h("a", { href: api.missionFileUrl(mission.id, file), download: "" }, label),
  );
  const reportUrl = api.missionFileUrl(mission.id, "report");
  const report = h("a", { href: reportUrl, target: "_blank", "data-testid": "report-link" }, "report");
  return h("td", {}, ...downloads, report);
}

// The tracking figures in plain words, their technical names in the headings' titles (index.html): "off route"
// is the cross-track error (RMS over the flight, and its maximum), the time is the flight's, in minutes and seconds.
function row(api, mission, onShow) {
  const t = mission.tracking || {};
  // a mission that ended with a reason is starred; the reason shows on hover
  const status = h("td", { title: mission.reason || "" }, `${mission.status}${mission.reason ? " *" : ""}`);
  const created = h("td", { title: mission.created_at, "data-testid": "history-date" }, dateTime(mission.created_at));
  const show = h("button", { type: "button" }, "show");
  show.addEventListener("click", () => onShow(mission.id));
  const numbers = [
    mission.buoys,
    formatNumber(mission.length_m, 0),
    formatNumber(t.distance_flown_m, 0),
    formatNumber(t.rms_cross_track_m, 2),
    formatNumber(t.max_cross_track_m, 2),
  ].map((text) => h("td", {}, String(text)));
  const exactTime = t.flight_time_s == null ? "" : `${formatNumber(t.flight_time_s)} s`;
  const time = h("td", { title: exactTime }, duration(t.flight_time_s));
  return h(
    "tr",
    {},
    h("td", {}, String(mission.id)),
    status,
    created,
    ...numbers,
    time,
    filesCell(api, mission),
    h("td", {}, show),
  );
}

// missions: the GET /missions answer (newest first); onShow(id) when a row's show button is clicked
export function showHistory(api, missions, onShow) {
  byId("history-rows").replaceChildren(...missions.map((mission) => row(api, mission, onShow)));
}
