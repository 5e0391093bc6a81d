"""A fleet mission's report has the single mission's inspection section, over the records gathered from its parts:
a row per fleet buoy (a buoy re-shared in flight shows the record of the vehicle that inspected it), the map by
verdict, each defective buoy's best frame copied beside index.html from the part holding it, text escaped."""

from __future__ import annotations

import io
import re
from dataclasses import replace

import pytest
from PIL import Image
from stored_missions import FLIGHT

from gcs.domain.inspection import BuoyInspection, Finding, InspectionRecord, StoredFrame, gather_fleet_inspections
from gcs.domain.planning import BuoyMark, Plan, sorties_plan
from gcs.domain.records import PlanFleet, PlannedShare
from gcs.missions.inspector import charted_record, not_inspected
from gcs.reports.inspection_report import INSPECTION_FIGURE
from gcs.reports.report import write_stored_report
from gcs.storage import SqliteStorage

HOSTILE_ID = "<b>x</b>"
IDS = ["B1", HOSTILE_ID, "B3"]
HOMES = [(55.0, 12.0), (55.0, 12.001)]  # vehicle 1's, vehicle 2's
BUOYS = [(55.0004, 12.0), (55.0004, 12.001), (55.0008, 12.0005)]
MARKS = [BuoyMark("port", "Fl R 4s", 3.0), BuoyMark("starboard", "Fl G 5s", 3.0), BuoyMark()]


def jpeg() -> bytes:
    out = io.BytesIO()
    Image.new("RGB", (64, 36), (40, 90, 120)).save(out, "JPEG")
    return out.getvalue()


def part_plan(home: tuple[float, float], buoys: list[int]) -> Plan:
    """A part's plan: fleet buoys `buoys` (in flying order) as its own buoys 0, 1, ... from its vehicle's home."""
    plan = sorties_plan(home, [BUOYS[b] for b in buoys], [IDS[b] for b in buoys], [list(range(len(buoys)))], "t", 0)
    return replace(plan, marks=[MARKS[b] for b in buoys])


def fleet_plan() -> Plan:
    """Vehicle 1 flies B1 then B3 and is lost before B3; B3 goes to vehicle 2, which flies <b>x</b>."""
    shares = [
        PlannedShare(sysid=1, home=list(HOMES[0]), buoys=[0, 2], altitude_m=5.0, predicted_time_s=60.0,
                     length_m=200.0, lost="battery failsafe", handed_over={"2": [2]}),
        PlannedShare(sysid=2, home=list(HOMES[1]), buoys=[1, 2], altitude_m=8.0, predicted_time_s=70.0,
                     length_m=250.0),
    ]  # fmt: skip
    overview = sorties_plan(HOMES[0], BUOYS, IDS, [[0, 2, 1]], "fleet", 0.0)
    fleet = PlanFleet(makespan_s=70.0, total_time_s=130.0, layer_gap_m=3.0, shares=shares)
    return replace(overview, fleet=fleet, marks=MARKS)


def verdict(plan: Plan, index: int, name: str, findings: list[Finding], frame_ids: list[int]) -> InspectionRecord:
    """Buoy `index` of `plan` judged `name` ("ok" or "defect") from frames `frame_ids` (the last the best)."""
    charted, frames = charted_record(plan, index), list(range(len(frame_ids)))
    result = BuoyInspection(buoy=charted, verdict=name, findings=findings, observed=None, offset_m=None,
                            light_seen="flashing . G 5.0s", frames=frames)  # fmt: skip
    return InspectionRecord(buoy=index, buoy_id=plan.buoy_ids[index], result=result, frame_ids=frame_ids,
                            best_frame=frame_ids[-1] if frame_ids else None)  # fmt: skip


