"""How `pytest -n N` hands the tests to its workers: longest first, from the durations a full run measured.

xdist's default (`--dist load`) sends each worker a run of consecutive tests and more as it drains: on two cores
with six workers a minutes-long test collected late (the wheel install, a browser's fleet mission) started after
the others had nearly finished and ran alone at the end. Here the tests are cut into work units, sorted by their
expected time, longest first (as a longest-processing-time schedule does), and a worker is given the next unit
only when it starts its last test:

* a test that took SPLIT_S or longer is a unit of its own;
* the other tests of a module stay together, in their order, so that what a module's tests share (a module- or
  session-scoped fixture: a vehicle, a service, a PostgreSQL server) is set up once, on one worker.

tests/durations.json holds the seconds each test took (setup, call and teardown) in full `pytest -n 6` runs on a
2-core machine, for the tests that took 0.5 s or more; a test it does not name counts as UNKNOWN_S. Rewrite it
after tests are added or become much faster or slower: `pytest -n 6 --record-durations tests/durations.json`
(a stale file only makes the order less good, never a test wrong). A run in this order starts the longest tests
together, and they then take longer than they would alone: what the order needs is their ranking, which holds.
"""

from __future__ import annotations

import json
from collections import OrderedDict
from collections.abc import Iterable
from pathlib import Path

from xdist.scheduler import LoadScopeScheduling

DURATIONS = Path(__file__).with_name("durations.json")
SPLIT_S = 3.0
UNKNOWN_S = 0.1
RECORDED_FROM_S = 0.5  # what --record-durations keeps: shorter tests count as UNKNOWN_S


def load_durations(path: Path = DURATIONS) -> dict[str, float]:
    return json.loads(path.read_text()) if path.exists() else {}


def work_units(nodeids: Iterable[str], durations: dict[str, float]) -> list[tuple[str, list[str]]]:
    """(key, test ids) of each unit, longest expected first (ties in collection order)."""
    units: dict[str, list[str]] = {}
    for nodeid in nodeids:
        key = nodeid if durations.get(nodeid, 0.0) >= SPLIT_S else nodeid.split("::", 1)[0]
        units.setdefault(key, []).append(nodeid)
    expected = {key: sum(durations.get(n, UNKNOWN_S) for n in ids) for key, ids in units.items()}
    return sorted(units.items(), key=lambda unit: -expected[unit[0]])


class LongestFirstScheduling(LoadScopeScheduling):
    """xdist's module-by-module scheduler (`--dist loadscope`) with the units and order of work_units(), and a
    worker given a new unit only when it is down to its last test (which cannot start before the worker knows
    what comes after it: a worker always holds the test it runs and the next)."""

    def __init__(self, config, log=None) -> None:
        super().__init__(config, log)
        self.durations = load_durations()
        self.unit_of: dict[str, str] = {}

    def _split_scope(self, nodeid: str) -> str:
        return self.unit_of[nodeid]

    def schedule(self) -> None:
        assert self.collection_is_completed
        if self.collection is not None:  # a node added later: give it work
            for node in self.nodes:
                self._reschedule(node)
            return
        if not self._check_nodes_have_same_collection():
            self.log("**Different tests collected, aborting run**")
            return
        self.collection = list(next(iter(self.registered_collections.values())))
        if not self.collection:
            return
        self.workqueue = OrderedDict(
            (key, dict.fromkeys(ids, False)) for key, ids in work_units(self.collection, self.durations)
        )
        self.unit_of = {nodeid: key for key, unit in self.workqueue.items() for nodeid in unit}
        for _ in range(max(0, len(self.nodes) - len(self.workqueue))):  # more workers than units
            unused, _ = self.assigned_work.popitem()
            unused.shutdown()
        # The first two rounds pair the longest unit with the shortest of the second round, and so on.
        for node in self.nodes:
            if self.workqueue:
                self._assign_work_unit(node)
        for node in reversed(self.nodes):
            self._reschedule(node)

    def _reschedule(self, node) -> None:
        if node.shutting_down:
            return
        if not self.workqueue:
            node.shutdown()
            return
        if self._pending_of(self.assigned_work[node]) > 1:
            return
        self._assign_work_unit(node)
