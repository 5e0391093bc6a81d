// Time-series charts (uPlot) of the live flight: how far off the route the vehicle is (cross-track error),
// altitude and yaw, actual against desired. The two lines of a chart differ in colour, in lightness and in style,
// so that neither colour vision nor a grey print is needed to tell them apart: actual solid dark blue, desired
// dashed orange (drawn last, so it stays visible where the vehicle tracks it closely); the legend names the style
// too. Both axes carry their units. Time is the vehicle's clock in seconds since its boot, as the samples carry it.
const MAX_POINTS = 5000;
const HEIGHT = 170;

const ACTUAL = { label: "actual (solid)", stroke: "#0b3c6b", width: 2 };
const DESIRED = { label: "desired (dashed)", stroke: "#d55e00", dash: [7, 4], width: 2 };

// yUnit: the y axis's label ("m", "°")
function makeChart(uPlot, element, series, yUnit) {
  const width = () => Math.max(200, element.clientWidth || element.parentElement.clientWidth - 8);
  const opts = {
    width: width(),
    height: HEIGHT,
    scales: { x: { time: false } },
    axes: [
      { label: "vehicle clock (s since boot)", labelSize: 18 },
      { label: yUnit, labelSize: 18, size: 48 },
    ],
    series: [{ label: "t (s)" }, ...series],
    // the legend's marker drawn in its line's style: a dashed box for the dashed line
    legend: { live: false, markers: { dash: (u, i) => (u.series[i].dash ? "dashed" : "solid") } },
  };
  const data = [[], ...series.map(() => [])];
  const plot = new uPlot(opts, data, element);
  new ResizeObserver(() => plot.setSize({ width: width(), height: HEIGHT })).observe(element.parentElement);
  return { plot, data };
}

export class FlightCharts {
  constructor(uPlot) {
    const chart = (id, series, unit) => makeChart(uPlot, document.getElementById(id), series, unit);
    this.charts = {
      xte: chart("chart-xte", [{ label: "off the route", stroke: "#a11d1d", width: 2 }], "m off the route"),
      alt: chart("chart-alt", [ACTUAL, DESIRED], "m above home"),
      yaw: chart("chart-yaw", [ACTUAL, DESIRED], "° from north"),
    };
    this.lastT = null;
    this.dirty = false;
  }

  clear() {
    for (const chart of Object.values(this.charts)) {
      chart.data.forEach((column) => (column.length = 0));
      chart.plot.setData(chart.data);
    }
    this.lastT = null;
  }

  // sample: a telemetry sample (the track's series, GET /missions/{id}/track, or the live stream's mission.sample)
  add(sample) {
    if (!sample || sample.t_s == null || (this.lastT !== null && sample.t_s <= this.lastT)) return;
    this.lastT = sample.t_s;
    const deg = (r) => (r == null ? null : (r * 180) / Math.PI);
    const rows = {
      xte: [sample.cross_track_m ?? null],
      alt: [sample.alt_m ?? null, sample.ref_down == null ? null : -sample.ref_down],
      yaw: [deg(sample.yaw), deg(sample.ref_yaw)],
    };
    for (const [name, values] of Object.entries(rows)) {
      const data = this.charts[name].data;
      data[0].push(sample.t_s);
      values.forEach((v, i) => data[i + 1].push(v));
      if (data[0].length > MAX_POINTS) data.forEach((column) => column.shift());
    }
    this.dirty = true;
  }

  redraw() {
    if (!this.dirty) return;
    for (const chart of Object.values(this.charts)) chart.plot.setData(chart.data);
    this.dirty = false;
  }
}
