"""The buoy register as the service keeps it (MissionService.register): charts imported into it, each buoy's
history and defects, the operator's changes, and the off-station alarms from inspections and from AIS.

The register's rows are written by storage alone: an inspection record of a register buoy joins its history in
the record's own transaction (gcs.storage.base.Storage.set_inspection), whoever stores the record.
"""

from __future__ import annotations

import asyncio
from collections.abc import Sequence
from dataclasses import replace
from datetime import UTC, datetime, timedelta
from typing import Any, TypeVar

from pydantic import ValidationError

from gcs.ais.feed import AisFeed
from gcs.domain.aton_table import distance_m
from gcs.domain.chart_basemap import encoded_features, feature_collection
from gcs.domain.charted_marks import ChartImport
from gcs.domain.register import (
    AisMatch,
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
    current_report,
    defect_out,
    event_out,
    from_mark,
    inspection_alarm,
    match_atons,
    without_duplicates,
)
from gcs.domain.schemas import BuoyIn, PlanRequest, RegisterSelectionIn
from gcs.missions.validation import Location, RequestInvalidError
from gcs.storage.off_loop import AsyncStorage

Request = TypeVar("Request", bound=PlanRequest)


class BuoyNotFoundError(KeyError):
    """No register buoy with this id (or it has no such defect): the message says which, `field` names the id."""

    def __init__(self, message: str, field: str = "buoy_id") -> None:
        super().__init__(message)
        self.field = field


