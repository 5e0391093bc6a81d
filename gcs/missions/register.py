"""The buoy register as the service keeps it (MissionService.register): charts imported into it, each buoy's
history and defects, the operator's changes, and the off-station alarms from inspections and from AIS.

The register's rows are written by storage alone: an inspection record of a register buoy joins its history in
the record's own transaction (gcs.storage.base.Storage.set_inspection), whoever stores the record.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from datetime import UTC, datetime, timedelta
from typing import Any

from gcs.ais.feed import AisFeed
from gcs.domain.aton_table import distance_m
from gcs.domain.charted_marks import ChartImport
from gcs.domain.register import (
    AlarmOut,
    BuoyDetailOut,
    BuoyFilter,
    BuoyOut,
    DefectOut,
    DefectState,
    RegisterImportOut,
    StoredBuoy,
    ais_alarm,
    buoy_out,
    chart_source,
    defect_out,
    event_out,
    from_mark,
    inspection_alarm,
    without_duplicates,
)
from gcs.domain.schemas import BuoyIn
from gcs.missions.validation import Location, RequestInvalidError
from gcs.storage.off_loop import AsyncStorage


class BuoyNotFoundError(KeyError):
    """No register buoy with this id (or it has no such defect): the message says which."""


class Register:
    def __init__(self, storage: AsyncStorage, ais: AisFeed) -> None:
        self._storage = storage
        self._ais = ais

    async def import_chart(self, chart: ChartImport) -> RegisterImportOut:
        """The cell's marks into the register, upserted by LNAM; ids or names given twice reported, not merged."""
        source = chart_source(chart)
        buoys, duplicates = without_duplicates([from_mark(mark, source) for mark in chart.marks])
        created, updated, unchanged = await self._storage.upsert_buoys(buoys)
        return RegisterImportOut(source=source, created=created, updated=updated, unchanged=unchanged,
                                 duplicates=duplicates, warnings=list(chart.warnings))  # fmt: skip

    async def check_request(self, buoys: Sequence[BuoyIn]) -> None:
        """Every register_id a mission request names is in the register (422 naming each buoy that is not)."""
        named = [(i, b.register_id) for i, b in enumerate(buoys) if b.register_id is not None]
        if not named:
            return
        known = await self._storage.known_buoys([register_id for _, register_id in named])
        errors: list[tuple[Location, str]] = [
            (("body", "buoys", i, "register_id"), f"no buoy {register_id!r} in the register")
            for i, register_id in named
            if register_id not in known
        ]
        if errors:
            raise RequestInvalidError(errors)

    async def buoys(self, where: BuoyFilter, overdue_days: float | None = None) -> list[BuoyOut]:
        if overdue_days is not None:
            since = datetime.now(UTC) - timedelta(days=overdue_days)
            where = replace(where, inspected_before=since.isoformat(timespec="milliseconds"))
        return [buoy_out(stored) for stored in await self._storage.buoys(where)]

    async def buoy(self, buoy_id: str) -> BuoyDetailOut:
        """A register buoy with its latest inspection, open defects, history and its MMSI's latest AIS report."""
        stored = await self._stored(buoy_id)
        history = [event_out(event) for event in await self._storage.buoy_events(buoy_id)]
        inspections = [event for event in history if event.kind == "inspection"]
        defects = [defect_out(defect) for defect in await self._storage.defects(buoy_id)]
        reports = self._ais_by_mmsi().get(stored.mmsi, []) if stored.mmsi is not None else []
        latest = inspections[-1] if inspections else None
        return BuoyDetailOut(**buoy_out(stored).model_dump(), latest_inspection=latest, defects=defects,
                             history=history, ais=reports[0] if reports else None)  # fmt: skip

    async def set_mmsi(self, buoy_id: str, mmsi: int | None) -> BuoyOut:
        if not await self._storage.set_buoy_mmsi(buoy_id, mmsi):
            raise BuoyNotFoundError(f"no buoy {buoy_id!r} in the register")
        return buoy_out(await self._stored(buoy_id))

    async def set_defect(self, buoy_id: str, defect_id: int, state: DefectState, note: str) -> DefectOut:
        defect = await self._storage.set_defect_state(buoy_id, defect_id, state, note)
        if defect is None:
            await self._stored(buoy_id)  # an unknown buoy is named as such
            raise BuoyNotFoundError(f"buoy {buoy_id!r} has no defect {defect_id}")
        return defect_out(defect)

    async def alarms(self) -> list[AlarmOut]:
        """Off-station alarms: each open or confirmed off_station defect an inspection opened (closing it ends the
        alarm), and each register buoy whose MMSI's current AIS report says, or shows, it is off station."""
        stored = {s.buoy.id: s for s in await self._storage.buoys()}
        alarms = [
            inspection_alarm(stored[defect.buoy_id], defect)
            for defect in await self._storage.defects(code="off_station")
        ]
        reports = self._ais_by_mmsi()
        for buoy in stored.values():
            for aton in reports.get(buoy.mmsi, []) if buoy.mmsi is not None else []:
                at = (aton["lat"], aton["lon"])
                distance = None if None in at else distance_m((buoy.buoy.lat, buoy.buoy.lon), at)
                alarm = ais_alarm(buoy, aton, distance)
                if alarm is not None:
                    alarms.append(alarm)
        return alarms

    def _ais_by_mmsi(self) -> dict[int, list[dict[str, Any]]]:
        """The feed's rows (AtonOut documents) by MMSI: one each, or several AtoNs in conflict on one."""
        rows: dict[int, list[dict[str, Any]]] = {}
        for aton in self._ais.atons().atons:
            rows.setdefault(aton.mmsi, []).append(aton.model_dump(mode="json"))
        return rows

    async def _stored(self, buoy_id: str) -> StoredBuoy:
        stored = await self._storage.buoy(buoy_id)
        if stored is None:
            raise BuoyNotFoundError(f"no buoy {buoy_id!r} in the register")
        return stored
