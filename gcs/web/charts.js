// Time-series charts (uPlot) of the live flight: cross-track error, altitude and yaw, actual vs desired
// (the desired, dashed, is drawn last so it stays visible where the vehicle tracks it closely).
const MAX_POINTS = 5000;

function makeChart(uPlot, element, series) {
  const width = () => Math.max(200, element.clientWidth || element.parentElement.clientWidth - 8);
  const opts = {
    width: width(),
    height: 160,
    scales: { x: { time: false } },
    axes: [{ label: "t (s, vehicle)" }, {}],
    series: [{ label: "t" }, ...series],
    legend: { live: false },
  };
  const data = [[], ...series.map(() => [])];
  const plot = new uPlot(opts, data, element);
  new ResizeObserver(() => plot.setSize({ width: width(), height: 160 })).observe(element.parentElement);
  return { plot, data };
}

export class FlightCharts {
  constructor(uPlot) {
    this.charts = {
      xte: makeChart(uPlot, document.getElementById("chart-xte"), [{ label: "cross-track", stroke: "#b23b3b" }]),
      alt: makeChart(uPlot, document.getElementById("chart-alt"), [
        { label: "actual", stroke: "#2f8f4f", width: 2 },
        { label: "desired", stroke: "#1f6fb2", dash: [5, 4], width: 1.5 },
      ]),
      yaw: makeChart(uPlot, document.getElementById("chart-yaw"), [
        { label: "actual", stroke: "#2f8f4f", width: 2 },
        { label: "desired", stroke: "#1f6fb2", dash: [5, 4], width: 1.5 },
      ]),
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