@pytest.fixture
def fleet(tmp_path):
    """The fleet mission stored with its two parts' records (part 1: B1 ok, B3 not reached; part 2, re-planned
    in flight with B3 appended: <b>x</b> light out, with a JPEG best frame, B3 ok) and a few samples each."""
    storage = SqliteStorage(tmp_path / "gcs.sqlite")
    first, second = part_plan(HOMES[0], [0, 2]), part_plan(HOMES[1], [1, 2])
    fleet_id, (first_id, second_id) = storage.create_fleet_mission(
        FLIGHT, fleet_plan(), [(FLIGHT, first, 1), (FLIGHT, second, 2)]
    )
    storage.set_inspection(first_id, verdict(first, 0, "ok", [], []))
    storage.set_inspection(first_id, not_inspected(first, 1, "not reached (the vehicle was lost)"))
    frame = jpeg()
    frame_id = storage.add_frame(second_id, frame_of(0), frame, 10**6)
    light_out = Finding(code="light_out", charted="Fl G 5s", seen="dark")
    storage.set_inspection(second_id, verdict(second, 0, "defect", [light_out], [frame_id]))
    storage.set_inspection(second_id, verdict(second, 1, "ok", [], []))
    for part_id, (lat, lon) in ((first_id, HOMES[0]), (second_id, HOMES[1])):
        storage.add_telemetry(part_id, [{"t_s": t, "lat": lat + 1e-4 * t, "lon": lon} for t in (0.0, 1.0, 2.0)])
    yield storage, storage.get_mission(fleet_id), frame
    storage.close()


def frame_of(buoy: int) -> StoredFrame:
    return StoredFrame(buoy=buoy, image_index=0, t_s=1.0, lat=55.0, lon=12.0, height_m=5.0, q=(1.0, 0.0, 0.0, 0.0),
                       file_url="mftp://[;comp=100]/IMG_000000.jpg")  # fmt: skip


def rows_of(page: str) -> list[list[str]]:
    """The inspection table's rows, cell texts (as written: escaped)."""
    table = page[page.index('<table data-testid="inspections">') :]
    body = table[: table.index("</table>")]
    return [re.findall(r"<td>(.*?)</td>", row) for row in re.findall(r"<tr class=[^>]*>(.*?)</tr>", body)]


def test_a_fleet_report_has_the_inspection_section_of_every_fleet_buoy(fleet, tmp_path):
    storage, record, frame = fleet
    index = write_stored_report(storage, record, tmp_path / "out")
    page, folder = index.read_text(), index.parent

    rows = rows_of(page)
    assert [row[:2] for row in rows] == [["B1", "ok"], ["&lt;b&gt;x&lt;/b&gt;", "defect"], ["B3", "ok"]]
    assert rows[1][2] == "light out: charted Fl G 5s, seen dark"
    assert '<p data-testid="inspection-counts">2 ok, 1 defect</p>' in page
    assert HOSTILE_ID not in page  # escaped everywhere: the table, the caption, the fleet's buoy table
    # the defective buoy's best frame, from part 2 (its buoy 0) as the fleet's buoy 1
    assert (folder / "defect-1.jpg").read_bytes() == frame
    assert '<img src="defect-1.jpg"' in page
    assert sorted(p.name for p in folder.glob("defect-*")) == ["defect-1.jpg"]
    assert (folder / INSPECTION_FIGURE).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert f'<img src="{INSPECTION_FIGURE}"' in page


def test_a_re_shared_buoy_takes_the_inspecting_vehicles_record_whichever_part_comes_first():
    first, second = part_plan(HOMES[0], [0, 2]), part_plan(HOMES[1], [1, 2])
    lost = (1, first, [not_inspected(first, 1, "not reached")])
    took = (2, second, [verdict(second, 1, "ok", [], [7])])
    for parts in ([lost, took], [took, lost]):
        [(mission_id, record)] = gather_fleet_inspections(fleet_plan(), parts)
        assert (mission_id, record.buoy, record.buoy_id, record.result.verdict) == (2, 2, "B3", "ok")
