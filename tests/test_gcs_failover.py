"""Two service instances on one PostgreSQL database: one owns the vehicle link, the other stands by and takes
over when the owner is killed mid-flight; with a fleet, one owns every vehicle's link and the fleet mission's
coordination, and the stand-by carries the fleet mission on.

Real processes throughout: the vehicle (`python -m sitl_quad --speed 4`, its own position loop flying), two
`python -m gcs serve --db postgresql://...` on their own HTTP ports, a throwaway PostgreSQL server
(tests/postgres_server.py). The scenario and its figures are bench/failover.py's, which runs it N times.
"""

from __future__ import annotations

import json
import os
import signal
from collections.abc import Iterator
from pathlib import Path

import psycopg
import pytest
from websockets.sync.client import connect

from bench.failover import (
    LOST_VEHICLE_WAIT_S,
    TAKEOVER_REQUIREMENT_S,
    TELEMETRY_PERIOD_S,
    VEHICLE_WAIT_S,
    FailoverStack,
    close_buoys,
    fly_and_kill,
    fly_fleet_and_kill,
    owns_a_connected_vehicle,
    poll,
)
from gcs.domain.fleet_coordination import FleetCoordination
from gcs.missions.fleet_missions import FOLLOWED_AGAIN
from gcs.missions.lifecycle import FLUSH_PERIOD_S, REATTACHED
from gcs.missions.ownership import LEASE_LOST_EXIT_CODE
from gcs.storage import open_storage

pytestmark = [pytest.mark.integration, pytest.mark.slow]

# Wall seconds a stand-by that owns the link may need before it records again: the vehicle's next heartbeat
# (1 s), its MISSION_CURRENT (the lifecycle waits up to 3 s) and the mission download, with room for a loaded
# machine.
REATTACH_ALLOWANCE_S = 6.0


def udp_sockets(pid: int) -> int:
    """How many UDP sockets the process holds (Linux: its socket descriptors found in /proc/net/udp)."""
    inodes = {line.split()[9] for line in Path("/proc/net/udp").read_text().splitlines()[1:]}
    fds = Path(f"/proc/{pid}/fd")
    links = [os.readlink(fd) for fd in fds.iterdir()]
    return sum(1 for link in links if link.startswith("socket:[") and link[8:-1] in inodes)


def _running(stack: FailoverStack) -> Iterator[FailoverStack]:
    """A fixture's body: the stack started, closed after the test, and neither instance's log with a traceback."""
    try:
        yield stack.start()
    finally:
        stack.close()
    for name in ("gcs-a", "gcs-b"):
        assert "Traceback" not in stack.log(name), stack.log(name)


@pytest.fixture
def stack(postgres_url, tmp_path):
    yield from _running(FailoverStack(postgres_url, tmp_path / "logs", speed=4.0))


def test_the_standby_refuses_to_fly_and_takes_over_the_mission_when_the_owner_is_killed(stack):
    owner, standby = stack.instances
    vehicle = standby.vehicle()
    assert (vehicle["role"], vehicle["instance"], vehicle["owner"]) == ("standby", "gcs-b", "gcs-a")
    assert vehicle["connected"] is False and udp_sockets(standby.process.pid) == 0  # it never talks to the vehicle
    assert owner.vehicle()["role"] == "owner" and udp_sockets(owner.process.pid) == 1
    for path, body in (
        ("/missions", {"buoys": close_buoys()}),
        ("/missions/1/start", None),
        ("/missions/1/abort", None),
    ):
        refused = standby.client.post(path, json=body)
        assert refused.status_code == 503, (path, refused.text)
        (problem,) = refused.json()["detail"]
        assert problem["type"] == "unavailable" and "stand-by" in problem["msg"] and "'gcs-a'" in problem["msg"]
        assert int(refused.headers["Retry-After"]) >= 1
    assert standby.get("/missions") == []  # reads work
    with connect(str(standby.client.base_url.copy_with(scheme="ws", path="/ws"))) as live:
        pushed = json.loads(live.recv(timeout=60))
    assert (pushed["vehicle"]["role"], pushed["vehicle"]["owner"]) == ("standby", "gcs-a")

    run = fly_and_kill(stack, "owner")
    print(
        f"\nfail-over: take-over {run['takeover_s']:.2f} s after the kill, re-attached after "
        f"{run['reattached_s']:.2f} s; telemetry gap {run['gap_s']:.2f} s simulated "
        f"({run['gap_from_t_s']:.1f} -> {run['gap_to_t_s']:.1f} s, "
        f"{run['gap_wall_s']:.2f} s wall at {stack.speed:g}x), "
        f"of which {run['unflushed_tail_s']:.2f} s before the kill; {run['samples']} samples, "
        f"{run['duplicates']} duplicated, {run['lost_beyond_gap']} lost beyond the gap; load {run['load_after']:.1f}"
    )
    assert run["owner_after"] == "gcs-b"
    assert run["takeover_s"] < TAKEOVER_REQUIREMENT_S  # the requirement
    assert (run["status"], run["reason"], run["visited"]) == ("completed", None, run["buoys"])
    assert run["reattached_s"] is not None and run["reattached_s"] < TAKEOVER_REQUIREMENT_S + REATTACH_ALLOWANCE_S
    assert run["duplicates"] == 0 and run["lost_beyond_gap"] == 0
    # the gap is what the vehicle flew between the owner's last write and the re-attachment: at most a flush
    # period before the kill, and up to the re-attachment after it (the vehicle paced at stack.speed)
    assert 0 < run["gap_s"] <= stack.speed * (FLUSH_PERIOD_S + run["reattached_s"] + 1.0)
    assert run["unflushed_tail_s"] <= stack.speed * (FLUSH_PERIOD_S + 1.0)
    mission = standby.get(f"/missions/{run['mission']}")
    statuses = [(e["status"], e["reason"]) for e in mission["events"]]
    assert statuses[-2:] == [("flying", REATTACHED), ("completed", None)]
    assert standby.vehicle()["connected"] and udp_sockets(standby.process.pid) == 1


