"""The reports' inspection section (gcs.reports.report, gcs.reports.fleet_report): every buoy's verdict, findings
and light read as a table, a figure of the route (a fleet's: each share's) with each buoy coloured and marked by its
verdict (an off-station buoy with a line to where it was seen), and the best frame of each defective buoy copied
beside index.html and shown.

`load_inspections` reads what the section needs from storage (the records, the defective buoys' best frames), and
`load_fleet_inspections` a fleet mission's, from its parts; `write_inspection_section` draws the figure, writes the
frames and returns the section's HTML. The words for the findings are the map page's (gcs/web/verdicts.js says the
same). Every text from the mission (buoy ids, reasons,
light readings) goes through html.escape; the frames' file names are made of the buoy's input index, never its id.
"""

from __future__ import annotations

import html
import re
from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gcs.domain.inspection import HeldInspection, InspectionRecord, gather_fleet_inspections
from gcs.domain.planning import Plan
from gcs.reports.drawing import new_figure, save_figure
from gcs.storage import MissionRecord, Storage

INSPECTION_FIGURE = "inspection.png"
# a defective buoy's best frame in the report folder: defect-<input index>.<jpg|png>
FRAME_FILE = re.compile(r"defect-(\d{1,4})\.(jpg|png)")
FRAME_SIGNATURES = {b"\xff\xd8\xff": "jpg", b"\x89PNG\r\n\x1a\n": "png"}  # what is copied: images only

# verdict -> (colour, matplotlib marker, words); Okabe & Ito's green and vermillion, a grey, and a hollow ring for a
# buoy with no record yet. Told apart by the marker's shape as well as its colour.
VERDICT_LOOK = {
    "ok": ("#009e73", "o", "ok"),
    "defect": ("#d55e00", "X", "defect"),
    "not_inspected": ("#7f7f7f", "s", "not inspected"),
    None: ("#7f7f7f", "o", "no record"),
}
COLUMNS = ("buoy", "verdict", "findings", "light charted", "light read", "offset m", "frames", "reason")


@dataclass(frozen=True)
class InspectionSection:
    """What the report shows of a mission's inspections: the records (by input index) and the bytes of each
    defective buoy's best frame (by input index)."""

    records: list[InspectionRecord] = field(default_factory=list)
    best_frames: dict[int, bytes] = field(default_factory=dict)


def load_inspections(storage: Storage, mission_id: int) -> InspectionSection:
    """The mission's inspection records and its defective buoys' best frames, from storage."""
    return _section(storage, [HeldInspection(mission_id, record) for record in storage.inspections(mission_id)])


def load_fleet_inspections(storage: Storage, fleet: MissionRecord, parts: Sequence[MissionRecord]) -> InspectionSection:
    """A fleet mission's records, gathered from its parts by the fleet's input index (gather_fleet_inspections),
    and its defective buoys' best frames, each read from the part that holds it."""
    held = gather_fleet_inspections(fleet.plan, [(part.id, part.plan, storage.inspections(part.id)) for part in parts])
    return _section(storage, held)


def _section(storage: Storage, held: Sequence[HeldInspection]) -> InspectionSection:
    """The records, and the best frame of each defective one from the mission holding its frames."""
    frames = {}
    for mission_id, record in held:
        if record.result.verdict == "defect" and record.best_frame is not None:
            data = storage.frame_data(mission_id, record.best_frame)
            if data is not None:
                frames[record.buoy] = data
    return InspectionSection([record for _, record in held], frames)


def is_frame_file(name: str) -> bool:
    """Whether `name` is a frame file the section writes (the report route serves these and its figures only)."""
    return FRAME_FILE.fullmatch(name) is not None


def frame_file_name(index: int, data: bytes) -> str | None:
    """The file name for buoy `index`'s best frame, by what its bytes are (None: not a JPEG or PNG)."""
    kind = next((ext for magic, ext in FRAME_SIGNATURES.items() if data.startswith(magic)), None)
    return None if kind is None else f"defect-{index}.{kind}"


# ----- words
def _number(value: Any, digits: int = 1) -> str:
    return "?" if not isinstance(value, int | float) else f"{value:.{digits}f}"


def _colours(value: Any) -> str:
    return "/".join(str(v) for v in value) if isinstance(value, list | tuple) else str(value)


