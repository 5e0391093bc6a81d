// A local metric grid drawn on canvas tiles: the map stays usable with no tile server (offline).
// Lines every `spacing` metres around an origin, using the local tangent-plane scale at the origin.
const METRES_PER_DEGREE_LAT = 111320;

export function metricGridLayer(L, origin, spacing = 100) {
  const mPerDegLon = METRES_PER_DEGREE_LAT * Math.cos((origin.lat * Math.PI) / 180);
  const Grid = L.GridLayer.extend({
    createTile(coords) {
      const tile = document.createElement("canvas");
      const size = this.getTileSize();
      tile.width = size.x;
      tile.height = size.y;
      const ctx = tile.getContext("2d");
      ctx.fillStyle = "#d6e8f2";
      ctx.fillRect(0, 0, size.x, size.y);
      const map = this._map;
      const nwPixel = coords.scaleBy(size);
      const nw = map.unproject(nwPixel, coords.z);
      const se = map.unproject(nwPixel.add(size), coords.z);
      const metresPerPixel = ((nw.lat - se.lat) * METRES_PER_DEGREE_LAT) / size.y;
      // zoomed out, lines at least 8 px apart: the spacing times the next power of ten that achieves it
      const minStep = metresPerPixel * 8;
      const step = minStep > spacing ? spacing * Math.pow(10, Math.ceil(Math.log10(minStep / spacing))) : spacing;
      const toPixel = (lat, lon) => map.project(L.latLng(lat, lon), coords.z).subtract(nwPixel);
      ctx.lineWidth = 1;
      const northFrom = Math.floor(((se.lat - origin.lat) * METRES_PER_DEGREE_LAT) / step);
      const northTo = Math.ceil(((nw.lat - origin.lat) * METRES_PER_DEGREE_LAT) / step);
      for (let k = northFrom; k <= northTo; k++) {
        const y = toPixel(origin.lat + (k * step) / METRES_PER_DEGREE_LAT, origin.lng).y;
        ctx.strokeStyle = k === 0 ? "#5a7d95" : "#a9c3d3";
        ctx.beginPath(); ctx.moveTo(0, y); ctx.lineTo(size.x, y); ctx.stroke();
      }
      const eastFrom = Math.floor(((nw.lng - origin.lng) * mPerDegLon) / step);
      const eastTo = Math.ceil(((se.lng - origin.lng) * mPerDegLon) / step);
      for (let k = eastFrom; k <= eastTo; k++) {
        const x = toPixel(origin.lat, origin.lng + (k * step) / mPerDegLon).x;
        ctx.strokeStyle = k === 0 ? "#5a7d95" : "#a9c3d3";
        ctx.beginPath(); ctx.moveTo(x, 0); ctx.lineTo(x, size.y); ctx.stroke();
      }
      ctx.fillStyle = "#5a7d95";
      ctx.font = "10px sans-serif";
      ctx.fillText(`grid ${step} m`, 4, 12);
      return tile;
    },
  });
  return new Grid({ attribution: `local grid, ${spacing} m` });
}

// Resolve true if one OpenStreetMap tile loads within timeoutMs, else false (offline).
export function tilesReachable(url, timeoutMs = 3000) {
  return new Promise((resolve) => {
    const img = new Image();
    const timer = setTimeout(() => { img.src = ""; resolve(false); }, timeoutMs);
    img.onload = () => { clearTimeout(timer); resolve(true); };
    img.onerror = () => { clearTimeout(timer); resolve(false); };
    img.src = url;
  });
}