def test_killing_the_standby_changes_nothing_for_the_owner(stack):
    owner, _ = stack.instances
    run = fly_and_kill(stack, "standby")
    assert run["owner_after"] == "gcs-a" and run["takeover_s"] < 1.0  # the owner never stopped owning
    assert (run["status"], run["reason"], run["visited"]) == ("completed", None, run["buoys"])
    assert run["duplicates"] == 0 and run["lost_beyond_gap"] == 0
    assert run["gap_s"] < 2 * TELEMETRY_PERIOD_S  # no gap: the step across the kill is an ordinary one
    mission = owner.get(f"/missions/{run['mission']}")
    assert [e["status"] for e in mission["events"]] == ["planned", "uploading", "uploaded", "flying", "completed"]


def test_an_owner_that_loses_its_lease_exits_at_once_and_the_standby_takes_over(stack, postgres_url):
    """The owner's lease connection dies under it (a database restart, a network cut): it cannot know whether
    another instance took over, so it ends its process without writing anything, and the stand-by owns the link."""
    owner, standby = stack.instances
    with psycopg.connect(postgres_url, autocommit=True) as admin:
        admin.execute("SELECT pg_terminate_backend(pid) FROM pg_stat_activity WHERE application_name = 'gcs-a'")
    assert owner.process.wait(30) == LEASE_LOST_EXIT_CODE
    assert "vehicle lease lost" in stack.log("gcs-a")
    poll(standby.vehicle, owns_a_connected_vehicle, 30.0, "the stand-by owning the vehicle")


def test_an_owner_stopped_in_flight_hands_the_mission_over_instead_of_failing_it(stack):
    """SIGTERM (a rolling upgrade, a host shutdown): the owner stores what it recorded, leaves the mission flying
    and releases the lease; the stand-by re-attaches and the mission completes, never marked failed."""
    _, standby = stack.instances
    run = fly_and_kill(stack, "owner", how=signal.SIGTERM)
    assert run["owner_after"] == "gcs-b" and run["takeover_s"] < TAKEOVER_REQUIREMENT_S
    assert (run["status"], run["reason"], run["visited"]) == ("completed", None, run["buoys"])
    assert run["duplicates"] == 0 and run["lost_beyond_gap"] == 0
    mission = standby.get(f"/missions/{run['mission']}")
    statuses = [(e["status"], e["reason"]) for e in mission["events"]]
    assert statuses[-3:] == [("flying", None), ("flying", REATTACHED), ("completed", None)]
    assert "handed over in flight" in stack.log("gcs-a")


@pytest.fixture
def fleet_stack(postgres_url, tmp_path, request):
    """Two vehicles and two instances linked to both; `request.param`, when given: the stand-by's --vehicle-wait."""
    wait_s = getattr(request, "param", VEHICLE_WAIT_S)
    yield from _running(
        FailoverStack(postgres_url, tmp_path / "logs", speed=4.0, vehicles=2, standby_vehicle_wait_s=wait_s)
    )


