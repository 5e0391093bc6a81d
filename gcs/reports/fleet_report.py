"""A fleet mission's report: who flew what and who inspected what, as a figure and an index.html.

The figure draws each vehicle's share (its route from its home, in its colour, as the map page draws it) and the
track its part mission recorded, a lost vehicle's last position and the buoys it handed over; the page has the
fleet's figures (planned makespan, each part's flight time, the closest two vehicles came), a row per vehicle
(buoys, inspected, status, why it was lost and who took its buoys, its own report) and a row per buoy (the
vehicle that inspected it), then the inspection section of the single mission's report
(gcs.reports.inspection_report: every buoy's verdict, the map by verdict, the defective buoys' best frames) over the
records gathered from the parts. Every text from the missions goes through html.escape; the style is the mission
report's (gcs.reports.drawing.REPORT_STYLE, which the service's Content-Security-Policy allows by its hash).
"""

from __future__ import annotations

import html
from pathlib import Path
from typing import Any

import numpy as np

from gcs.domain.planning import Plan
from gcs.domain.schemas import FleetOut, FleetShareOut
from gcs.reports.drawing import REPORT_STYLE, column, new_figure, save_figure, sortie_style
from gcs.reports.inspection_report import InspectionSection, write_inspection_section
from gcs.reports.views import fleet_out
from gcs.storage import MissionRecord

FLEET_FIGURE = "fleet.png"  # a fleet mission's report has this figure and the inspection section's