def describe_finding(finding: Mapping[str, Any]) -> str:
    """One finding in plain words with its figures (the map page's words, gcs/web/verdicts.js)."""
    f, code = finding, finding.get("code")
    if code == "off_station":
        return (
            f"off station: {_number(f.get('offset_m'))} m from its charted position, bearing "
            f"{_number(f.get('bearing_deg'), 0)}° (swing radius {_number(f.get('swing_radius_m'))} m)"
        )
    if code == "light_out":
        return f"light out: charted {f.get('charted')}, seen {f.get('seen')}"
    if code == "wrong_character":
        return f"wrong light character: charted {f.get('charted')}, seen {f.get('seen')}"
    if code == "wrong_period":
        return (
            f"wrong light period: charted {_number(f.get('charted_period_s'))} s, "
            f"seen {_number(f.get('seen_period_s'))} s"
        )
    if code == "wrong_colour":
        return f"wrong light colour: charted {f.get('charted')}, seen {f.get('seen')}"
    if code == "wrong_body_colour":
        return f"wrong body colour: {_colours(f.get('expected'))} expected, {_colours(f.get('seen'))} seen"
    if code == "not_found":
        return f"not found in any of its {f.get('frames')} frames ({f.get('why')})"
    figures = ", ".join(f"{name} {value}" for name, value in f.items() if name != "code")
    return f"{code}: {figures}" if figures else str(code)


def counts_line(plan: Plan, records: Sequence[InspectionRecord]) -> str:
    """'3 ok, 1 defect, 1 not inspected, 2 without a record' (the kinds present, in that order)."""
    counts = Counter(r.result.verdict for r in records)
    missing = len(plan.buoy_ids) - len({r.buoy for r in records})
    parts = [f"{counts[v]} {VERDICT_LOOK[v][2]}" for v in ("ok", "defect", "not_inspected") if counts[v]]
    return ", ".join([*parts, *([f"{missing} without a record"] if missing else [])])


