"""The buoy register's storage on both backends (SQLite and a real PostgreSQL server): buoys upserted by id with
their history kept, an inspection record of a register buoy joining its history in the record's transaction,
defects opened per finding code and set by an operator, and the filters GET /buoys uses."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path

import pytest
from inspected_missions import inspected_plan
from stored_missions import FLIGHT

from gcs.domain.inspection import BuoyInspection, Finding, InspectionRecord
from gcs.domain.planning import Plan
from gcs.domain.register import BuoyFilter, RegisterBuoy
from gcs.missions.inspector import charted_record, not_inspected
from gcs.storage import Storage, open_storage

OFF_STATION = Finding(code="off_station", offset_m=9.5, swing_radius_m=3.0, bearing_deg=10)
LIGHT_OUT = Finding(code="light_out", charted="Fl G 5s", seen="dark")


@pytest.fixture(params=["sqlite", pytest.param("postgresql", marks=pytest.mark.integration)])
def storage(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[Storage]:
    target = tmp_path / "gcs.sqlite" if request.param == "sqlite" else request.getfixturevalue("postgres_url")
    opened = open_storage(target)
    yield opened
    opened.close()


def buoy(ident: str, lat: float = 38.96, lon: float = -76.45, **changes) -> RegisterBuoy:
    charted = {"object_class": "BOYLAT", "colours": ["green"], "beacon": False}
    charted_buoy = RegisterBuoy(ident, lat, lon, f"Buoy {ident}", "port", "Fl G 4s", 5.0, charted, "US4MD81M")
    return replace(charted_buoy, **changes)


def registered_plan(register_ids: list[str | None]) -> Plan:
    """The four-buoy plan of tests/inspected_missions.py, its buoys naming these register ids."""
    plan = inspected_plan()
    assert plan.marks is not None
    return replace(plan, marks=[replace(m, register_id=r) for m, r in zip(plan.marks, register_ids, strict=True)])


def record(plan: Plan, index: int, *findings: Finding) -> InspectionRecord:
    """Buoy `index`'s record: a defect with these findings, or ok without any."""
    result = BuoyInspection(buoy=charted_record(plan, index), verdict="defect" if findings else "ok",
                            findings=list(findings), observed=None, offset_m=None, light_seen=None,
                            frames=[])  # fmt: skip
    return InspectionRecord(buoy=index, buoy_id=plan.buoy_ids[index], result=result)


def test_buoys_are_upserted_by_id_and_a_chart_change_joins_the_history(storage):
    assert storage.upsert_buoys([buoy("A"), buoy("B"), buoy("C")]) == (["A", "B", "C"], [], 0)
    created = storage.buoy("A")
    moved = buoy("A", lat=38.961, light="Fl G 6s", source="US4MD81M edition 32")
    assert storage.upsert_buoys([moved, buoy("B")]) == ([], ["A"], 1)
    after = storage.buoy("A")
    assert (after.buoy, after.created_at) == (moved, created.created_at)
    kinds = [(e.kind, e.detail) for e in storage.buoy_events("A")]
    assert kinds[0] == ("registered", {"source": "US4MD81M"})
    assert kinds[1] == ("charted", {"source": "US4MD81M edition 32",
                                    "changes": {"lat": [38.96, 38.961], "light": ["Fl G 4s", "Fl G 6s"]}})  # fmt: skip
    assert storage.set_buoy_mmsi("A", 993_672_001) and not storage.set_buoy_mmsi("nope", 993_672_001)
    assert storage.buoy("A").mmsi == 993_672_001
    assert storage.upsert_buoys([replace(moved, source="US4MD81M edition 33")]) == ([], [], 1)
    again = storage.buoy("A")
    assert (again.mmsi, again.buoy.source, len(storage.buoy_events("A"))) == (993_672_001, "US4MD81M edition 33", 2)
    assert storage.known_buoys(["A", "C", "Z"]) == {"A", "C"}
    assert storage.buoy("Z") is None


