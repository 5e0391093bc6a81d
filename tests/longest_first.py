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
from collections import Counter, deque
from collections.abc import Sequence
from pathlib import Path

from xdist.remote import Producer
from xdist.report import report_collection_diff
from xdist.workermanage import WorkerController, parse_tx_spec_config

DURATIONS = Path(__file__).with_name("durations.json")
SPLIT_S = 3.0
UNKNOWN_S = 0.1
RECORDED_FROM_S = 0.5  # what --record-durations keeps: shorter tests count as UNKNOWN_S


def load_durations(path: Path = DURATIONS) -> dict[str, float]:
    return json.loads(path.read_text()) if path.exists() else {}


def work_units(nodeids: Sequence[str], durations: dict[str, float]) -> list[list[int]]:
    """The indices into `nodeids` of each unit, longest expected first (ties in collection order). By index: a
    test id can name several tests (schemathesis's one per API operation), whose recorded seconds are their sum."""
    named = Counter(nodeids)
    seconds = [durations.get(nodeid, UNKNOWN_S * named[nodeid]) / named[nodeid] for nodeid in nodeids]
    units: dict[str, list[int]] = {}
    for index, nodeid in enumerate(nodeids):
        key = f"{index}:{nodeid}" if seconds[index] >= SPLIT_S else nodeid.split("::", 1)[0]
        units.setdefault(key, []).append(index)
    expected = {key: sum(seconds[i] for i in unit) for key, unit in units.items()}
    return [units[key] for key in sorted(units, key=lambda key: -expected[key])]


class LongestFirstScheduling:
    """An xdist scheduler (xdist.scheduler.protocol.Scheduling) handing out work_units() in their order. A worker
    is given the next unit only when it is down to its last test, which it cannot start before it knows what
    comes after it: a worker always holds the test it runs and the next."""

    def __init__(self, config, log: Producer | None = None) -> None:
        self.numnodes = len(parse_tx_spec_config(config))
        self.log = log.longestfirst if log is not None else Producer("longestfirst")
        self.collection: list[str] | None = None
        self.registered_collections: dict[WorkerController, list[str]] = {}
        self.node2pending: dict[WorkerController, list[int]] = {}
        self.units: deque[list[int]] = deque()
        self.durations = load_durations()

    @property
    def nodes(self) -> list[WorkerController]:
        return list(self.node2pending)

    @property
    def collection_is_completed(self) -> bool:
        return len(self.registered_collections) >= self.numnodes

    @property
    def tests_finished(self) -> bool:
        if not self.collection_is_completed or self.units:
            return False
        return all(len(pending) < 2 for pending in self.node2pending.values())

    @property
    def has_pending(self) -> bool:
        return bool(self.units) or any(self.node2pending.values())

    def add_node(self, node: WorkerController) -> None:
        assert node not in self.node2pending
        self.node2pending[node] = []

    def add_node_collection(self, node: WorkerController, collection: Sequence[str]) -> None:
        if self.collection is not None and list(collection) != self.collection:  # a replacement collected otherwise
            self.log(report_collection_diff(self.collection, collection, "the first worker", node.gateway.id))
            return
        self.registered_collections[node] = list(collection)

    def mark_test_complete(self, node: WorkerController, item_index: int, duration: float = 0) -> None:
        self.node2pending[node].remove(item_index)
        self._reschedule(node)

    def mark_test_pending(self, item: str) -> None:
        raise NotImplementedError()

    def remove_pending_tests_from_node(self, node: WorkerController, indices: Sequence[int]) -> None:
        raise NotImplementedError()

    def remove_node(self, node: WorkerController) -> str | None:
        """A worker gone: None when it had finished its tests, else the test it crashed in (its other tests go
        back to the front of the queue)."""
        pending = self.node2pending.pop(node)
        if not pending:
            return None
        assert self.collection is not None
        crashed = self.collection[pending.pop(0)]
        if pending:
            self.units.appendleft(pending)
        for other in self.nodes:
            self._reschedule(other)
        return crashed

    def schedule(self) -> None:
        assert self.collection_is_completed
        if self.collection is not None:  # a worker added later: give it work
            for node in self.nodes:
                self._reschedule(node)
            return
        collections = list(self.registered_collections.items())
        first_node, first = collections[0]
        for node, collection in collections[1:]:
            if collection != first:
                self.log(report_collection_diff(first, collection, first_node.gateway.id, node.gateway.id))
                self.log("**Different tests collected, aborting run**")
                return
        self.collection = first
        self.units = deque(work_units(first, self.durations))
        # The first two rounds pair the longest unit with the shortest of the second round, and so on.
        for node in self.nodes:
            if self.units:
                self._send(node, self.units.popleft())
        for node in reversed(self.nodes):
            self._reschedule(node)

    def _reschedule(self, node: WorkerController) -> None:
        if node.shutting_down:
            return
        if not self.units:
            node.shutdown()
        elif len(self.node2pending[node]) <= 1:
            self._send(node, self.units.popleft())

    def _send(self, node: WorkerController, indices: list[int]) -> None:
        self.node2pending[node].extend(indices)
        node.send_runtest_some(indices)
