// The AIS AtoNs (GET /ais/atons) as a map overlay: a small diamond per AtoN that reports a position, polled while
// the overlay is on and the tab is shown. Its look says its flags (style.css .aton): a stale report hollow and grey
// (no current position), a virtual AtoN dashed (nothing physical is there), one off position in red (only where
// the flag counts: off_position_valid). Its tooltip says the same in words. Names come from the air: text nodes.
import { h, svg } from "./dom.js";
import { Poller } from "./poll.js";

const L = window.L;
const POLL_MS = 10_000; // AtoNs report every 3 minutes: a 10 s poll shows a new report soon enough

// "42 s ago", "3 min ago", "2 h ago"
export function ageText(seconds) {
  if (seconds < 120) return `${Math.round(seconds)} s ago`;
  if (seconds < 7200) return `${Math.round(seconds / 60)} min ago`;
  return `${Math.round(seconds / 3600)} h ago`;
}

// The flags of a report in words (none: []).
export function atonFlags(aton, staleAfterS) {
  const flags = [];
  if (aton.stale) flags.push(`stale: no report for over ${Math.round(staleAfterS)} s, no current position`);
  if (aton.virtual) flags.push("virtual: nothing physical is at this position");
  if (aton.off_position && aton.off_position_valid) flags.push("off position: it reports itself off its station");
  if (aton.conflict) flags.push("conflict: another AtoN reports the same MMSI");
  return flags;
}

function atonClasses(aton) {
  const classes = ["aton"];
  if (aton.stale) classes.push("stale");
  if (aton.virtual) classes.push("virtual");
  if (aton.off_position && aton.off_position_valid) classes.push("off-position");
  return classes.join(" ");
}

function atonIcon(aton) {
  const diamond = svg("polygon", { points: "7,1 13,7 7,13 1,7" });
  const html = svg("svg", { class: atonClasses(aton), width: 14, height: 14, viewBox: "0 0 14 14" }, diamond);
  html.setAttribute("data-testid", "aton");
  html.setAttribute("data-mmsi", String(aton.mmsi));
  html.setAttribute("aria-label", `AtoN ${aton.name}`);
  return L.divIcon({ className: "aton-icon", html, iconSize: [14, 14], iconAnchor: [7, 7] });
}

// The tooltip: name, MMSI and type, age (counted on from when it was fetched), the flags; built when it opens.
function atonTooltip(aton, fetchedAt, staleAfterS) {
  const age = aton.age_s + (Date.now() - fetchedAt) / 1000;
  const lines = [`MMSI ${aton.mmsi}, ${aton.aid_type_name.replaceAll("_", " ")}`, `heard ${ageText(age)}`];
  lines.push(...atonFlags(aton, staleAfterS));
  return h(
    "div",
    { class: "aton-tip", "data-testid": "aton-tooltip" },
    h("b", {}, aton.name || "(no name)"),
    ...lines.map((line) => h("div", {}, line)),
  );
}

export class AtonLayer {
  // fetchAtons: () => a promise of GET /ais/atons' answer; onError(error) when it fails
  constructor(fetchAtons, onError) {
    this.layer = L.layerGroup();
    this.markers = new Map(); // key (MMSI, name, rank among the same) -> {marker, look}
    const show = (answer) => this.show(answer.atons, answer.stale_after_s, Date.now());
    this.poller = new Poller(fetchAtons, show, onError, POLL_MS);
    this.layer.on("add", () => this.poller.start());
    this.layer.on("remove", () => this.poller.stop());
  }

  // Each AtoN with a position: a marker moved and its icon replaced only when its look changed (an open tooltip
  // stays open); the markers of AtoNs no longer listed are removed.
  show(atons, staleAfterS, fetchedAt) {
    const seen = new Map();
    const kept = new Set();
    for (const aton of atons) {
      if (aton.lat == null || aton.lon == null) continue;
      const name = `${aton.mmsi} ${aton.name}`;
      const rank = seen.get(name) ?? 0; // an MMSI in conflict may list two AtoNs of one name far apart
      seen.set(name, rank + 1);
      const key = `${name} ${rank}`;
      kept.add(key);
      const look = `${atonClasses(aton)} ${aton.name}`;
      let entry = this.markers.get(key);
      if (!entry) {
        const marker = L.marker([aton.lat, aton.lon], { icon: atonIcon(aton) });
        entry = { marker, look };
        this.markers.set(key, entry);
        marker.addTo(this.layer);
      } else {
        entry.marker.setLatLng([aton.lat, aton.lon]);
        if (entry.look !== look) entry.marker.setIcon(atonIcon(aton));
        entry.look = look;
      }
      const tip = () => atonTooltip(aton, fetchedAt, staleAfterS);
      if (entry.marker.getTooltip()) entry.marker.setTooltipContent(tip); // binding anew would close an open one
      else entry.marker.bindTooltip(tip, { direction: "top" });
    }
    for (const [key, entry] of this.markers) {
      if (kept.has(key)) continue;
      this.layer.removeLayer(entry.marker);
      this.markers.delete(key);
    }
  }
}
