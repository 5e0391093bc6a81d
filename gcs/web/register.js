// The buoy register (GET /buoys) as a map overlay: a marker per register buoy in its IALA kind's colours
// (style.css .register-buoy), ringed with a count badge while it has open defects, dimmed while its inspection is
// overdue; a click opens its record (GET /buoys/{id}) in a popup: kind, light, last inspection, open defects, its
// AIS AtoN and the latest history. Fetched when the overlay is turned on and every 30 s while it is on and the tab
// is shown (poll.js), with the filters chosen in its control (a kind, overdue, open defects: GET /buoys'). Names,
// lights and notes come from the chart and from operators: text nodes only. The alarms
// (alarms.js, through app.js) take a buoy's position from the buoys it holds and open a buoy's popup with openBuoy().
import { h } from "./dom.js";
import { ageText } from "./atons.js";
import { Poller } from "./poll.js";

const L = window.L;
const POLL_MS = 30_000; // the register changes as missions land and operators act: minutes, not seconds
// Overdue for inspection: never inspected, or last inspected longer ago than this. 90 days is the page's own
// choice (a quarterly round), not the service's: GET /buoys' overdue_days takes any figure.
const OVERDUE_DAYS = 90;
const HISTORY_SHOWN = 10;
const KINDS = new Set(["port", "starboard", "north", "east", "south", "west", "isolated_danger", "safe_water",
  "special"]); // the service's BuoyKind
const EVENT_WORDS = {
  registered: "registered",
  charted: "chart changed",
  inspection: "inspected",
  defect_opened: "defect opened",
  defect_state: "defect set",
};

export function isOverdue(buoy, now = Date.now()) {
  if (!buoy.last_inspected_at) return true;
  const at = Date.parse(buoy.last_inspected_at);
  return Number.isNaN(at) || now - at > OVERDUE_DAYS * 86_400_000;
}

// "2026-11-27 20:31 UTC" from the service's ISO times (anything else as it came)
export function when(iso) {
  const at = new Date(iso);
  return Number.isNaN(at.getTime()) ? String(iso) : `${at.toISOString().slice(0, 16).replace("T", " ")} UTC`;
}

const kindClass = (kind) => (KINDS.has(kind) ? `kind-${kind}` : "kind-unknown"); // a class from a known word only
const kindText = (kind) => (kind ? kind.replaceAll("_", " ") : "unknown kind");

function buoyIcon(buoy) {
  // the colours dimmed while overdue, the defects' ring and count beside them (not dimmed with them)
  const classes = ["register-mark"];
  if (isOverdue(buoy)) classes.push("overdue");
  if (buoy.open_defects > 0) classes.push("has-defects");
  const mark = h("div", { class: classes.join(" "), "data-testid": "register-buoy", "data-id": buoy.id });
  mark.append(h("div", { class: `register-buoy ${kindClass(buoy.kind)}` }));
  if (buoy.open_defects > 0) mark.append(h("span", { class: "defect-count" }, String(buoy.open_defects)));
  return L.divIcon({ className: "", html: mark, iconSize: [14, 14], iconAnchor: [7, 7] });
}

function eventLine(event) {
  const words = [when(event.at), EVENT_WORDS[event.kind] ?? event.kind];
  const detail = event.detail || {};
  if (event.kind === "charted" && detail.changes) words.push(Object.keys(detail.changes).join(", "));
  if (event.kind === "defect_opened" && detail.code) words.push(detail.code);
  if (event.kind === "defect_state" && detail.code) words.push(`${detail.code}: ${detail.from} → ${detail.to}`);
  if (event.mission_id != null) words.push(`mission ${event.mission_id}`);
  if (event.verdict) words.push(event.verdict);
  const line = words.join(" · ");
  return h("li", {}, event.note ? `${line}: ${event.note}` : line);
}

function aisLine(detail) {
  const aton = detail.ais;
  if (!aton) return detail.mmsi ? `AIS: MMSI ${detail.mmsi}, no report heard` : "AIS: no AtoN matched";
  const flags = [aton.stale && "stale", aton.virtual && "virtual"];
  if (aton.off_position && aton.off_position_valid) flags.push("off position");
  const said = flags.filter(Boolean).map((flag) => `, ${flag}`).join("");
  const by = detail.ais_match === "mmsi" ? "by MMSI" : "by name";
  return `AIS: ${aton.name} (MMSI ${aton.mmsi}, matched ${by}), heard ${ageText(aton.age_s)}${said}`;
}

// The popup's content: a buoy's record (BuoyDetailOut) as text.
function buoyDetail(detail) {
  const latest = detail.latest_inspection;
  const inspected = latest
    ? `last inspection: ${when(latest.at)}, mission ${latest.mission_id}: ${latest.verdict}`
    : "last inspection: never";
  const defects = detail.defects.map((d) => h("li", {}, `${d.code} (${d.state})`));
  const overdue = isOverdue(detail) ? " (overdue)" : "";
  const newest = detail.history.slice(-HISTORY_SHOWN).reverse();
  const shown = detail.history.length > HISTORY_SHOWN ? `the last ${HISTORY_SHOWN} of ${detail.history.length}` : "";
  return h(
    "div",
    { class: "register-detail", "data-testid": "register-detail" },
    h("h3", {}, detail.name || detail.id),
    h("div", {}, `${kindText(detail.kind)}, ${detail.light ? `light ${detail.light}` : "unlit"}`),
    h("div", {}, inspected + overdue),
    h("div", {}, defects.length ? "open defects:" : "open defects: none"),
    defects.length ? h("ul", { "data-testid": "register-defects" }, ...defects) : "",
    h("div", { "data-testid": "register-ais" }, aisLine(detail)),
    h("div", { class: "history-head" }, `history${shown ? ` (${shown})` : ""}, newest first:`),
    h("ol", { class: "register-history", "data-testid": "register-history" }, ...newest.map(eventLine)),
  );
}