def test_an_inspection_of_a_register_buoy_joins_its_history_and_opens_a_defect_per_finding_code(storage):
    storage.upsert_buoys([buoy("R1"), buoy("R2"), buoy("R3")])
    plan = registered_plan(["R1", "R2", "not-registered", None])
    mission = storage.create_mission(FLIGHT, plan)
    storage.set_inspection(mission, record(plan, 0))
    storage.set_inspection(mission, record(plan, 1, OFF_STATION, LIGHT_OUT))
    storage.set_inspection(mission, record(plan, 1, OFF_STATION, LIGHT_OUT))  # stored again: replaces its event
    storage.set_inspection(mission, record(plan, 2, OFF_STATION))  # a register id the register does not hold
    storage.set_inspection(mission, not_inspected(plan, 3, "no camera"))

    assert [(e.kind, e.mission_id, e.verdict) for e in storage.buoy_events("R1")][1:] == [("inspection", mission, "ok")]
    events = storage.buoy_events("R2")
    assert [e.kind for e in events] == ["registered", "defect_opened", "defect_opened", "inspection"]
    assert events[-1].detail["result"]["findings"][0] == OFF_STATION.model_dump()
    defects = storage.defects("R2")
    assert [(d.code, d.state, d.mission_id) for d in defects] == [
        ("off_station", "open", mission),
        ("light_out", "open", mission),
    ]
    assert storage.buoy("R2").unclosed_defects == 2 and storage.buoy("R3").last_inspected_at is None

    # a later mission finding the buoy off station again adds evidence, not a second open defect
    later = storage.create_mission(FLIGHT, plan)
    storage.set_inspection(later, record(plan, 1, OFF_STATION))
    assert len(storage.defects("R2", code="off_station")) == 1

    closed = storage.set_defect_state("R2", defects[0].id, "closed", "re-moored by the buoy tender")
    assert (closed.state, closed.note) == ("closed", "re-moored by the buoy tender")
    assert storage.buoy_events("R2")[-1].detail == {"code": "off_station", "from": "open", "to": "closed"}
    assert storage.set_defect_state("R1", defects[0].id, "closed", "not R1's") is None
    third = storage.create_mission(FLIGHT, plan)
    storage.set_inspection(third, record(plan, 1, OFF_STATION))  # off station again after the close: a new defect
    assert [d.mission_id for d in storage.defects("R2", code="off_station")] == [third]
    assert storage.delete_mission(mission) and len(storage.buoy_events("R2")) == 8  # the history outlives it


def test_the_filters_by_area_kind_inspection_age_and_open_defects(storage):
    storage.upsert_buoys([buoy("N", lat=39.0), buoy("S", lat=38.9, kind="starboard"), buoy("M")])
    plan = registered_plan(["N", "S", None, None])
    mission = storage.create_mission(FLIGHT, plan)
    storage.set_inspection(mission, record(plan, 0))
    storage.set_inspection(mission, record(plan, 1, LIGHT_OUT))
    inspected = storage.buoy("N").last_inspected_at

    def ids(**where) -> list[str]:
        return [b.buoy.id for b in storage.buoys(BuoyFilter(**where))]

    assert ids() == ["M", "N", "S"]
    assert ids(bbox=(-76.5, 38.95, -76.4, 39.05)) == ["M", "N"]
    assert ids(kind="starboard") == ["S"]
    assert ids(inspected_before=inspected) == ["M"]  # N and S inspected at or after it; M never
    assert ids(inspected_before="9999") == ["M", "N", "S"]
    assert ids(open_defects=True) == ["S"] and ids(open_defects=False) == ["M", "N"]
    assert ids(bbox=(-76.5, 38.95, -76.4, 39.05), open_defects=False, kind="port") == ["M", "N"]


def test_a_cells_base_map_is_stored_under_its_name_and_a_later_import_replaces_it(storage):
    assert storage.basemaps() == []
    storage.store_basemap("US4MD81M", "31", "0", '[{"a": 1}]')
    storage.store_basemap("AAAAAAAA", "1", None, "[]")
    storage.store_basemap("US4MD81M", "32", "1", '[{"b": 2}]')  # a new edition of the cell: its features replaced
    assert storage.basemaps() == ["[]", '[{"b": 2}]']  # by cell name