def test_the_standby_carries_a_fleet_mission_on_when_its_owner_is_killed_and_no_buoy_is_lost(fleet_stack):
    """Both instances are linked to both vehicles; the owner holds both vehicles' leases and coordinates the fleet
    mission, the stand-by none. Killed in flight, the owner leaves the leases to the stand-by at once, which
    re-attaches each part and follows the fleet mission again from its stored coordinator state: the closest
    approach stored before the kill (the climb side by side from pads 3 m apart) is kept, not forgotten."""
    owner, standby = fleet_stack.instances
    assert [v["role"] for v in owner.get("/vehicles")] == ["owner", "owner"]
    assert [(v["role"], v["connected"]) for v in standby.get("/vehicles")] == [("standby", False)] * 2
    assert udp_sockets(standby.process.pid) == 0  # it talks to neither vehicle
    stored_before: list[FleetCoordination] = []

    def read_state(fleet_id: int) -> None:
        storage = open_storage(fleet_stack.db_url)
        try:
            # killed once the owner stored a closest approach: both vehicles in the air together
            stored = poll(
                lambda: storage.fleet_coordination(fleet_id),
                lambda state: state.separation.min_distance_m is not None,
                60.0,
                "a closest approach stored",
            )
            stored_before.append(stored)
        finally:
            storage.close()

    run = fly_fleet_and_kill(fleet_stack, before_kill=read_state)
    print(
        f"\nfleet fail-over: take-over {run['takeover_s']:.2f} s after the kill, followed again after "
        f"{run['followed_again_s']:.2f} s, every part re-attached after {run['reattached_s']:.2f} s; largest gap "
        f"{run['gap_s']:.2f} s simulated; {run['buoys_lost']} buoys lost; closest approach {run['min_distance_m']} m"
        f"; load {run['load_after']:.1f}"
    )
    assert run["takeover_s"] < TAKEOVER_REQUIREMENT_S
    assert (run["status"], run["reason"], run["visited"], run["buoys_lost"]) == ("completed", None, 6, 0)
    assert all(part["status"] == "completed" for part in run["parts"])
    assert run["followed_again_s"] is not None and run["followed_again_s"] < TAKEOVER_REQUIREMENT_S
    assert run["reattached_s"] is not None and run["reattached_s"] < TAKEOVER_REQUIREMENT_S + REATTACH_ALLOWANCE_S
    assert run["duplicates"] == 0 and run["lost_beyond_gap"] == 0
    (before,) = stored_before
    assert before.coordinator == "gcs-a" and run["coordinator"] == "gcs-b"
    assert run["min_distance_m"] <= before.separation.min_distance_m  # carried on, not started again
    assert run["stored_min_distance_m"] == run["min_distance_m"]
    fleet = standby.get(f"/missions/{run['mission']}")
    reasons = [e["reason"] for e in fleet["events"]]
    assert reasons.count(FOLLOWED_AGAIN) == 1 and fleet["events"][-1]["status"] == "completed"
    assert [v["role"] for v in standby.get("/vehicles")] == ["owner", "owner"]
    assert udp_sockets(standby.process.pid) == 2  # a link per vehicle


@pytest.mark.parametrize("fleet_stack", [LOST_VEHICLE_WAIT_S], indirect=True)
def test_a_vehicle_lost_with_the_owner_has_its_buoys_re_shared_by_the_standby_and_no_buoy_is_lost(fleet_stack):
    """Vehicle 2 dies with the owner (one host for both, a radio gone): the stand-by re-attaches vehicle 1's part,
    gives vehicle 2's up once it does not answer within its --vehicle-wait, and re-shares its buoys not inspected to
    vehicle 1, in flight: the fleet mission completes with every buoy."""
    _, standby = fleet_stack.instances
    run = fly_fleet_and_kill(fleet_stack, lose_vehicle=2)
    print(
        f"\nfleet fail-over, vehicle 2 lost with the owner: take-over {run['takeover_s']:.2f} s, vehicle 1 "
        f"re-attached after {run['reattached_s']:.2f} s, vehicle 2's buoys re-shared after {run['reshared_s']:.2f} s; "
        f"{run['buoys_lost']} buoys lost; load {run['load_after']:.1f}"
    )
    assert run["takeover_s"] < TAKEOVER_REQUIREMENT_S
    assert [(part["sysid"], part["status"]) for part in run["parts"]] == [(1, "completed"), (2, "failed")]
    assert run["reattached_s"] is not None and run["reshared_s"] is not None
    assert (run["status"], run["reason"], run["visited"], run["buoys_lost"]) == ("completed", None, 6, 0)
    fleet = standby.get(f"/missions/{run['mission']}")
    lost = fleet["fleet"]["shares"][1]
    assert lost["sysid"] == 2 and lost["lost"] and set(lost["handed_over"]) == {"1"}
    handed = lost["handed_over"]["1"]
    assert handed and all(fleet["fleet"]["inspected_by"][f"B{b + 1}"] == 1 for b in handed)  # flown by vehicle 1
    assert run["coordinator"] == "gcs-b"
