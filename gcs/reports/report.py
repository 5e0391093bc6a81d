"""The mission report: the paper's Section VI (route, flown track, tracking error, altitude and yaw tracking,
ESO estimates) drawn from one recorded mission, as PNG figures and an index.html with the figures table. A
mission of several sorties draws each sortie's route in its own colour; one planned for a battery (issue 12) adds
a per-sortie table and a chart of the energy predicted against the energy the vehicle reported using. The
inspection section (gcs.reports.inspection_report) tables every buoy's verdict, findings and light read, maps the
buoys by verdict and shows each defective buoy's best frame, copied into the folder.

`report_series` turns the stored samples into time series (pure); `write_report` draws them into a folder;
`cached_report` keeps one folder per mission under a cache root and redraws it only when the mission changed
(its `updated_at` or its number of samples), for `python -m gcs report` and GET /missions/{id}/report.
Matplotlib is used through its object API (no pyplot state), so reports can be drawn from worker threads.
"""

from __future__ import annotations

import html
import json
import math
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

from gcs.domain.planning import Plan
from gcs.domain.records import MissionResults
from gcs.domain.schemas import SortieOut
from gcs.reports.drawing import REPORT_STYLE, SORTIE_COLOURS, column, new_figure, save_figure, sortie_style
from gcs.reports.fleet_report import FLEET_FIGURE, write_fleet_report
from gcs.reports.inspection_report import (
    INSPECTION_FIGURE,
    InspectionSection,
    is_frame_file,
    load_fleet_inspections,
    load_inspections,
    write_inspection_section,
)
from gcs.reports.views import sorties_out
from gcs.storage import MissionRecord, Storage, StoredFlightLog

FIGURES = ("route.png", "tracking_error.png", "cross_track.png", "altitude.png", "yaw.png", "eso.png")
ENERGY_FIGURE = "energy.png"  # drawn only for a mission planned with energy figures
# every file a report folder may hold (a fleet mission's report: index.html, FLEET_FIGURE and INSPECTION_FIGURE
# only), besides the defective buoys' frames (is_report_file)
REPORT_FILES = ("index.html", *FIGURES, ENERGY_FIGURE, INSPECTION_FIGURE, FLEET_FIGURE)
# Okabe & Ito's colour-blind-safe palette less its yellow and black, as the map page draws sorties
# (gcs/web/sorties.js); past six sorties the colours repeat with another dash.
STAMP_FILE = "stamp.json"


def is_report_file(name: str) -> bool:
    """Whether `name` may be a file of a report folder (what GET /missions/{id}/report/{name} serves)."""
    return name in REPORT_FILES or is_frame_file(name)


class ReportError(LookupError):
    """The mission to report on does not exist (the message says which)."""


@dataclass
class ReportSeries:
    """A recorded flight as arrays over the vehicle's time (seconds). NaN where a sample lacked the value."""

    t_s: np.ndarray
    east: np.ndarray
    north: np.ndarray
    altitude: np.ndarray
    ref_altitude: np.ndarray
    yaw_deg: np.ndarray
    ref_yaw_deg: np.ndarray
    cross_track_m: np.ndarray
    position_error_m: np.ndarray  # 3-D distance from the reference trajectory point (the ADRC tracking error)
    eso: dict[str, np.ndarray] = field(default_factory=dict)  # name -> (n, k) estimates, NaN when absent


def _wrap_deg(angle_rad: np.ndarray) -> np.ndarray:
    return np.degrees((angle_rad + math.pi) % (2 * math.pi) - math.pi)


def _eso_series(samples: list[dict[str, Any]]) -> dict[str, np.ndarray]:
    names = sorted({name for s in samples for name in (s.get("eso") or {})})
    series = {}
    for name in names:
        width = max(len(np.atleast_1d(s["eso"][name])) for s in samples if s.get("eso") and name in s["eso"])
        rows = []
        for s in samples:
            value = (s.get("eso") or {}).get(name)
            row = np.full(width, np.nan)
            if value is not None:
                values = np.array([np.nan if v is None else v for v in np.atleast_1d(value)], dtype=float)
                row[: len(values)] = values
            rows.append(row)
        series[name] = np.array(rows).reshape(len(samples), width)
    return series


