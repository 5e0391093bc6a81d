"""The AtoNs the AIS feed heard: each one's latest report, its age, and the MMSIs that several AtoNs claim. Pure: the
feed (gcs.ais.feed) adds what it decodes and says what time it is.

- **Latest per AtoN**: an AtoN is known by its MMSI. A report joins the AtoN of its MMSI that has the same name and
  was last within `conflict_distance_m` of it (a buoy drifts metres in its swing circle, and even one dragged off
  station moves little between two 3-minute reports); otherwise it is another AtoN with the same MMSI.
- **Duplicate MMSIs** (two transmitters configured alike, a mistyped MMSI) are kept apart, never merged: each is a
  row of its own and `conflicts` lists the MMSIs that more than one AtoN still reports (none of them stale).
- **Staleness**: ages run on the monotonic clock; a report older than `stale_after_s` is stale, whatever its
  source, so a silent feed never leaves a position looking current.
- **Bounded**: at most `max_atons` AtoNs (the one heard longest ago goes first: a flood of invented MMSIs cannot
  grow the table) and `MAX_PER_MMSI` per MMSI; AtoNs not heard for `forget_after_s` are forgotten.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from dataclasses import dataclass

from uavcore.ais import AtonReport

MAX_PER_MMSI = 4
EARTH_RADIUS_M = 6_371_008.8  # mean radius: distances of metres to kilometres, well within the check's need


@dataclass(frozen=True)
class HeardReport:
    """A report as the feed received it."""

    report: AtonReport
    source: str  # the source's URL
    received_at: float  # unix seconds (wall clock): shown
    received_mono: float  # monotonic seconds: ages


@dataclass
class _Aton:
    latest: HeardReport
    reports: int = 1


@dataclass(frozen=True)
class AtonState:
    """One AtoN as the table shows it at some instant."""

    latest: HeardReport
    reports: int
    age_s: float
    stale: bool
    conflict: bool


def distance_m(a: tuple[float, float], b: tuple[float, float]) -> float:
    """Great-circle distance between two (lat, lon) in degrees (haversine)."""
    lat1, lon1, lat2, lon2 = map(math.radians, (*a, *b))
    h = math.sin((lat2 - lat1) / 2) ** 2 + math.cos(lat1) * math.cos(lat2) * math.sin((lon2 - lon1) / 2) ** 2
    return 2 * EARTH_RADIUS_M * math.asin(min(1.0, math.sqrt(h)))


def same_name(a: str, b: str) -> bool:
    """Whether two AtoN names are the same, case and spacing aside (AIS pads and upper-cases its 6-bit text)."""
    return " ".join(a.upper().split()) == " ".join(b.upper().split())


class AtonTable:
    """Latest report per AtoN (module docstring)."""

    def __init__(
        self,
        stale_after_s: float = 420.0,
        conflict_distance_m: float = 500.0,
        max_atons: int = 10_000,
        forget_after_s: float = 86_400.0,
    ) -> None:
        self.stale_after_s = stale_after_s
        self.conflict_distance_m = conflict_distance_m
        self.max_atons = max_atons
        self.forget_after_s = forget_after_s
        self._by_mmsi: OrderedDict[int, list[_Aton]] = OrderedDict()  # the MMSI heard longest ago first
        self._count = 0
        self.evicted = 0  # AtoNs dropped to stay within max_atons or MAX_PER_MMSI

    def __len__(self) -> int:
        return self._count

    def _same_aton(self, aton: _Aton, report: AtonReport) -> bool:
        known = aton.latest.report
        if not same_name(known.name, report.name):
            return False
        if known.lat is None or known.lon is None or report.lat is None or report.lon is None:
            return True
        return distance_m((known.lat, known.lon), (report.lat, report.lon)) <= self.conflict_distance_m

    def add(self, heard: HeardReport) -> None:
        """One more report: the latest of its AtoN, or a new AtoN."""
        self._forget(heard.received_mono)
        mmsi = heard.report.mmsi
        atons = self._by_mmsi.get(mmsi)
        if atons is None:
            atons = self._by_mmsi[mmsi] = []
        else:
            self._by_mmsi.move_to_end(mmsi)
        for aton in atons:
            if self._same_aton(aton, heard.report):
                aton.latest, aton.reports = heard, aton.reports + 1
                return
        if len(atons) >= MAX_PER_MMSI:  # the one of this MMSI heard longest ago makes room
            atons.remove(min(atons, key=lambda a: a.latest.received_mono))
            self._count -= 1
            self.evicted += 1
        atons.append(_Aton(heard))
        self._count += 1
        while self._count > self.max_atons:
            _, oldest = self._by_mmsi.popitem(last=False)
            self._count -= len(oldest)
            self.evicted += len(oldest)

    def _forget(self, now: float) -> None:
        """Drop the MMSIs none of whose AtoNs was heard for forget_after_s (from the front: heard longest ago)."""
        while self._by_mmsi:
            mmsi, atons = next(iter(self._by_mmsi.items()))
            if now - max(a.latest.received_mono for a in atons) <= self.forget_after_s:
                break
            del self._by_mmsi[mmsi]
            self._count -= len(atons)

    def atons(self, now: float) -> list[AtonState]:
        """Every AtoN at monotonic time now, by MMSI, then the most recently heard first."""
        self._forget(now)
        states = []
        for mmsi in sorted(self._by_mmsi):
            atons = sorted(self._by_mmsi[mmsi], key=lambda a: -a.latest.received_mono)
            ages = [max(0.0, now - a.latest.received_mono) for a in atons]
            conflict = sum(age <= self.stale_after_s for age in ages) > 1
            states += [
                AtonState(a.latest, a.reports, age, age > self.stale_after_s, conflict)
                for a, age in zip(atons, ages, strict=True)
            ]
        return states

    @staticmethod
    def conflicts(states: list[AtonState]) -> dict[int, list[AtonState]]:
        """The MMSIs in conflict among states (as atons() gave them), each with its fresh AtoNs."""
        conflicts: dict[int, list[AtonState]] = {}
        for state in states:
            if state.conflict and not state.stale:
                conflicts.setdefault(state.latest.report.mmsi, []).append(state)
        return conflicts
