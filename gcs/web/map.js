// The Leaflet map: base layers (offline metric grid, OpenStreetMap when reachable), the depot, the buoys,
// the planned route (dashed), the flown track and the vehicle. Icons are built as DOM elements, never HTML.
import { h } from "./dom.js";
import { metricGridLayer, tilesReachable } from "./grid.js";

const L = window.L;
const OSM_URL = "https://tile.openstreetmap.org/{z}/{x}/{y}.png";
const SVG_NS = "http://www.w3.org/2000/svg";

function buoyIcon(label, cls) {
  const html = h("div", { class: `buoy-icon ${cls}` }, String(label));
  return L.divIcon({ className: "", html, iconSize: [22, 22], iconAnchor: [11, 11] });
}

function depotIcon() {
  const html = h("div", { class: "depot-icon", title: "depot" });
  return L.divIcon({ className: "", html, iconSize: [20, 20], iconAnchor: [10, 10] });
}

// An arrow pointing along the vehicle's heading.
function vehicleIcon(yawDeg) {
  const svg = document.createElementNS(SVG_NS, "svg");
  for (const [name, value] of Object.entries({ width: 28, height: 28, viewBox: "-14 -14 28 28" })) {
    svg.setAttribute(name, value);
  }
  svg.style.transform = `rotate(${yawDeg}deg)`;
  const arrow = document.createElementNS(SVG_NS, "path");
  const shape = { d: "M0,-12 L8,10 L0,5 L-8,10 Z", fill: "#c2185b", stroke: "#fff", "stroke-width": 1.5 };
  for (const [name, value] of Object.entries(shape)) arrow.setAttribute(name, value);
  svg.append(arrow);
  return L.divIcon({ className: "vehicle-icon", html: svg, iconSize: [28, 28], iconAnchor: [14, 14] });
}

export class MissionMap {
  constructor(elementId) {
    this.map = L.map(elementId, { zoomControl: true });
    this.buoyLayer = L.layerGroup().addTo(this.map);
    this.buoyMarkers = new Map(); // buoy object -> marker
    this.buoyLooks = new Map(); // marker -> "label class" it shows, so an unchanged icon is not rebuilt
    this.route = L.polyline([], { color: "#1f6fb2", weight: 3, dashArray: "8 6" }).addTo(this.map);
    this.track = L.polyline([], { color: "#c2185b", weight: 3 }).addTo(this.map);
    this.depotMarker = null;
    this.vehicleMarker = null;
  }

  // handler({lat, lon}) on every click on the map (not on a marker)
  onClick(handler) {
    this.map.on("click", (event) => handler({ lat: event.latlng.lat, lon: event.latlng.lng }));
  }

  // Centre on the depot with the offline grid, then switch to OpenStreetMap if its tiles load.
  showBaseLayers(depot) {
    const centre = [depot.lat, depot.lon];
    this.map.setView(centre, 15);
    const grid = metricGridLayer(L, L.latLng(centre)).addTo(this.map);
    const osm = L.tileLayer(OSM_URL, { maxZoom: 19, attribution: "© OpenStreetMap contributors" });
    const baseLayers = { "Metric grid (offline)": grid, OpenStreetMap: osm };
    L.control.layers(baseLayers, {}, { position: "topright" }).addTo(this.map);
    L.control.scale({ metric: true, imperial: false }).addTo(this.map);
    tilesReachable(OSM_URL.replace("{z}/{x}/{y}", "0/0/0")).then((online) => {
      if (online) {
        this.map.removeLayer(grid);
        osm.addTo(this.map);
      }
    });
  }

  setDepot(depot) {
    const position = [depot.lat, depot.lon];
    if (!this.depotMarker) {
      const options = { icon: depotIcon(), title: "depot", zIndexOffset: 500 };
      this.depotMarker = L.marker(position, options).addTo(this.map);
    } else this.depotMarker.setLatLng(position);
  }

  // buoy: {id, lat, lon}; onClick(buoy) when its marker is clicked. The marker's title (a DOM property) is
  // the buoy's name.
  addBuoy(buoy, onClick) {
    const icon = buoyIcon(this.buoyMarkers.size + 1, "");
    const marker = L.marker([buoy.lat, buoy.lon], { icon, title: buoy.id || "buoy" });
    marker.on("click", () => onClick(buoy));
    marker.addTo(this.buoyLayer);
    this.buoyMarkers.set(buoy, marker);
  }

  removeBuoy(buoy) {
    const marker = this.buoyMarkers.get(buoy);
    this.buoyLayer.removeLayer(marker);
    this.buoyMarkers.delete(buoy);
    this.buoyLooks.delete(marker);
  }

  clearBuoys() {
    this.buoyLayer.clearLayers();
    this.buoyMarkers.clear();
    this.buoyLooks.clear();
  }

  // markings: state.buoyMarkings(), parallel to buoys. An icon is replaced only when its look changes.
  markBuoys(buoys, markings) {
    buoys.forEach((buoy, index) => {
      const { label, visited, current } = markings[index];
      const cls = visited ? "visited" : current ? "current" : "";
      const marker = this.buoyMarkers.get(buoy);
      const look = `${label} ${cls}`;
      if (this.buoyLooks.get(marker) === look) return;
      this.buoyLooks.set(marker, look);
      marker.setIcon(buoyIcon(label, cls));
    });
  }

  fitBuoys(buoys) {
    if (buoys.length) this.map.fitBounds(L.latLngBounds(buoys.map((b) => [b.lat, b.lon])).pad(0.2));
  }

  // route: [[lat, lon], ...] from the depot round the buoys and back
  showRoute(route) {
    this.route.setLatLngs(route);
    if (route.length) this.map.fitBounds(this.route.getBounds(), { padding: [30, 30] });
  }

  clearRoute() {
    this.route.setLatLngs([]);
  }

  setTrack(points) {
    this.track.setLatLngs(points);
  }

  // Extend the flown track (the live stream repeats a sample while the vehicle holds still).
  extendTrack(lat, lon) {
    const points = this.track.getLatLngs();
    const last = points[points.length - 1];
    if (!last || last.lat !== lat || last.lng !== lon) this.track.addLatLng([lat, lon]);
  }

  showVehicle(lat, lon, yawDeg) {
    if (!this.vehicleMarker) {
      const options = { icon: vehicleIcon(yawDeg), zIndexOffset: 1000, title: "vehicle" };
      this.vehicleMarker = L.marker([lat, lon], options).addTo(this.map);
    } else this.vehicleMarker.setLatLng([lat, lon]).setIcon(vehicleIcon(yawDeg));
  }
}