def report_series(samples: list[dict[str, Any]]) -> ReportSeries:
    """Stored telemetry samples -> the time series the report draws (pure)."""
    north, east, down = (column(samples, k) for k in ("north", "east", "down"))
    ref_north, ref_east, ref_down = (column(samples, k) for k in ("ref_north", "ref_east", "ref_down"))
    error = np.sqrt((ref_north - north) ** 2 + (ref_east - east) ** 2 + (ref_down - down) ** 2)
    return ReportSeries(
        t_s=column(samples, "t_s"),
        east=east,
        north=north,
        altitude=-down,
        ref_altitude=-ref_down,
        yaw_deg=_wrap_deg(column(samples, "yaw")),
        ref_yaw_deg=_wrap_deg(column(samples, "ref_yaw")),
        cross_track_m=column(samples, "cross_track_m"),
        position_error_m=error,
        eso=_eso_series(samples),
    )


def _rms(values: np.ndarray) -> float | None:
    finite = values[np.isfinite(values)]
    return float(np.sqrt(np.mean(finite**2))) if len(finite) else None


def _max(values: np.ndarray) -> float | None:
    finite = values[np.isfinite(values)]
    return float(finite.max()) if len(finite) else None


def _yaw_error_deg(series: ReportSeries) -> np.ndarray:
    return (series.ref_yaw_deg - series.yaw_deg + 180.0) % 360.0 - 180.0


def summary_rows(record: MissionRecord, series: ReportSeries) -> list[tuple[str, str]]:
    """The figures table: (what, value) pairs, all from the record and the series (pure)."""
    plan = record.plan
    results = record.results or MissionResults()
    tracking, buoys = results.tracking, results.buoys or []

    def metres(value: float | None, digits: int = 3) -> str:
        return "–" if value is None else f"{value:.{digits}f} m"

    in_flight = np.isfinite(series.cross_track_m)
    closest = [b.closest_m for b in buoys if b.closest_m is not None]
    return [
        ("status", record.status + (f" ({record.reason})" if record.reason else "")),
        ("buoys", str(len(plan.order))),
        *_battery_rows(plan),
        ("planner", f"{plan.method}, {plan.elapsed_s:.2f} s"),
        ("planned route", f"{plan.length_m:.1f} m ({plan.improvement_pct:.1f} % shorter than the input order)"),
        ("flown (horizontal)", metres(tracking.distance_flown_m if tracking else None, 1)),
        ("flight time (vehicle)", _seconds(tracking.flight_time_s if tracking else None)),
        ("buoys reached", f"{sum(1 for b in buoys if b.reached)} of {len(plan.order)}"),
        ("worst closest approach", metres(_max(np.array(closest, dtype=float)))),
        ("acceptance radius", f"{record.flight.acceptance_radius_m:g} m"),
        ("cross-track RMS", metres(tracking.rms_cross_track_m if tracking else None)),
        ("cross-track max", metres(tracking.max_cross_track_m if tracking else None)),
        ("3-D tracking error RMS (on legs)", metres(_rms(series.position_error_m[in_flight]))),
        ("3-D tracking error max (on legs)", metres(_max(series.position_error_m[in_flight]))),
        ("altitude error RMS (on legs)", metres(_rms((series.ref_altitude - series.altitude)[in_flight]))),
        ("yaw error RMS (on legs)", _degrees(_rms(_yaw_error_deg(series)[in_flight]))),
        ("samples", str(len(series.t_s))),
    ]


def _battery_rows(plan: Plan) -> list[tuple[str, str]]:
    """The sorties and the battery they were planned for (none for a single tour without energy planning)."""
    rows = [("sorties", str(len(plan.sortie_orders())))] if plan.sorties or plan.energy else []
    if plan.energy:
        e = plan.energy
        rows.append(
            (
                "battery",
                f"{e.pack['capacity_mah']:.0f} mAh pack ({e.pack_source}), reserve {e.reserve_pct:.0f} % "
                f"({e.reserve_source}), margin {e.margin_pct:g} %: {e.budget_wh:.2f} Wh a sortie",
            )
        )
    return rows


def _seconds(value: float | None) -> str:
    return "–" if value is None else f"{value:.1f} s"


def _degrees(value: float | None) -> str:
    return "–" if value is None else f"{value:.2f}°"