# ----- the figure
def draw_inspection_map(
    plan: Plan,
    records: Sequence[InspectionRecord],
    tracks_en: Sequence[np.ndarray],
    path: Path,
    routes_en: Sequence[np.ndarray] | None = None,
) -> None:
    """The routes (dashed; default: the plan's) and the flown tracks (`tracks_en`, each (n, 2) east/north, may be
    empty: a fleet's vehicles each have their own, never joined into one line) with each buoy drawn by its verdict
    (VERDICT_LOOK), its swing circle, and a line from its charted position to where it was seen. Each route
    starts at its depot (a fleet's: each vehicle's home)."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Circle

    figure, ax = new_figure(6.0)
    routes = [plan.route_local()] if routes_en is None else routes_en
    for route in routes:
        ax.plot(route[:, 0], route[:, 1], "--", color="0.6", lw=1, zorder=1)
    for track in tracks_en:
        if len(track):
            ax.plot(track[:, 0], track[:, 1], color="tab:blue", lw=0.8, alpha=0.6, zorder=1)
    by_index = {r.buoy: r for r in records}
    buoys = np.asarray(plan.buoys_local, dtype=float).reshape(-1, 2)
    counts: Counter[str | None] = Counter()
    for index, (east, north) in enumerate(buoys):
        record = by_index.get(index)
        verdict = None if record is None else record.result.verdict
        counts[verdict] += 1
        colour, marker, _ = VERDICT_LOOK.get(verdict, VERDICT_LOOK[None])
        hollow = verdict is None
        ax.scatter([east], [north], s=90, marker=marker, zorder=3, linewidths=1.5,
                   facecolors="none" if hollow else colour, edgecolors=colour)  # fmt: skip
        if record is not None:
            ax.add_patch(Circle((east, north), record.result.buoy.swing_radius_m, fill=False, color=colour, lw=0.6))
            seen = record.result.observed
            if seen is not None:
                seen_en = plan.frame.project(np.array([[seen.lat, seen.lon]]))[0]
                ax.plot([east, seen_en[0]], [north, seen_en[1]], color=colour, lw=1.2, zorder=2)
                ax.scatter([seen_en[0]], [seen_en[1]], s=18, marker="+", color=colour, zorder=3)
        ax.annotate(plan.buoy_ids[index], (east, north), textcoords="offset points", xytext=(8, 8), fontsize=8)
    depots = np.array([route[0] for route in routes]).reshape(-1, 2)
    ax.scatter(depots[:, 0], depots[:, 1], marker="s", color="k", zorder=3)
    handles = [
        Line2D([], [], ls="", marker=VERDICT_LOOK[v][1], markersize=9, color=VERDICT_LOOK[v][0],
               markerfacecolor="none" if v is None else VERDICT_LOOK[v][0], label=f"{VERDICT_LOOK[v][2]} ({counts[v]})")
        for v in ("ok", "defect", "not_inspected", None)
        if counts[v]
    ]  # fmt: skip
    handles += [
        Line2D([], [], ls="", marker="s", color="k", label="depot" if len(routes) == 1 else "depots (homes)"),
        Line2D([], [], ls="--", color="0.6", label="planned route" if len(routes) == 1 else "planned routes"),
        Line2D([], [], marker="+", color="0.3", label="where seen (line from the charted position)"),
    ]
    ax.set_aspect("equal", adjustable="datalim")
    ax.set(xlabel="east (m)", ylabel="north (m)", title="Inspection: each buoy by its verdict (circle: swing radius)")
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)  # off the buoys
    save_figure(figure, path)


# ----- the section
def write_inspection_section(
    plan: Plan,
    section: InspectionSection,
    tracks_en: Sequence[np.ndarray],
    out_dir: Path,
    routes_en: Sequence[np.ndarray] | None = None,
) -> str:
    """Draw INSPECTION_FIGURE (draw_inspection_map: `tracks_en`, `routes_en`) and copy the defective buoys' best
    frames into out_dir (the frames of an earlier drawing removed first); returns the section's HTML. A mission
    with no record gets a line saying so, no figure."""
    for old in out_dir.iterdir():
        if is_frame_file(old.name):
            old.unlink()
    (out_dir / INSPECTION_FIGURE).unlink(missing_ok=True)
    if not section.records:
        return '<h2>Inspection</h2>\n<p data-testid="inspection-none">No inspection records.</p>'
    draw_inspection_map(plan, section.records, tracks_en, out_dir / INSPECTION_FIGURE, routes_en)
    frame_files = {}
    for index, data in sorted(section.best_frames.items()):
        name = frame_file_name(index, data)
        if name is not None:
            (out_dir / name).write_bytes(data)
            frame_files[index] = name
    return inspection_html(plan, section.records, frame_files)


def _row(plan: Plan, index: int, record: InspectionRecord | None) -> str:
    if record is None:
        cells = [plan.buoy_ids[index], "no record", "", plan.mark(index).light or "–", "–", "–", "0", ""]
        verdict = "none"
    else:
        r = record.result
        cells = [
            record.buoy_id,
            VERDICT_LOOK.get(r.verdict, VERDICT_LOOK[None])[2],
            "; ".join(describe_finding(f.model_dump()) for f in r.findings) or "–",
            r.buoy.light or "unlit",
            r.light_seen or "–",
            "–" if r.offset_m is None else f"{r.offset_m:.2f}",
            str(len(record.frame_ids)),
            r.reason or "",
        ]
        verdict = r.verdict
    return f'<tr class="verdict-{verdict}">' + "".join(f"<td>{html.escape(c)}</td>" for c in cells) + "</tr>"


def inspection_html(plan: Plan, records: Sequence[InspectionRecord], frame_files: Mapping[int, str]) -> str:
    """The section: the counts, a row per buoy (input order), the figure, then each defective buoy's best frame."""
    by_index = {r.buoy: r for r in records}
    rows = "\n".join(_row(plan, index, by_index.get(index)) for index in range(len(plan.buoy_ids)))
    head = "".join(f"<th>{html.escape(name)}</th>" for name in COLUMNS)
    frames = "\n".join(
        f'<figure><img src="{name}" alt="best frame of buoy {index + 1}">'
        f"<figcaption>{html.escape(by_index[index].buoy_id)}: "
        f"{html.escape('; '.join(describe_finding(f.model_dump()) for f in by_index[index].result.findings))}"
        "</figcaption></figure>"
        for index, name in sorted(frame_files.items())
    )
    defects = f"<h3>Defective buoys: the best frame of each</h3>\n{frames}" if frames else ""
    return (
        "<h2>Inspection</h2>\n"
        f'<p data-testid="inspection-counts">{html.escape(counts_line(plan, records))}</p>\n'
        f'<table data-testid="inspections"><thead><tr>{head}</tr></thead>\n<tbody>\n{rows}\n</tbody></table>\n'
        f'<figure><img src="{INSPECTION_FIGURE}" alt="inspection map"></figure>\n'
        f"{defects}"
    )
