// The Leaflet map: base layers (offline metric grid, OpenStreetMap when reachable), the offline chart of the
// imported cells, and overlays in one layer control (atons.js and register.js add theirs), the depot, the buoys
// (with their inspection's verdict as a badge once the watched mission has one), the planned route (dashed; one
// colour per sortie, with a legend, when the plan has several), the flown track and the vehicle. Icons and the
// legend are built as DOM elements, never HTML.
import { h, svg } from "./dom.js";
import { metricGridLayer, tilesReachable } from "./grid.js";
import { hasSortieFigures, legsOf, routeLook, sortieLook, swatch } from "./sorties.js";
import { verdictBadge } from "./verdicts.js";

const L = window.L;
const OSM_URL = "https://tile.openstreetmap.org/{z}/{x}/{y}.png";

// look: {label, cls, colour, verdict}; colour (a sortie's, or null) fills the marker through a CSS variable set on
// the element (CSSOM, which the page's Content-Security-Policy allows, unlike a style attribute); verdict (null:
// none) adds its badge at the marker's top right
function buoyIcon(look) {
  const icon = h("div", { class: `buoy-icon ${look.cls}${look.colour ? " in-sortie" : ""}` }, String(look.label));
  if (look.colour) icon.style.setProperty("--sortie-colour", look.colour);
  const html = look.verdict ? h("div", { class: "buoy-marker" }, icon, verdictBadge(look.verdict)) : icon;
  return L.divIcon({ className: "", html, iconSize: [22, 22], iconAnchor: [11, 11] });
}

function depotIcon() {
  const html = h("div", { class: "depot-icon", title: "depot" });
  return L.divIcon({ className: "", html, iconSize: [20, 20], iconAnchor: [10, 10] });
}

// An arrow pointing along the vehicle's heading (a fleet's vehicle: in its share's colour).
function vehicleIcon(yawDeg, colour = "#c2185b") {
  const shape = { d: "M0,-12 L8,10 L0,5 L-8,10 Z", fill: colour, stroke: "#fff", "stroke-width": 1.5 };
  const arrow = svg("svg", { width: 28, height: 28, viewBox: "-14 -14 28 28" }, svg("path", shape));
  arrow.style.transform = `rotate(${yawDeg}deg)`;
  return L.divIcon({ className: "vehicle-icon", html: arrow, iconSize: [28, 28], iconAnchor: [14, 14] });
}

// The legend of a plan's legs, bottom right: a swatch and "sortie k: n buoys, predicted X Wh" (a fleet's share:
// "vehicle N: n buoys, about T s") for each.
const SortieLegend = L.Control.extend({
  options: { position: "bottomright" },
  onAdd() {
    this.list = h("ul", {});
    return h("div", { class: "sortie-legend", "data-testid": "sortie-legend" }, this.list);
  },
  show(plan) {
    const line = (leg) => h("li", {}, swatch(routeLook(plan, leg.index)), leg.label);
    this.list.replaceChildren(...legsOf(plan).map(line));
  },
});

export class MissionMap {
  constructor(elementId) {
    this.map = L.map(elementId, { zoomControl: true });
    this.buoyLayer = L.layerGroup().addTo(this.map);
    this.buoyMarkers = new Map(); // buoy object -> marker
    this.buoyLooks = new Map(); // marker -> "label class" it shows, so an unchanged icon is not rebuilt
    this.routeLayer = L.featureGroup().addTo(this.map); // one dashed polyline per sortie
    this.legend = new SortieLegend();
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
    this.layerControl = L.control.layers(baseLayers, {}, { position: "topright" }).addTo(this.map);
    L.control.scale({ metric: true, imperial: false }).addTo(this.map);
    tilesReachable(OSM_URL.replace("{z}/{x}/{y}", "0/0/0")).then((online) => {
      if (online) {
        this.map.removeLayer(grid);
        osm.addTo(this.map);
      }
    });
  }