def sortie_label(sortie: SortieOut) -> str:
    """'sortie 2: 5 buoys, predicted 12.1 Wh' (the map page's legend says the same)."""
    predicted = sortie.predicted_energy_wh
    energy = "" if predicted is None else f", predicted {predicted:.1f} Wh"
    return f"sortie {sortie.index + 1}: {len(sortie.order)} buoys{energy}"


def _draw_route(plan: Plan, radius_m: float, series: ReportSeries, path: Path) -> None:
    figure, ax = new_figure(6.0)
    buoys = np.asarray(plan.buoys_local)
    colour_of = {index: "tab:orange" for index in plan.order}  # a single tour: as it always looked
    if plan.sorties:
        for sortie in sorties_out(plan):
            style = sortie_style(sortie.index)
            route = plan.sortie_plan(sortie.index).route_local()
            ax.plot(route[:, 0], route[:, 1], lw=1.4, label=sortie_label(sortie), **style)
            colour_of.update(dict.fromkeys(sortie.order, style["color"]))
        ax.plot(series.east, series.north, color="k", lw=1, alpha=0.8, label="flown track")
    else:
        route = plan.route_local()
        ax.plot(route[:, 0], route[:, 1], "--", color="0.5", lw=1, label="planned route")
        ax.plot(series.east, series.north, color="tab:blue", lw=1.2, label="flown track")
    colours = [colour_of[index] for index in range(len(buoys))]
    ax.scatter(buoys[:, 0], buoys[:, 1], marker="o", color=colours, zorder=3, label="buoys")
    for visit, index in enumerate(plan.order, start=1):
        east, north = buoys[index]
        ax.add_patch(_circle((east, north), radius_m, colour_of[index]))
        ax.annotate(
            f"{plan.buoy_ids[index]} ({visit})", (east, north), textcoords="offset points", xytext=(5, 5), fontsize=8
        )
    ax.scatter([0.0], [0.0], marker="s", color="k", zorder=3, label="depot")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set(xlabel="east (m)", ylabel="north (m)", title="Route: planned and flown (visiting order in brackets)")
    ax.legend(loc="best", fontsize=8)
    save_figure(figure, path)


def _circle(centre: tuple[float, float], radius: float, colour: str):
    from matplotlib.patches import Circle

    return Circle(centre, radius, fill=False, color=colour, lw=0.8)


def energy_error_pct(sortie: SortieOut) -> float | None:
    """The energy model's error on a flown sortie, in % of the energy used: (used - predicted) / used."""
    used, predicted = sortie.used_energy_wh, sortie.predicted_energy_wh
    if used is None or predicted is None or used <= 0.0:
        return None
    return 100.0 * (used - predicted) / used


def _draw_energy(sorties: list[SortieOut], budget_wh: float, path: Path) -> None:
    """Per sortie: the predicted energy (pale) beside the energy used (with the error in %), against the budget."""
    from matplotlib.patches import Patch

    figure, ax = new_figure()
    width = 0.38
    for s in sorties:
        colour, x = sortie_style(s.index)["color"], s.index
        if s.predicted_energy_wh is not None:
            ax.bar(x - width / 2, s.predicted_energy_wh, width, color=colour, alpha=0.4, edgecolor=colour)
        used, error = s.used_energy_wh, energy_error_pct(s)
        if used is not None:
            ax.bar(x + width / 2, used, width, color=colour, edgecolor="k")
        text = "not flown" if used is None else "–" if error is None else f"{error:+.1f} %"
        ax.annotate(text, (x + width / 2, used or 0.0), textcoords="offset points", xytext=(0, 3), ha="center",
                    fontsize=8)  # fmt: skip
    ax.axhline(budget_wh, color="0.3", ls="--", lw=1)
    ax.set_xticks(range(len(sorties)), [f"sortie {s.index + 1}" for s in sorties])
    ax.set_xlim(-0.6, len(sorties) - 0.4)  # room for every used bar, flown or not
    ax.margins(y=0.25)  # and above them for the legend
    ax.set(ylabel="Wh", title="Energy per sortie: predicted and used (error = (used − predicted) / used)")
    ax.grid(alpha=0.3, axis="y")
    handles = [
        Patch(facecolor="0.6", alpha=0.4, edgecolor="0.6", label="predicted (energy model)"),
        Patch(facecolor="0.6", edgecolor="k", label="used (the vehicle's BATTERY_STATUS)"),
        ax.get_lines()[-1],
    ]
    handles[-1].set_label(f"budget a sortie ({budget_wh:.1f} Wh)")
    ax.legend(handles=handles, loc="upper left", ncols=3, fontsize=8)
    save_figure(figure, path)


