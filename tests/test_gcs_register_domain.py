"""The register's pure rules: an import's duplicates reported (not merged), a mark as a register buoy, the defects a
record opens, and when an AIS report is an off-station alarm."""

from __future__ import annotations

from gcs.domain.charted_marks import ChartedMark
from gcs.domain.inspection import BuoyInspection, Finding, InspectedBuoy, InspectionRecord
from gcs.domain.register import RegisterBuoy, StoredBuoy, ais_alarm, defect_findings, from_mark, without_duplicates

SOURCE = "US4MD81M edition 31 update 0"


def test_an_id_given_twice_registers_neither_and_a_shared_name_keeps_each_buoy_apart():
    buoys = [RegisterBuoy("A", 1.0, 2.0, "Light 1"), RegisterBuoy("A", 1.1, 2.0, "Light 1A"),
             RegisterBuoy("B", 1.2, 2.0, "Light 2"), RegisterBuoy("C", 1.3, 2.0, "Light 2")]  # fmt: skip
    kept, reports = without_duplicates(buoys)
    assert [b.id for b in kept] == ["B", "C"]
    assert reports == [
        "id 'A' is given 2 times in this import: none of them registered",
        "name 'Light 2' is shared by 2 buoys: each kept under its own id",
    ]


def test_a_beacon_stands_fixed_and_a_buoy_takes_the_missions_swing_radius():
    beacon = ChartedMark("L1", 38.9, -76.4, "BCNLAT", "Light 4", "starboard", colours=("red",), region="B")
    buoy = ChartedMark("L2", 38.9, -76.4, "BOYLAT", "Buoy 2", "port", shape="can", light="Fl G 4s")
    assert (from_mark(beacon, SOURCE).swing_radius_m, from_mark(buoy, SOURCE).swing_radius_m) == (0.0, 5.0)
    assert from_mark(beacon, SOURCE).charted == {
        "object_class": "BCNLAT", "beacon": True, "preferred_channel": None, "shape": None, "colours": ["red"],
        "colour_pattern": None, "region": "B", "other_lights": [],
    }  # fmt: skip


def test_a_defect_verdict_opens_one_defect_per_finding_code():
    charted = InspectedBuoy(lat=1.0, lon=2.0, kind="port", light="Fl G 4s", swing_radius_m=5.0)
    findings = [Finding(code="wrong_colour"), Finding(code="off_station", offset_m=9.0), Finding(code="wrong_colour")]

    def record(verdict: str) -> InspectionRecord:
        result = BuoyInspection(buoy=charted, verdict=verdict, findings=findings, observed=None, offset_m=None,
                                light_seen=None, frames=[])  # fmt: skip
        return InspectionRecord(buoy=0, buoy_id="B1", result=result)

    assert list(defect_findings(record("defect"))) == ["wrong_colour", "off_station"]
    assert defect_findings(record("not_inspected")) == {}


def test_an_ais_report_is_an_alarm_off_position_or_beyond_the_swing_circle_and_the_fix_never_when_stale():
    stored = StoredBuoy(RegisterBuoy("A", 1.0, 2.0, "Light 1", swing_radius_m=5.0), 993672001, "t", "t", None, 0)
    report = {"stale": False, "virtual": False, "off_position": False, "off_position_valid": True,
              "position_accuracy": True, "received_at": "2026-11-27T18:00:00+00:00"}  # fmt: skip
    assert ais_alarm(stored, report, 6.9) is None  # inside 5 m + the DGNSS fix's 2 m
    assert ais_alarm(stored, report, 7.1).why.startswith("its reported position is 7.1 m")
    assert ais_alarm(stored, report | {"position_accuracy": False}, 14.9) is None  # a fix worse than 10 m
    flagged = report | {"off_position": True}
    assert ais_alarm(stored, flagged, 1.0).why == "the AtoN reports itself off position"
    assert ais_alarm(stored, flagged | {"off_position_valid": False}, 1.0) is None
    assert ais_alarm(stored, flagged | {"stale": True}, 50.0) is None
    assert ais_alarm(stored, flagged | {"virtual": True}, 50.0) is None