  // The offline chart (GET /basemap.geojson: the land, piers and depth contours of the chart cells the register
  // imported), an overlay over either base layer, on at first when there is any. Drawn in SVG with a class per
  // layer (the look in style.css), under the route and the track; a contour's depth is its tooltip.
  showChart(collection) {
    if (!collection.features.length) return;
    const pane = this.map.createPane("chart");
    pane.style.zIndex = 350; // over the tiles (200), under the overlay pane's route and track (400)
    const looks = {
      land: { className: "chart-land", fillColor: "#efe4c0", fillOpacity: 1, color: "#8c7a4b", weight: 1 },
      shoreline_construction: { className: "chart-pier", color: "#555", weight: 2 },
      depth_contour: { className: "chart-depth", color: "#6a9fd4", weight: 1, opacity: 0.8 },
    };
    const layer = L.geoJSON(collection, {
      pane: "chart",
      interactive: true,
      style: (feature) => looks[feature.properties.layer] || {},
      onEachFeature: (feature, path) => {
        const depth = feature.properties.depth_m;
        if (depth !== undefined) path.bindTooltip(`${depth} m depth contour`, { sticky: true });
      },
    });
    this.addOverlay(layer, "Chart (offline)", true);
  }

  // An overlay the operator turns on and off in the layer control (after showBaseLayers); shown: on at first.
  addOverlay(layer, name, shown) {
    this.layerControl.addOverlay(layer, name);
    if (shown) layer.addTo(this.map);
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
    const icon = buoyIcon({ label: this.buoyMarkers.size + 1, cls: "", colour: null, verdict: null });
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
      const { label, visited, current, sortie, verdict } = markings[index];
      const look = {
        label,
        cls: visited ? "visited" : current ? "current" : "",
        colour: sortie == null ? null : sortieLook(sortie).colour,
        verdict,
      };
      const marker = this.buoyMarkers.get(buoy);
      const key = `${look.label} ${look.cls} ${look.colour} ${look.verdict}`;
      if (this.buoyLooks.get(marker) === key) return;
      this.buoyLooks.set(marker, key);
      marker.setIcon(buoyIcon(look));
    });
  }

  fitBuoys(buoys) {
    if (buoys.length) this.map.fitBounds(L.latLngBounds(buoys.map((b) => [b.lat, b.lon])).pad(0.2));
  }

  // plan: a POST /plans answer or a mission. Each leg's route ([[lat, lon], ...] from the depot, or a fleet
  // vehicle's home, round its buoys and back): one dashed as a route always looked, several each in its own look.
  showRoute(plan) {
    this.clearRoute();
    for (const leg of legsOf(plan)) {
      const look = routeLook(plan, leg.index);
      L.polyline(leg.route, { color: look.colour, weight: 3, dashArray: look.dash }).addTo(this.routeLayer);
    }
    if (hasSortieFigures(plan)) {
      this.legend.addTo(this.map);
      this.legend.show(plan);
    }
    const bounds = this.routeLayer.getBounds();
    if (bounds.isValid()) this.map.fitBounds(bounds, { padding: [30, 30] });
  }

  clearRoute() {
    this.routeLayer.clearLayers();
    this.legend.remove();
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

  // A fleet: a marker per vehicle (/ws `vehicles`, as GET /vehicles lists them), titled "vehicle N", in the colour
  // colourOf(sysid) gives it (its share's in the fleet mission shown; null: the one vehicle's colour).
  showVehicles(vehicles, colourOf) {
    this.fleetMarkers ??= new Map(); // sysid -> marker
    for (const vehicle of vehicles) {
      if (!vehicle.connected || vehicle.lat == null) continue;
      const icon = vehicleIcon(((vehicle.yaw ?? 0) * 180) / Math.PI, colourOf(vehicle.sysid) ?? undefined);
      const marker = this.fleetMarkers.get(vehicle.sysid);
      if (marker) marker.setLatLng([vehicle.lat, vehicle.lon]).setIcon(icon);
      else {
        const options = { icon, zIndexOffset: 1000, title: `vehicle ${vehicle.sysid}` };
        this.fleetMarkers.set(vehicle.sysid, L.marker([vehicle.lat, vehicle.lon], options).addTo(this.map));
      }
    }
  }

  showVehicle(lat, lon, yawDeg) {
    if (!this.vehicleMarker) {
      const options = { icon: vehicleIcon(yawDeg), zIndexOffset: 1000, title: "vehicle" };
      this.vehicleMarker = L.marker([lat, lon], options).addTo(this.map);
    } else this.vehicleMarker.setLatLng([lat, lon]).setIcon(vehicleIcon(yawDeg));
  }
}