def _draw_lines(path: Path, title: str, ylabel: str, t_s: np.ndarray, lines: list[tuple[np.ndarray, str]]) -> None:
    draw_series(path, title, "vehicle time (s)", ylabel, [(t_s, values, label) for values, label in lines])


def draw_series(
    path: Path,
    title: str,
    xlabel: str,
    ylabel: str,
    lines: list[tuple[np.ndarray, np.ndarray, str]],
    shade: tuple[float, float] | None = None,
) -> None:
    """Curves (x, y, label), each on its own x values (e.g. two missions around the same event), in one PNG;
    `shade` greys an x interval."""
    figure, ax = new_figure()
    if shade is not None:
        ax.axvspan(*shade, color="0.9", zorder=0)
    for x, values, label in lines:
        ax.plot(x, values, lw=1, label=label)
    ax.set(xlabel=xlabel, ylabel=ylabel, title=title)
    ax.grid(alpha=0.3)
    if len(lines) > 1:
        ax.legend(loc="best", fontsize=8)
    save_figure(figure, path)


def _draw_eso(series: ReportSeries, path: Path) -> None:
    lines = []
    for name, values in series.eso.items():
        axes = "xyz" if values.shape[1] == 3 else [str(i) for i in range(values.shape[1])]
        lines += [(values[:, k], f"{name} {axis}" if values.shape[1] > 1 else name) for k, axis in enumerate(axes)]
    if not lines:
        lines = [(np.full(len(series.t_s), np.nan), "no estimates recorded (no offboard controller?)")]
    _draw_lines(path, "ESO total-disturbance estimates z3 (paper eq. 11, Figure 7)", "m/s²", series.t_s, lines)


def write_report(
    record: MissionRecord,
    samples: list[dict[str, Any]],
    out_dir: Path,
    inspections: InspectionSection | None = None,
    flight_log: StoredFlightLog | None = None,
) -> Path:
    """Draw every figure and write index.html into out_dir; returns the index.html path. `inspections`: the
    mission's inspection records and defective buoys' best frames (none: the section says there are none);
    `flight_log`: the vehicle's log as the service fetched it (linked), or why it could not."""
    out_dir.mkdir(parents=True, exist_ok=True)
    plan = record.plan
    series = report_series(samples)
    t = series.t_s
    _draw_route(plan, record.flight.acceptance_radius_m, series, out_dir / "route.png")
    _draw_lines(
        out_dir / "tracking_error.png",
        "3-D tracking error |reference − position|",
        "m",
        t,
        [(series.position_error_m, "tracking error")],
    )
    _draw_lines(
        out_dir / "cross_track.png",
        "Cross-track error to the planned leg",
        "m",
        t,
        [(series.cross_track_m, "cross-track")],
    )
    _draw_lines(
        out_dir / "altitude.png",
        "Altitude: desired and actual",
        "m",
        t,
        [(series.ref_altitude, "desired"), (series.altitude, "actual")],
    )
    _draw_lines(
        out_dir / "yaw.png",
        "Yaw: desired and actual",
        "degrees",
        t,
        [(series.ref_yaw_deg, "desired"), (series.yaw_deg, "actual")],
    )
    _draw_eso(series, out_dir / "eso.png")
    sorties = sorties_out(plan, record.progress.sorties_flown)
    figures: tuple[str, ...] = FIGURES
    if plan.energy:
        _draw_energy(sorties, plan.energy.budget_wh, out_dir / ENERGY_FIGURE)
        figures = (*FIGURES, ENERGY_FIGURE)
    flown = np.isfinite(series.east) & np.isfinite(series.north)
    track = np.column_stack([series.east[flown], series.north[flown]])
    inspection = write_inspection_section(plan, inspections or InspectionSection(), [track], out_dir)
    index = out_dir / "index.html"
    shown = sorties if plan.sorties or plan.energy else []
    inspection += flight_log_section(record.id, flight_log)
    index.write_text(report_html(record, summary_rows(record, series), shown, figures, inspection))
    return index


