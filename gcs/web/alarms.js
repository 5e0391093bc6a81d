// The buoy register's off-station alarms (GET /alarms) as the side panel's first section, not a map control: an
// alarm is a few lines of text (name, evidence, distance, when, why) that a map corner, already holding the layer
// control and the frames' gallery, would have to clip or cover the map with; the panel shows a list of any length
// beside the map, like the inspections and the history, and first in it, an alarm is what the operator must not
// miss. The heading carries a count badge. Polled every 30 s while the tab is shown (at once when it is shown
// again), and refreshed when asked (app.js: when the watched mission's inspection records change). A click on an
// alarm is app.js's: the map centred on the buoy, its register popup opened when that overlay is on. Names come from
// charts and from the air: text nodes only.
import { byId, h } from "./dom.js";
import { Poller } from "./poll.js";
import { when } from "./register.js";

const POLL_MS = 30_000; // alarms follow inspections (minutes) and AtoN reports (every 3 minutes)

const metres = (value) => `${Number(value).toFixed(1)} m`;

// Where the evidence comes from: "inspection, mission 3", "AIS, MMSI 993672102".
export function sourceText(alarm) {
  if (alarm.source === "inspection") {
    return alarm.mission_id == null ? "inspection" : `inspection, mission ${alarm.mission_id}`;
  }
  if (alarm.source === "ais") return alarm.ais && alarm.ais.mmsi != null ? `AIS, MMSI ${alarm.ais.mmsi}` : "AIS";
  return String(alarm.source);
}

// "7.3 m from its charted position, swing radius 5.0 m" (the distance unknown when the evidence gives none)
export function distanceText(alarm) {
  const radius = `swing radius ${metres(alarm.swing_radius_m)}`;
  if (alarm.distance_m == null) return `distance unknown, ${radius}`;
  return `${metres(alarm.distance_m)} from its charted position, ${radius}`;
}

// An alarm's lines as shown, newest first: what a redraw compares (an AIS row's age changes at every poll and
// must not redraw an unchanged list, which would take the focus from a button).
function alarmLines(alarms) {
  const newest = [...alarms].sort((a, b) => (Date.parse(b.at) || 0) - (Date.parse(a.at) || 0));
  return newest.map((alarm) => ({
    alarm,
    name: alarm.name || alarm.buoy,
    source: sourceText(alarm),
    distance: distanceText(alarm),
    at: when(alarm.at),
    why: alarm.why,
  }));
}

function alarmItem(line, onSelect) {
  const { alarm } = line;
  const button = h(
    "button",
    {
      type: "button",
      class: "alarm-buoy",
      "data-testid": "alarm",
      "data-buoy": alarm.buoy,
      "data-source": alarm.source,
      title: "centre the map on this buoy",
    },
    h("b", { class: "alarm-name", "data-testid": "alarm-name" }, line.name),
    h(
      "span",
      {},
      h("span", { "data-testid": "alarm-source" }, line.source),
      " · ",
      h("span", { "data-testid": "alarm-at" }, line.at),
    ),
    h("span", { "data-testid": "alarm-distance" }, line.distance),
    h("span", { class: "alarm-why", "data-testid": "alarm-why" }, line.why),
  );
  button.addEventListener("click", () => onSelect(alarm));
  return h("li", { class: "alarm", "data-source": alarm.source }, button);
}

export class AlarmList {
  // fetchAlarms: () => a promise of GET /alarms' answer; onSelect(alarm) on a click on one; onError(error) when a
  // request fails
  constructor(fetchAlarms, onSelect, onError) {
    this.onSelect = onSelect;
    this.list = byId("alarm-list");
    this.count = byId("alarm-count");
    this.shownText = null; // the lines drawn, so that an unchanged answer redraws nothing
    this.poller = new Poller(fetchAlarms, (alarms) => this.show(alarms), onError, POLL_MS);
  }

  start() {
    this.poller.start();
  }

  refresh() {
    this.poller.poll();
  }

  show(alarms) {
    const lines = alarmLines(alarms);
    const text = JSON.stringify(lines.map(({ alarm, ...shown }) => [alarm.buoy, alarm.source, shown]));
    if (text === this.shownText) return;
    this.shownText = text;
    this.count.textContent = String(lines.length);
    this.count.classList.toggle("none", lines.length === 0);
    this.count.title = lines.length === 1 ? "1 alarm" : `${lines.length} alarms`;
    if (!lines.length) {
      this.list.replaceChildren(h("li", { class: "hint", "data-testid": "alarms-empty" }, "no alarms"));
      return;
    }
    this.list.replaceChildren(...lines.map((line) => alarmItem(line, this.onSelect)));
  }
}
