"""The register's pure rules: an import's duplicates reported (not merged), a mark as a register buoy, the defects a
record opens, when an AIS report is an off-station alarm, and which AtoN is which register buoy."""

from __future__ import annotations

from gcs.domain.charted_marks import ChartedMark
from gcs.domain.inspection import BuoyInspection, Finding, InspectedBuoy, InspectionRecord
from gcs.domain.register import (
    NAME_MATCH_M,
    RegisterBuoy,
    StoredBuoy,
    ais_alarm,
    current_report,
    defect_findings,
    from_mark,
    match_atons,
    without_duplicates,
)
from uavcore.geodesy import LocalFrame

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


def stored_buoy(buoy_id: str, name: str | None, mmsi: int | None = None, at: tuple[float, float] = (38.95, -76.45)):
    return StoredBuoy(RegisterBuoy(buoy_id, *at, name), mmsi, "t", "t", None, 0)


def aton(mmsi: int, name: str, north_m: float = 0.0, **flags) -> dict:
    """An AtonOut document `north_m` north of (38.95, -76.45)."""
    lat, lon = LocalFrame(38.95, -76.45).unproject([[0.0, north_m]])[0]
    return {"mmsi": mmsi, "name": name, "lat": lat, "lon": lon, "stale": False, "virtual": False} | flags


def test_an_aton_is_a_buoys_by_its_mmsi_else_by_its_name_within_a_nautical_mile_and_never_by_a_guess():
    buoys = [
        stored_buoy("A", "Annapolis 4", mmsi=993672001),
        stored_buoy("B", "Green 1"),  # no MMSI: its name, close by
        stored_buoy("C", "Red 2"),  # its name, but too far
        stored_buoy("D", "Twin"),  # two AtoNs of its name: ambiguous
        stored_buoy("E", "Claimed"),  # its name's AtoN has buoy F's MMSI
        stored_buoy("F", "Other", mmsi=993672009),
    ]
    atons = [
        aton(993672001, "SOMETHING ELSE", 3000.0),  # an MMSI match needs neither name nor distance
        aton(993672002, "GREEN  1", 40.0),  # AIS upper-cases and pads its names
        aton(993672003, "RED 2", NAME_MATCH_M + 50.0),
        aton(993672004, "TWIN", 10.0),
        aton(993672005, "TWIN", 20.0),
        aton(993672009, "CLAIMED", 5.0),
    ]
    matches, ambiguous = match_atons(buoys, atons)
    assert {buoy: (m.aton["mmsi"], m.by) for buoy, m in matches.items()} == {
        "A": (993672001, "mmsi"), "B": (993672002, "name"), "F": (993672009, "mmsi")
    }  # fmt: skip
    assert ambiguous == {"D": "2 AtoNs of its name within 1852 m (993672004, 993672005): set its MMSI"}
    # two buoys of one name near one AtoN: neither takes it
    twins = [stored_buoy("G", "Green 1"), stored_buoy("H", "Green 1", at=(38.951, -76.45))]
    matches, ambiguous = match_atons(twins, [aton(993672002, "GREEN 1", 40.0)])
    assert matches == {} and set(ambiguous) == {"G", "H"}
    assert ambiguous["G"] == "the AtoN of its name within 1852 m (993672002) has another buoy's name too: set its MMSI"


def test_a_mission_looks_at_an_ais_position_only_while_it_is_current_and_of_a_physical_buoy():
    (match,) = match_atons([stored_buoy("A", None, mmsi=1)], [aton(1, "A", 30.0)])[0].values()
    assert current_report(match) is match.aton and current_report(None) is None
    for stale_or_virtual in ({"stale": True}, {"virtual": True}, {"lat": None, "lon": None}):
        (match,) = match_atons([stored_buoy("A", None, mmsi=1)], [aton(1, "A", 30.0, **stale_or_virtual)])[0].values()
        assert current_report(match) is None, stale_or_virtual