SORTIE_COLUMNS = (
    "sortie", "buoys (in order)", "length m", "predicted Wh", "predicted time s", "margin Wh", "margin %",
    "used Wh", "error %", "predicted landing %", "measured landing %", "battery warning",
)  # fmt: skip


def report_html(
    record: MissionRecord,
    rows: list[tuple[str, str]],
    sorties: list[SortieOut] | None = None,
    figures: tuple[str, ...] = FIGURES,
    inspection: str = "",
) -> str:
    """The page: figures table, per-sortie table (for `sorties`, SortieOut documents), per-buoy table, the
    inspection section (`inspection`, HTML already escaped), then the PNGs (by relative name, so the folder is
    portable)."""
    table = "\n".join(f"<tr><th>{html.escape(k)}</th><td>{html.escape(v)}</td></tr>" for k, v in rows)
    buoys = (record.results or MissionResults()).buoys or []
    arrivals = record.progress.reached_wall_at
    buoy_rows = "\n".join(
        f"<tr><td>{html.escape(b.id)}</td><td>{'yes' if b.reached else 'no'}</td>"
        f"<td>{_cell(b.closest_m, 2)}</td><td>{_cell(b.arrival_s, 1)}</td><td>{_utc(arrivals.get(b.index))}</td></tr>"
        for b in buoys
    )
    images = "\n".join(f'<figure><img src="{name}" alt="{name[:-4]}"></figure>' for name in figures)
    events = _events_table(record)
    return f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>Mission {record.id} report</title>