def write_fleet_report(
    record: MissionRecord,
    parts: list[MissionRecord],
    samples: dict[int, list[dict[str, Any]]],
    out_dir: Path,
    inspections: InspectionSection | None = None,
) -> Path:
    """Draw the fleet figure and the inspection section and write index.html into out_dir (samples: each part's
    telemetry by mission id; inspections: the records gathered from the parts, by the fleet's input index, with
    the defective buoys' best frames: gcs.reports.inspection_report.load_fleet_inspections)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    plan = record.plan
    fleet = fleet_out(record)
    recorded = {part.vehicle_sysid: samples.get(part.id, []) for part in parts}
    # sysid -> its part's flown track in the fleet's frame
    tracks = {share.sysid: _flown_en(plan, recorded.get(share.sysid, [])) for share in fleet.shares}
    routes = [plan.frame.project(np.asarray(share.route)) for share in fleet.shares]
    _draw_fleet(plan, fleet, routes, tracks, out_dir / FLEET_FIGURE)
    # The inspection map draws each share's route, not the fleet plan's own (route_local): that is one tour from
    # the first vehicle's home through every share's buoys in turn, with legs no vehicle flew; and each vehicle's
    # track apart, never one line from one vehicle's last position to another's first.
    section = inspections or InspectionSection()
    inspection = write_inspection_section(plan, section, list(tracks.values()), out_dir, routes)
    index = out_dir / "index.html"
    index.write_text(fleet_report_html(record, fleet, parts, inspection))
    return index


def _flown_en(plan: Plan, samples: list[dict[str, Any]]) -> np.ndarray:
    """A part's recorded positions, (n, 2) east/north in the fleet's frame: projected from lat/lon, since each
    vehicle's local frame (the samples' north/east) is its own."""
    lat, lon = column(samples, "lat"), column(samples, "lon")
    located = ~(np.isnan(lat) | np.isnan(lon))
    return plan.frame.project(np.column_stack([lat[located], lon[located]])) if located.any() else np.empty((0, 2))


def _draw_fleet(
    plan: Plan, fleet: FleetOut, routes: list[np.ndarray], tracks: dict[int, np.ndarray], path: Path
) -> None:
    """Each share's route (`routes`, in the shares' order) and track (`tracks`, by sysid) in its colour."""
    figure, ax = new_figure(6.5)
    buoys = np.asarray(plan.buoys_local)
    for k, (share, route) in enumerate(zip(fleet.shares, routes, strict=True)):
        style = sortie_style(k)
        ax.plot(route[:, 0], route[:, 1], lw=1.2, label=f"vehicle {share.sysid}: planned", **style)
        flown = tracks[share.sysid]
        if len(flown):
            ax.plot(flown[:, 0], flown[:, 1], color=style["color"], lw=0.8, alpha=0.6)
            if share.lost:
                east, north = flown[-1]
                ax.scatter(east, north, marker="x", s=80, color="k", zorder=4, label=f"vehicle {share.sysid} lost")
        home = route[0]
        ax.scatter(*home, marker="s", color=style["color"], edgecolor="k", zorder=4)
    inspected = set(fleet.inspected_by)
    for index, (east, north) in enumerate(buoys):
        done = plan.buoy_ids[index] in inspected
        ax.scatter(east, north, marker="o", s=28, color="tab:green" if done else "tab:red", zorder=3)
        ax.annotate(plan.buoy_ids[index], (east, north), textcoords="offset points", xytext=(4, 4), fontsize=7)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set(xlabel="east (m)", ylabel="north (m)", title="Fleet: each vehicle's share, planned and flown")
    ax.legend(loc="best", fontsize=8)
    save_figure(figure, path)


def _flight_time_s(part: MissionRecord) -> float | None:
    tracking = part.results.tracking if part.results else None
    return tracking.flight_time_s if tracking else None


def _number(value: float | None, digits: int = 1) -> str:
    return "–" if value is None else f"{value:.{digits}f}"


def fleet_report_html(record: MissionRecord, fleet: FleetOut, parts: list[MissionRecord], inspection: str = "") -> str:
    """The page: figures, a row per vehicle and per buoy, the inspection section (`inspection`, HTML already
    escaped), then the fleet figure."""
    ids = record.plan.buoy_ids
    # each part's flight time (None: not flown, or no tracking figures)
    flown = {part.vehicle_sysid: _flight_time_s(part) for part in parts}
    separation = fleet.separation
    longest = max((t or 0.0 for t in flown.values()), default=None)
    rows = [
        ("status", f"{record.status}" + (f" ({record.reason})" if record.reason else "")),
        ("vehicles", str(len(fleet.shares))),
        ("planned makespan", f"{_number(fleet.makespan_s)} s"),
        (
            "flown, longest part",
            f"{_number(longest)} s",
        ),
        ("buoys inspected", f"{len(fleet.inspected_by)} / {len(ids)}"),
        ("layers", f"{_number(fleet.layer_gap_m)} m apart"),
        (
            "closest approach",
            f"{_number(separation.min_distance_m)} m (horizontal {_number(separation.min_horizontal_m)} m, "
            f"vertical {_number(separation.min_vertical_m)} m)",
        ),
    ]
    figures = "\n".join(f"<tr><th>{html.escape(k)}</th><td>{html.escape(v)}</td></tr>" for k, v in rows)

    def vehicle_row(k: int, share: FleetShareOut) -> str:
        handed = "; ".join(
            f"{', '.join(ids[b] for b in buoys)} to vehicle {sysid}" for sysid, buoys in share.handed_over.items()
        )
        cells = [
            str(len(share.buoys)),
            str(len(share.visited_buoys)),
            str(share.status),
            f"{_number(share.altitude_m, 0)} m",
            _number(share.predicted_time_s),
            _number(flown.get(share.sysid)),
            share.lost or "",
            handed,
        ]
        swatch = f'<span class="swatch sortie-{k % 6}"></span>'
        link = f'<a href="/missions/{share.mission_id}/report">mission {share.mission_id}</a>'
        body = "".join(f"<td>{html.escape(c)}</td>" for c in cells)
        return f"<tr><td>{swatch}{share.sysid}</td>{body}<td>{link}</td></tr>"

    heads = (
        "vehicle",
        "buoys",
        "inspected",
        "status",
        "layer",
        "predicted s",
        "flown s",
        "lost",
        "handed over",
        "part",
    )
    vehicle_rows = "\n".join(vehicle_row(k, s) for k, s in enumerate(fleet.shares))
    buoy_rows = "\n".join(
        f"<tr><td>{html.escape(ident)}</td><td>{html.escape(str(fleet.inspected_by.get(ident, 'nobody')))}</td></tr>"
        for ident in ids
    )
    return f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>Fleet mission {record.id} report</title>
<style>{REPORT_STYLE}</style></head>
<body>
<h1>Fleet mission {record.id} report</h1>
<p>Created {html.escape(record.created_at)}, last updated {html.escape(record.updated_at)}.</p>
<h2>Figures</h2>
<table data-testid="figures">
{figures}
</table>
<h2>Vehicles</h2>
<table data-testid="vehicles"><thead><tr>{"".join(f"<th>{h}</th>" for h in heads)}</tr></thead>
<tbody>
{vehicle_rows}
</tbody></table>
<h2>Buoys</h2>
<table data-testid="inspected-by"><thead><tr><th>buoy</th><th>inspected by vehicle</th></tr></thead>
<tbody>
{buoy_rows}
</tbody></table>
{inspection}
<h2>Flight</h2>
<figure><img src="{FLEET_FIGURE}" alt="fleet"></figure>
</body></html>
"""