// The overlay's filters, GET /buoys' own (the service filters): a kind, overdue only, with open defects only. A
// control at the map's bottom left while the overlay is on; a change asks for the buoys at once.
const RegisterFilters = L.Control.extend({
  options: { position: "bottomleft" },
  initialize(onChange) {
    this.onChange = onChange;
  },
  onAdd() {
    const option = (kind) => h("option", { value: kind }, kindText(kind));
    const kinds = [h("option", { value: "" }, "every kind"), ...[...KINDS].map(option)];
    this.kind = h("select", { "aria-label": "register kind", "data-testid": "register-kind" }, ...kinds);
    this.overdue = h("input", { type: "checkbox", "data-testid": "register-overdue" });
    this.defects = h("input", { type: "checkbox", "data-testid": "register-defects-only" });
    for (const input of [this.kind, this.overdue, this.defects]) {
      input.addEventListener("change", () => this.onChange());
    }
    const box = h(
      "div",
      { class: "register-filters", "data-testid": "register-filters" },
      h("b", {}, "Register"),
      this.kind,
      h("label", {}, this.overdue, ` overdue (${OVERDUE_DAYS} d)`),
      h("label", {}, this.defects, " open defects"),
    );
    L.DomEvent.disableClickPropagation(box); // choosing a filter is no click on the map (which places a buoy)
    return box;
  },
  // GET /buoys' query: what is chosen, the rest left out
  filters() {
    if (!this.kind) return {};
    return {
      kind: this.kind.value || null,
      overdue_days: this.overdue.checked ? OVERDUE_DAYS : null,
      open_defects: this.defects.checked ? true : null,
    };
  },
});

export class RegisterLayer {
  // map: the Leaflet map; api: GcsApi (buoys(), buoy(id)); onError(error) when a request fails
  constructor(map, api, onError) {
    this.map = map;
    this.api = api;
    this.onError = onError;
    this.layer = L.layerGroup();
    this.shownText = null; // the latest answer drawn, so that an unchanged one redraws nothing (an open popup stays)
    this.shown = new Map(); // register id -> {buoy, marker}, as drawn
    this.filterControl = new RegisterFilters(() => this.poller.start(false));
    const ask = () => api.buoys(this.filterControl.filters());
    this.poller = new Poller(ask, (buoys, turnedOn) => this.draw(buoys, turnedOn), onError, POLL_MS);
    this.layer.on("add", () => {
      this.filterControl.addTo(this.map);
      this.poller.start(true);
    });
    this.layer.on("remove", () => this.stop());
  }

  stop() {
    this.poller.stop();
    this.filterControl.remove();
    this.layer.clearLayers();
    this.shownText = null;
    this.shown.clear();
  }

  isOn() {
    return this.poller.running;
  }

  // The buoy (a BuoyOut) of this register id as drawn, or null (the overlay off, or its answer not in yet).
  buoyById(id) {
    const entry = this.shown.get(id);
    return entry ? entry.buoy : null;
  }

  // While the overlay is on: the popup of the buoy ({id, name, lat, lon}: a BuoyOut, or a BuoyDetailOut), at its
  // marker (at its charted position when not drawn yet). False when the overlay is off.
  openBuoy(buoy) {
    if (!this.isOn()) return false;
    const entry = this.shown.get(buoy.id);
    this.open(entry ? entry.buoy : buoy, entry ? entry.marker.getLatLng() : L.latLng(buoy.lat, buoy.lon));
    return true;
  }

  // An answer of GET /buoys: drawn when it changed; turnedOn: the overlay's first, which may move the view
  draw(buoys, turnedOn) {
    const text = JSON.stringify(buoys);
    if (text !== this.shownText) this.show(buoys);
    this.shownText = text;
    if (turnedOn) this.bringIntoView(buoys);
  }

  show(buoys) {
    this.layer.clearLayers();
    this.shown.clear();
    for (const buoy of buoys) {
      const marker = L.marker([buoy.lat, buoy.lon], { icon: buoyIcon(buoy), title: buoy.name || buoy.id });
      marker.on("click", () => this.open(buoy, marker.getLatLng()));
      marker.addTo(this.layer);
      this.shown.set(buoy.id, { buoy, marker });
    }
  }

  // Turned on with none of the register's buoys in view (the map opens on the depot): the view moves to them,
  // else the operator would see nothing and not know why.
  bringIntoView(buoys) {
    if (!buoys.length) return;
    const view = this.map.getBounds();
    if (buoys.some((b) => view.contains([b.lat, b.lon]))) return;
    this.map.fitBounds(L.latLngBounds(buoys.map((b) => [b.lat, b.lon])).pad(0.05));
  }

  async open(buoy, latLng) {
    const popup = L.popup({ maxWidth: 360, maxHeight: 320 }).setLatLng(latLng);
    popup.setContent(h("div", { class: "register-detail" }, `${buoy.name || buoy.id}: loading…`)).openOn(this.map);
    try {
      popup.setContent(buoyDetail(await this.api.buoy(buoy.id)));
    } catch (error) {
      popup.close();
      this.onError(error);
    }
  }
}
