// The history table: one row per stored mission with its figures, its files (track, QGC plan, waypoints),
// its report and a button that shows it on the map. Rows are built element by element (no HTML strings).
import { byId, h } from "./dom.js";
import { formatNumber } from "./panel.js";

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

function row(api, mission, onShow) {
  const t = mission.tracking || {};
  // a mission that ended with a reason is starred; the reason shows on hover
  const status = h("td", { title: mission.reason || "" }, `${mission.status}${mission.reason ? " *" : ""}`);
  const show = h("button", { type: "button" }, "show");
  show.addEventListener("click", () => onShow(mission.id));
  const numbers = [
    mission.buoys,
    formatNumber(mission.length_m, 0),
    formatNumber(t.distance_flown_m, 0),
    formatNumber(t.rms_cross_track_m, 2),
    formatNumber(t.max_cross_track_m, 2),
    formatNumber(t.flight_time_s),
  ].map((text) => h("td", {}, String(text)));
  return h("tr", {}, h("td", {}, String(mission.id)), status, ...numbers, filesCell(api, mission), h("td", {}, show));
}

// missions: the GET /missions answer (newest first); onShow(id) when a row's show button is clicked
export function showHistory(api, missions, onShow) {
  byId("history-rows").replaceChildren(...missions.map((mission) => row(api, mission, onShow)));
}