class Register:
    def __init__(self, storage: AsyncStorage, ais: AisFeed) -> None:
        self._storage = storage
        self._ais = ais

    async def import_chart(self, chart: ChartImport) -> RegisterImportOut:
        """The cell's marks into the register, upserted by LNAM; ids or names given twice reported, not merged. The
        cell's land, piers and depth contours become the page's offline base map (`basemap`)."""
        source = chart_source(chart)
        buoys, duplicates = without_duplicates([from_mark(mark, source) for mark in chart.marks])
        created, updated, unchanged = await self._storage.upsert_buoys(buoys)
        features = await asyncio.to_thread(encoded_features, chart.basemap)  # megabytes of JSON: off the loop
        cell = chart.cell
        await self._storage.store_basemap(cell.name, cell.edition, cell.update, features)
        return RegisterImportOut(source=source, created=created, updated=updated, unchanged=unchanged,
                                 duplicates=duplicates, warnings=list(chart.warnings))  # fmt: skip

    async def basemap(self) -> bytes:
        """The base map of every cell imported: one GeoJSON FeatureCollection, encoded."""
        return feature_collection(await self._storage.basemaps()).encode()

    async def resolve(self, request: Request) -> Request:
        """The request with the buoys its `from_register` selection names appended to its own, each where the mission
        should look for it (its current AIS position, else its charted one) and charted as the register has it.
        Raises RequestInvalidError naming a register id that is not in the register, named twice, or a virtual
        AtoN, and a selection that matches no buoy."""
        errors = await self._unknown_ids(request.buoys)
        if errors:
            raise RequestInvalidError(errors)
        if request.from_register is None:
            return request
        selected = await self._selected(request.from_register)
        matches, _ = await self._matches()  # over the whole register: a buoy left out still claims its MMSI, its name
        given = {b.register_id for b in request.buoys if b.register_id is not None}
        errors += [(("body", "from_register"), f"buoy {s.buoy.id!r} is in `buoys` already") for s in selected
                   if s.buoy.id in given]  # fmt: skip
        if errors:
            raise RequestInvalidError(errors)
        chosen = [s for s in selected if not _virtual(matches.get(s.buoy.id))]
        if not chosen:
            why = "no buoy of the register matches the selection" + (" (only virtual AtoNs did)" if selected else "")
            raise RequestInvalidError([(("body", "from_register"), why)])
        targets: list[BuoyIn] = []
        for stored in chosen:
            try:
                targets.append(BuoyIn.model_validate(_target(stored, matches.get(stored.buoy.id))))
            except ValidationError as error:  # what a chart gave that a request may not (never seen: said, not hidden)
                errors.append((("body", "from_register"), f"register buoy {stored.buoy.id!r} cannot be flown: {error}"))
        if errors:
            raise RequestInvalidError(errors)
        return request.model_copy(update={"buoys": [*request.buoys, *targets], "from_register": None})

    async def _selected(self, selection: RegisterSelectionIn) -> list[StoredBuoy]:
        """The register buoys the selection names, by id; 422 naming each id given that is not in the register."""
        where = BuoyFilter(bbox=selection.bbox, kind=selection.kind, open_defects=selection.open_defects)
        if selection.overdue_days is not None:
            where = _overdue(where, selection.overdue_days)
        selected = await self._storage.buoys(where)
        if selection.ids is None:
            return selected
        known = await self._storage.known_buoys(selection.ids)
        errors: list[tuple[Location, str]] = [
            (("body", "from_register", "ids", i), f"no buoy {register_id!r} in the register")
            for i, register_id in enumerate(selection.ids)
            if register_id not in known
        ]
        if errors:
            raise RequestInvalidError(errors)
        wanted = set(selection.ids)
        return [s for s in selected if s.buoy.id in wanted]

    async def _unknown_ids(self, buoys: Sequence[BuoyIn]) -> list[tuple[Location, str]]:
        """A 422 error for each register_id the request's buoys give that is not in the register."""
        named = [(i, b.register_id) for i, b in enumerate(buoys) if b.register_id is not None]
        if not named:
            return []
        known = await self._storage.known_buoys([register_id for _, register_id in named])
        return [
            (("body", "buoys", i, "register_id"), f"no buoy {register_id!r} in the register")
            for i, register_id in named
            if register_id not in known
        ]

    async def buoys(self, where: BuoyFilter, overdue_days: float | None = None) -> list[BuoyOut]:
        if overdue_days is not None:
            where = _overdue(where, overdue_days)
        return [buoy_out(stored) for stored in await self._storage.buoys(where)]

    async def buoy(self, buoy_id: str) -> BuoyDetailOut:
        """A register buoy with its latest inspection, open defects, history and its MMSI's latest AIS report."""
        stored = await self._stored(buoy_id)
        history = [event_out(event) for event in await self._storage.buoy_events(buoy_id)]
        inspections = [event for event in history if event.kind == "inspection"]
        defects = [defect_out(defect) for defect in await self._storage.defects(buoy_id)]
        matches, unmatched = await self._matches()
        match = matches.get(buoy_id)
        latest = inspections[-1] if inspections else None
        return BuoyDetailOut(**buoy_out(stored).model_dump(), latest_inspection=latest, defects=defects,
                             history=history, ais=None if match is None else match.aton,
                             ais_match=None if match is None else match.by,
                             ais_unmatched=unmatched.get(buoy_id))  # fmt: skip

    async def set_mmsi(self, buoy_id: str, mmsi: int | None) -> BuoyOut:
        if not await self._storage.set_buoy_mmsi(buoy_id, mmsi):
            raise BuoyNotFoundError(f"no buoy {buoy_id!r} in the register")
        return buoy_out(await self._stored(buoy_id))

    async def set_defect(self, buoy_id: str, defect_id: int, state: DefectState, note: str) -> DefectOut:
        defect = await self._storage.set_defect_state(buoy_id, defect_id, state, note)
        if defect is None:
            await self._stored(buoy_id)  # an unknown buoy is named as such
            raise BuoyNotFoundError(f"buoy {buoy_id!r} has no defect {defect_id}", field="defect_id")
        return defect_out(defect)

    async def alarms(self) -> list[AlarmOut]:
        """Off-station alarms: each open or confirmed off_station defect an inspection opened (closing it ends the
        alarm), and each register buoy whose MMSI's current AIS report says, or shows, it is off station."""
        stored = {s.buoy.id: s for s in await self._storage.buoys()}
        alarms = [
            inspection_alarm(stored[defect.buoy_id], defect)
            for defect in await self._storage.defects(code="off_station")
        ]
        for buoy_id, match in (await self._matches(list(stored.values())))[0].items():
            buoy, aton = stored[buoy_id], match.aton
            at = (aton["lat"], aton["lon"])
            distance = None if None in at else distance_m((buoy.buoy.lat, buoy.buoy.lon), at)
            alarm = ais_alarm(buoy, aton, distance)
            if alarm is not None:
                alarms.append(alarm)
        return alarms

    async def _matches(self, stored: list[StoredBuoy] | None = None) -> tuple[dict[str, AisMatch], dict[str, str]]:
        """Each register buoy's AtoN of the feed, and why an ambiguous one has none (match_atons), by register id."""
        atons = [row.model_dump(mode="json") for row in self._ais.atons().atons]
        if not atons:
            return {}, {}
        return match_atons(await self._storage.buoys() if stored is None else stored, atons)

    async def _stored(self, buoy_id: str) -> StoredBuoy:
        stored = await self._storage.buoy(buoy_id)
        if stored is None:
            raise BuoyNotFoundError(f"no buoy {buoy_id!r} in the register")
        return stored


def _overdue(where: BuoyFilter, days: float) -> BuoyFilter:
    since = datetime.now(UTC) - timedelta(days=days)
    return replace(where, inspected_before=since.isoformat(timespec="milliseconds"))


def _virtual(match: AisMatch | None) -> bool:
    return match is not None and bool(match.aton["virtual"])


def _target(stored: StoredBuoy, match: AisMatch | None) -> dict[str, Any]:
    """A register buoy as a mission's buoy (BuoyIn's fields): looked for at its current AIS position (its chart's
    kept as `charted`), else at its charted one."""
    buoy = stored.buoy
    report = current_report(match)
    at = (buoy.lat, buoy.lon) if report is None else (report["lat"], report["lon"])
    charted = None if report is None else {"lat": buoy.lat, "lon": buoy.lon}
    return {"lat": at[0], "lon": at[1], "id": (buoy.name or buoy.id)[:64], "kind": buoy.kind, "light": buoy.light,
            "swing_radius_m": buoy.swing_radius_m, "register_id": buoy.id, "charted": charted,
            "region": buoy.charted.get("region")}  # fmt: skip