<style>{REPORT_STYLE}</style></head>
<body>
<h1>Mission {record.id} report</h1>
<p>Created {html.escape(record.created_at)}, last updated {html.escape(record.updated_at)}.</p>
<h2>Figures</h2>
<table data-testid="figures">
{table}
</table>
{_sortie_table(record, sorties or [])}
<h2>Buoys</h2>
<table><thead><tr><th>buoy</th><th>reached</th><th>closest m</th><th>arrival s (vehicle time)</th>
<th>arrived (UTC)</th></tr></thead>
<tbody>
{buoy_rows}
</tbody></table>
{inspection}
{events}
<h2>Flight</h2>
{images}
</body></html>
"""


def flight_log_section(mission_id: int, flight_log: StoredFlightLog | None) -> str:
    """The vehicle's flight log: a link to GET /missions/{id}/log, or the note saying why there is none ("" for a
    mission that never flew). The note may quote the vehicle: escaped."""
    if flight_log is None:
        return ""
    if flight_log.size_bytes is None:
        text = html.escape(flight_log.note or "not downloaded")
        return f'\n<h2>Flight log</h2>\n<p data-testid="flight-log">{text}</p>'
    size = f"{flight_log.size_bytes / 1024:.0f} kB"
    link = f'<a href="/missions/{mission_id}/log" download="mission-{mission_id}.ulg">mission-{mission_id}.ulg</a>'
    return (
        f'\n<h2>Flight log</h2>\n<p data-testid="flight-log">{link} ({size}, ULog: the vehicle\'s log '
        f"{flight_log.vehicle_log_id}, downloaded {html.escape(flight_log.downloaded_at)})</p>"
    )


def _utc(unix_s: float | None) -> str:
    """A time of day as the report gives it: "2026-11-27 23:45:02 UTC" ("-": not known)."""
    if unix_s is None:
        return "-"
    return datetime.fromtimestamp(unix_s, UTC).strftime("%Y-%m-%d %H:%M:%S UTC")


def _events_table(record: MissionRecord) -> str:
    """The mission's event log: its status changes (with their reasons) and the vehicle's events (STATUSTEXTs by
    severity, mode changes), in time order (an event without a time first), every text escaped (a vehicle's words
    are never markup)."""
    rows = [(_unix(e.at), "mission", "", str(e.status) + (f": {e.reason}" if e.reason else "")) for e in record.events]
    for e in record.progress.vehicle_events:
        vehicle_time = f" (vehicle time {e.t_s:.1f} s)" if e.t_s is not None else ""
        rows.append((e.at.timestamp() if e.at else None, "vehicle", e.severity or "", e.text + vehicle_time))
    if not rows:
        return ""
    rows.sort(key=lambda row: -math.inf if row[0] is None else row[0])
    cells = "\n".join(
        "<tr>" + "".join(f"<td>{html.escape(cell)}</td>" for cell in (_utc(at), source, severity, text)) + "</tr>"
        for at, source, severity, text in rows
    )
    return (
        '<h2>Events</h2>\n<table data-testid="events"><thead><tr><th>time (UTC)</th><th>from</th><th>severity</th>'
        f"<th>what</th></tr></thead>\n<tbody>\n{cells}\n</tbody></table>"
    )


def _unix(iso: str) -> float | None:
    """A stored ISO time as unix seconds (None: not a time)."""
    try:
        return datetime.fromisoformat(iso).timestamp()
    except ValueError:
        return None


def _sortie_table(record: MissionRecord, sorties: list[SortieOut]) -> str:
    """The sorties, predicted against used energy ("" without sorties)."""
    if not sorties:
        return ""
    ids = record.plan.buoy_ids

    def row(s: SortieOut) -> str:
        flown = s.used_energy_wh is not None or s.landing_charge_pct is not None
        warning = s.battery_warning or ("none" if flown else "–")
        swatch = f'<span class="swatch sortie-{s.index % len(SORTIE_COLOURS)}"></span>'
        cells = [
            ", ".join(ids[b] for b in s.order),
            _cell(s.length_m, 0),
            _cell(s.predicted_energy_wh, 2),
            _cell(s.predicted_time_s, 0),
            _cell(s.margin_wh, 2),
            _cell(s.margin_pct, 1),
            _cell(s.used_energy_wh, 2),
            _cell(energy_error_pct(s), 1),
            _cell(s.predicted_landing_charge_pct, 0),
            _cell(s.landing_charge_pct, 0),
            warning,
        ]
        return f"<tr><td>{swatch}{s.index + 1}</td>" + "".join(f"<td>{html.escape(c)}</td>" for c in cells) + "</tr>"

    head = "".join(f"<th>{html.escape(name)}</th>" for name in SORTIE_COLUMNS)
    body = "\n".join(row(s) for s in sorties)
    return (
        "<h2>Sorties</h2>\n<p>Energy predicted by the energy model against the energy the vehicle reported using "
        "(BATTERY_STATUS); error = (used − predicted) / used.</p>\n"
        f'<table data-testid="sorties"><thead><tr>{head}</tr></thead>\n<tbody>\n{body}\n</tbody></table>'
    )


def _cell(value: float | None, digits: int) -> str:
    return "–" if value is None else f"{value:.{digits}f}"


def cached_report(storage: Storage, mission_id: int, cache_root: Path) -> Path:
    """The mission's report folder under cache_root, drawn again only when the mission changed since.
    Raises ReportError for an unknown mission."""
    record = storage.get_mission(mission_id)
    if record is None:
        raise ReportError(f"no mission {mission_id} in {storage.location}")
    out_dir = cache_root / f"mission-{mission_id}"
    parts = storage.fleet_parts(mission_id) if record.is_fleet else []
    counted = [mission_id, *(part.id for part in parts)]
    stamp = {
        "updated_at": [record.updated_at, *(part.updated_at for part in parts)],
        "samples": sum(storage.telemetry_count(i) for i in counted),
    }
    stamp_path = out_dir / STAMP_FILE
    index = out_dir / "index.html"
    try:
        if index.exists() and json.loads(stamp_path.read_text()) == stamp:
            return index
    except (OSError, ValueError):
        pass
    write_stored_report(storage, record, out_dir)
    stamp_path.write_text(json.dumps(stamp))
    return index


def write_stored_report(storage: Storage, record: MissionRecord, out_dir: Path) -> Path:
    """A stored mission's report into out_dir: a mission's (write_report), or a fleet mission's, over its parts'
    telemetry and inspections (gcs.reports.fleet_report)."""
    if not record.is_fleet:
        inspections = load_inspections(storage, record.id)
        return write_report(record, storage.telemetry(record.id), out_dir, inspections, storage.flight_log(record.id))

    parts = storage.fleet_parts(record.id)
    samples = {part.id: storage.telemetry(part.id) for part in parts}
    return write_fleet_report(record, parts, samples, out_dir, load_fleet_inspections(storage, record, parts))
