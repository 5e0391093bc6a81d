"""Fail-over between two service instances on one PostgreSQL database, measured.

    .venv/bin/python -m bench.failover [--runs 5] [--speed 4] [--db postgresql://...]
    # prints a table, writes bench/results/failover.json

Each run starts the vehicle (`python -m sitl_quad --speed N`: its own position loop flies, paced at N times the
wall clock) and two `python -m gcs serve --db URL` instances for it on their own HTTP ports: the first owns the
vehicle link, the second stands by. A short mission (three buoys 30 m apart) is posted to the owner; once it
flies and the owner has stored samples, the owner is killed (SIGKILL: no goodbye, its lease is released by
PostgreSQL when its session dies). Per run:
- take-over: wall seconds from the kill until the stand-by says `role: owner` (GET /vehicle; requirement 5 s);
- re-attached: wall seconds from the kill until the new owner re-attached the mission (its event's timestamp);
- the telemetry gap across the kill: the largest step between consecutive stored samples, in simulated seconds
  and in wall seconds at the vehicle's pace (simulated / N), and the unflushed tail the owner took with it;
- duplicates (samples with the same t_s) and samples lost beyond the gap (missing 10 Hz samples elsewhere);
- the mission's end (completed, buoys visited) and the machine's 1-minute load average.

    .venv/bin/python -m bench.failover --fleet 2 [--runs 3]
    # the fleet case: rows under "fleet", "K vehicles" in bench/results/failover.json (the other rows kept)
    .venv/bin/python -m bench.failover --fleet 3 --lose-vehicle 3
    # vehicle 3 killed with the owner: the stand-by gives it up and re-shares its buoys to the others

The fleet case (`--fleet K`): K vehicles (system ids 1..K, on pads 3 m apart at the depot, each its own port) and
two instances each linked to all of them (`serve --vehicle 1=URL --vehicle 2=URL ...`): the first owns the
fleet's leases (one per vehicle, all or none: gcs.missions.ownership), the second stands by. A fleet mission
(FLEET_BUOYS_EN_M shared among the K vehicles, each at its own layer) is posted to the owner; once every part
flies and has stored samples, the owner is SIGKILLed. Per run: take-over (the stand-by owning every vehicle),
the fleet mission followed again (its FOLLOWED_AGAIN event) and each part re-attached (its REATTACHED event),
wall seconds after the kill; the largest telemetry gap of any part, duplicates; buoys lost (not inspected by
any vehicle: must be none); the fleet mission's end, its closest approach, its coordinator.

Without --db a throwaway PostgreSQL server is started from the machine's binaries (tests/postgres_server.py),
with a fresh database per run. tests/test_gcs_failover.py runs the same scenarios (`FailoverStack`,
`fly_and_kill`, `fly_fleet_and_kill`).
"""

from __future__ import annotations

import argparse
import contextlib
import itertools
import json
import math
import os
import signal
import statistics
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path
from typing import Any, TypeVar

import httpx

from bench.processes import free_tcp_port, free_udp_port
from gcs.missions.fleet_missions import FOLLOWED_AGAIN
from gcs.missions.lifecycle import REATTACHED
from gcs.storage import open_storage
from stack.supervisor import ChildSpec, Supervisor, SupervisorError, python_module
from uavcore.geodesy import DEFAULT_HOME, LocalFrame

REPO = Path(__file__).resolve().parents[1]
RESULTS = REPO / "bench" / "results" / "failover.json"
BUOYS_EN_M = ((30.0, 0.0), (30.0, 30.0), (0.0, 30.0))  # east, north of the depot (the vehicle's home)
# a fleet mission's buoys, east and north of the depot: on either side of it, each vehicle's share a short flight
FLEET_BUOYS_EN_M = ((30.0, 0.0), (30.0, 30.0), (0.0, 30.0), (-30.0, 0.0), (-30.0, -30.0), (0.0, -30.0))
FLEET_LAYER_GAP_M = 3.0
PAD_SPACING_M = 3.0  # the vehicles' pads, east of each other at the depot (as `buoy-gcs up --vehicles K` sets them)
MISSION = {"altitude_m": 5.0, "speed_m_s": 5.0, "dwell_s": 1.0, "acceptance_radius_m": 2.0}
TELEMETRY_PERIOD_S = 0.1  # the service's default sample spacing (simulated time)
TAKEOVER_REQUIREMENT_S = 5.0
VEHICLE_WAIT_S = 30.0  # wall seconds a mission waits for its vehicle (`serve --vehicle-wait`): a loaded machine
START_TIMEOUT_S = 120.0  # a loaded 2-core machine takes long to import numpy, numba and FastAPI
FLIGHT_TIMEOUT_S = 180.0
# wall seconds an instance may take to stop on SIGTERM: uvicorn's grace for open requests (gcs.cli's
# SHUTDOWN_GRACE_S) plus storing what the mission recorded, on a loaded machine
STOP_TIMEOUT_S = 30.0
TERMINAL = {"completed", "failed", "aborted"}

T = TypeVar("T")


def close_buoys(east_north_m: tuple[tuple[float, float], ...] = BUOYS_EN_M) -> list[dict[str, float | str]]:
    """Buoys around the depot, close together (by default three: a flight of about a minute of simulated time)."""
    lat_lon = LocalFrame(*DEFAULT_HOME).unproject(list(east_north_m))
    return [{"id": f"B{i + 1}", "lat": float(lat), "lon": float(lon)} for i, (lat, lon) in enumerate(lat_lon)]


def pad_home(sysid: int) -> str:
    """Vehicle `sysid`'s home for `sitl_quad --home`: its own pad at the depot."""
    lat, lon, _ = LocalFrame(*DEFAULT_HOME).from_ned(0.0, (sysid - 1) * PAD_SPACING_M, 0.0)
    return f"{lat:.8f},{lon:.8f},{DEFAULT_HOME[2]:g}"


def poll(
    read: Callable[[], T | None], done: Callable[[T], bool], timeout_s: float, what: str, interval_s: float = 0.05
) -> T:
    """read() until it answers (not None) with a value that is done; RuntimeError naming `what` after timeout_s."""
    deadline = time.monotonic() + timeout_s
    value = None
    while time.monotonic() < deadline:
        value = read()
        if value is not None and done(value):
            return value
        time.sleep(interval_s)
    raise RuntimeError(f"{what}: not within {timeout_s:g} s (last answer: {value})")


def read_log(path: Path) -> str:
    """A child's log as written so far ("" before it has written one)."""
    return path.read_text(errors="replace") if path.exists() else ""


@dataclass
class Instance:
    """One `python -m gcs serve` process (once started) and an HTTP client for it."""

    name: str
    client: httpx.Client
    log_path: Path
    process: subprocess.Popen | None = None

    def get(self, path: str) -> dict[str, Any] | list[Any] | None:
        """The JSON of a GET, None while the instance does not answer (starting, or dead)."""
        try:
            response = self.client.get(path)
        except httpx.HTTPError:
            return None
        return response.json() if response.status_code == 200 else None

    def vehicle(self) -> dict[str, Any] | None:
        return self.get("/vehicle")

    def kill(self, how: signal.Signals = signal.SIGKILL) -> None:
        """SIGKILL: the instance dies where it stands; SIGTERM: it stops, handing a flying mission over. An
        instance still running STOP_TIMEOUT_S later is made to write its stacks (SIGUSR1), killed, and the error
        carries its log's end: where it hung."""
        self.process.send_signal(how)
        try:
            self.process.wait(STOP_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            self.process.send_signal(signal.SIGUSR1)
            with contextlib.suppress(RuntimeError):  # no dump (the loop itself hung): the threads' stacks say why
                poll(self._log, lambda text: "stack dump:" in text, 10.0, "its stack dump", interval_s=0.2)
            self.process.kill()
            self.process.wait()
            raise RuntimeError(
                f"{self.name} still ran {STOP_TIMEOUT_S:g} s after {how.name}; its log ends:\n{self._log()[-12000:]}"
            ) from None

    def _log(self) -> str:
        return read_log(self.log_path)


def owns_a_connected_vehicle(vehicle: dict[str, Any] | None) -> bool:
    """GET /vehicle of an instance that owns the link and hears the vehicle."""
    return vehicle is not None and vehicle["role"] == "owner" and vehicle["connected"]


def stands_by(vehicle: dict[str, Any] | None) -> bool:
    return vehicle is not None and vehicle["role"] == "standby"


def owns_every_vehicle(vehicles: Any) -> bool:
    """GET /vehicles of an instance that owns the fleet's links and hears every vehicle."""
    return bool(vehicles) and all(v["role"] == "owner" and v["connected"] for v in vehicles)


@dataclass
class FailoverStack:
    """The vehicle and two service instances on one database, on free loopback ports, started in order by
    `buoy-gcs up`'s supervisor (each waited for: the first owning the vehicle link, the second standing by) and
    never restarted; `close()` stops what is left."""

    db_url: str
    logs: Path
    speed: float = 4.0
    lease_poll_s: float = 0.5
    vehicles: int = 1  # more: a fleet, system ids 1..vehicles, each instance linked to every one
    # wall seconds the stand-by, once owner, waits for a vehicle to re-attach its mission (`--vehicle-wait`): how
    # soon it gives up on a vehicle lost with the owner
    standby_vehicle_wait_s: float = VEHICLE_WAIT_S
    instances: list[Instance] = field(default_factory=list)
    supervisor: Supervisor | None = None

    def start(self) -> FailoverStack:
        pace = ("--speed", f"{self.speed:g}")
        ports = [free_udp_port() for _ in range(self.vehicles)]
        if self.vehicles == 1:
            specs = [ChildSpec("vehicle", python_module("sitl_quad", "--port", str(ports[0]), *pace))]
        else:
            specs = [
                ChildSpec(
                    f"vehicle-{sysid}",
                    python_module(
                        "sitl_quad", "--port", str(port), "--sysid", str(sysid), "--home", pad_home(sysid), *pace
                    ),
                )
                for sysid, port in enumerate(ports, 1)
            ]
        for name, ready in (("gcs-a", self.owns_the_links), ("gcs-b", lambda i: stands_by(i.vehicle()))):
            port = free_tcp_port()
            client = httpx.Client(base_url=f"http://127.0.0.1:{port}", timeout=10.0)
            instance = Instance(name, client, self.logs / f"{name}.log")
            self.instances.append(instance)
            specs.append(
                ChildSpec(
                    name,
                    self._serve(ports, port, VEHICLE_WAIT_S if name == "gcs-a" else self.standby_vehicle_wait_s),
                    ready=lambda instance=instance, ready=ready: ready(instance),
                    start_timeout_s=START_TIMEOUT_S,
                    env={"BUOY_GCS_INSTANCE_NAME": name, "BUOY_GCS_LEASE_POLL_S": str(self.lease_poll_s)},
                )
            )
        self.supervisor = Supervisor(specs, self.logs, REPO, say=lambda _: None)
        try:
            self.supervisor.start_all()
        except SupervisorError as error:  # say why: the logs' ends
            tails = "\n".join(f"--- {spec.name}:\n{self.log(spec.name)[-2000:]}" for spec in specs)
            raise SupervisorError(f"{error}\n{tails}") from None
        for instance, child in zip(self.instances, self.supervisor.children[self.vehicles :], strict=True):
            instance.process = child.process
        return self

    def owns_the_links(self, instance: Instance) -> bool:
        """The instance owns the link of the vehicle (of every vehicle of the fleet) and hears it."""
        if self.vehicles == 1:
            return owns_a_connected_vehicle(instance.vehicle())
        return owns_every_vehicle(instance.get("/vehicles"))

    def _serve(self, vehicle_ports: list[int], port: int, vehicle_wait_s: float) -> list[str]:
        """`python -m gcs serve` for the vehicles on vehicle_ports (a fleet: each named by its system id), on the
        shared database, HTTP on port."""
        if self.vehicles == 1:
            links = [f"udpout:127.0.0.1:{vehicle_ports[0]}"]
        else:
            links = [f"{sysid}=udpout:127.0.0.1:{p}" for sysid, p in enumerate(vehicle_ports, 1)]
        vehicles = [arg for link in links for arg in ("--vehicle", link)]
        wait = ("--vehicle-wait", f"{vehicle_wait_s:g}")
        return python_module("gcs", "serve", *vehicles, *wait, "--db", self.db_url, "--port", str(port))

    def log(self, name: str) -> str:
        return read_log(self.logs / f"{name}.log")

    def close(self) -> None:
        for instance in self.instances:
            instance.client.close()
        if self.supervisor is not None:
            self.supervisor.stop_all()


def _unix(timestamp: str) -> float:
    return datetime.fromisoformat(timestamp).timestamp()


def telemetry_figures(times: list[float], kill_t_s: float) -> dict[str, Any]:
    """Duplicates, the gap the kill made (the largest step ending after vehicle time kill_t_s: across the kill
    for SIGKILL, a little after it for SIGTERM, when the owner stores what it recorded while it stops) and the
    10 Hz samples missing elsewhere."""
    ordered = sorted(times)
    steps = [(b - a, a, b) for a, b in itertools.pairwise(ordered)]
    after_kill = [step for step in steps if step[2] > kill_t_s]
    gap_s, gap_from, gap_to = max(after_kill) if after_kill else (0.0, kill_t_s, kill_t_s)
    elsewhere = [step for step in steps if step[1:] != (gap_from, gap_to)]
    # a step of two periods or more misses a sample (the recorder keeps one per period of the vehicle's stream, so
    # a stream message a little early makes a step of up to two periods with nothing missed)
    lost = sum(max(0, math.floor(step / TELEMETRY_PERIOD_S + 0.05) - 1) for step, _, _ in elsewhere)
    return {
        "samples": len(times),
        "duplicates": len(times) - len(set(times)),
        "gap_s": gap_s,
        "gap_from_t_s": gap_from,
        "gap_to_t_s": gap_to,
        "unflushed_tail_s": max(0.0, kill_t_s - gap_from),  # flown after the owner's last write, before the kill
        "largest_step_elsewhere_s": max((step for step, _, _ in elsewhere), default=0.0),
        "lost_beyond_gap": lost,
    }


def taken_over_to_the_end(survivor: Instance, mission_id: int, kill_wall: float) -> tuple[dict, float, dict]:
    """After the owner's kill: the survivor owning every link (its GET /vehicle), the take-over's wall seconds
    since kill_wall, and the mission (or fleet mission) once it ended."""
    role = poll(survivor.vehicle, lambda v: v["role"] == "owner", 30.0, f"{survivor.name} owning the links")
    takeover_s = time.monotonic() - kill_wall
    mission = poll(
        lambda: survivor.get(f"/missions/{mission_id}"),
        lambda m: m["status"] in TERMINAL,
        FLIGHT_TIMEOUT_S,
        f"mission {mission_id} ending",
        interval_s=0.25,
    )
    return role, takeover_s, mission


def fly_and_kill(
    stack: FailoverStack, victim: str, kill_after_samples: int = 20, how: signal.Signals = signal.SIGKILL
) -> dict[str, Any]:
    """Post the mission to the owner, kill `victim` ("owner" or "standby") once the mission flies and the owner
    has stored kill_after_samples samples, and follow the mission to its end on the instance left. Figures."""
    owner, standby = stack.instances
    load_before = os.getloadavg()[0]
    created = owner.client.post("/missions", json={"buoys": close_buoys(), **MISSION})
    created.raise_for_status()
    mission_id = created.json()["id"]
    poll(lambda: owner.get(f"/missions/{mission_id}"), lambda m: m["status"] == "flying", FLIGHT_TIMEOUT_S, "flying")
    poll(
        lambda: owner.get(f"/missions/{mission_id}/telemetry?limit={kill_after_samples}"),
        lambda samples: len(samples) >= kill_after_samples,
        FLIGHT_TIMEOUT_S,
        f"{kill_after_samples} samples stored",
    )
    kill_t_s = owner.vehicle()["t_s"]  # the vehicle's time at the kill (to the owner's last message)
    killed, survivor = (owner, standby) if victim == "owner" else (standby, owner)
    kill_unix, kill_wall = time.time(), time.monotonic()
    killed.kill(how)
    role, takeover_s, mission = taken_over_to_the_end(survivor, mission_id, kill_wall)
    samples = survivor.get(f"/missions/{mission_id}/telemetry") or []
    reattached = [e for e in mission["events"] if e["reason"] == REATTACHED]
    figures = telemetry_figures([s["t_s"] for s in samples], kill_t_s)
    return {
        "victim": victim,
        "mission": mission_id,
        "status": mission["status"],
        "reason": mission["reason"],
        "visited": mission["progress"].get("visited"),
        "buoys": len(BUOYS_EN_M),
        "owner_after": role["instance"],
        "takeover_s": takeover_s,
        "reattached_s": _unix(reattached[0]["at"]) - kill_unix if reattached else None,
        "kill_t_s": kill_t_s,
        **figures,
        "gap_wall_s": figures["gap_s"] / stack.speed,
        "speed": stack.speed,
        "load_before": load_before,
        "load_after": os.getloadavg()[0],
    }


def _event_after(mission: dict[str, Any], reason: str, kill_unix: float, prefix: bool = False) -> float | None:
    """Wall seconds from the kill to the mission's first event with this reason (or beginning so with `prefix`),
    None when it has none."""
    times = [
        _unix(e["at"]) - kill_unix
        for e in mission["events"]
        if e["reason"] == reason or (prefix and (e["reason"] or "").startswith(reason))
    ]
    return times[0] if times else None


def fly_fleet_and_kill(
    stack: FailoverStack,
    kill_after_samples: int = 20,
    how: signal.Signals = signal.SIGKILL,
    before_kill: Callable[[int], None] | None = None,
    lose_vehicle: int | None = None,
) -> dict[str, Any]:
    """Post a fleet mission (FLEET_BUOYS_EN_M over every vehicle) to the owner, kill the owner once every part flies
    and has stored kill_after_samples samples (`before_kill(fleet_id)` called just before; `lose_vehicle`: that
    vehicle's process killed with it, as a vehicle lost with the owner's host), and follow the fleet mission to its
    end on the stand-by. Figures."""
    owner, standby = stack.instances
    load_before = os.getloadavg()[0]
    buoys = close_buoys(FLEET_BUOYS_EN_M)
    request = {"buoys": buoys, "vehicles": "fleet", "layer_gap_m": FLEET_LAYER_GAP_M, **MISSION}
    created = owner.client.post("/missions", json=request)
    created.raise_for_status()
    fleet_id = created.json()["id"]
    fleet = poll(
        lambda: owner.get(f"/missions/{fleet_id}"),
        lambda m: m["status"] == "flying" and all(share["status"] == "flying" for share in m["fleet"]["shares"]),
        FLIGHT_TIMEOUT_S,
        "every part flying",
    )
    parts = {share["mission_id"]: share["sysid"] for share in fleet["fleet"]["shares"]}
    for part in parts:
        poll(
            lambda part=part: owner.get(f"/missions/{part}/telemetry?limit={kill_after_samples}"),
            lambda samples: len(samples) >= kill_after_samples,
            FLIGHT_TIMEOUT_S,
            f"{kill_after_samples} samples stored of part {part}",
        )
    if before_kill is not None:
        before_kill(fleet_id)
    kill_t_s = {vehicle["sysid"]: vehicle["t_s"] for vehicle in owner.get("/vehicles") or []}
    kill_unix, kill_wall = time.time(), time.monotonic()
    if lose_vehicle is not None:
        vehicle = stack.supervisor.children[lose_vehicle - 1].process
        vehicle.kill()
        vehicle.wait()
    owner.kill(how)
    _, takeover_s, fleet = taken_over_to_the_end(standby, fleet_id, kill_wall)
    per_part = []
    for part, sysid in parts.items():
        mission = standby.get(f"/missions/{part}") or {}
        samples = standby.get(f"/missions/{part}/telemetry") or []
        figures = telemetry_figures([sample["t_s"] for sample in samples], kill_t_s[sysid])
        reattached = _event_after(mission, REATTACHED, kill_unix)
        per_part.append({"mission": part, "sysid": sysid, "status": mission.get("status"), "reattached_s": reattached,
                         "gap_s": figures["gap_s"], "duplicates": figures["duplicates"],
                         "lost_beyond_gap": figures["lost_beyond_gap"], "samples": figures["samples"]})  # fmt: skip
    storage = open_storage(stack.db_url)
    try:
        coordination = storage.fleet_coordination(fleet_id)
    finally:
        storage.close()
    reattached_parts = [part["reattached_s"] for part in per_part if part["sysid"] != lose_vehicle]
    return {
        "victim": "owner",
        "mission": fleet_id,
        "vehicles": stack.vehicles,
        "lost_vehicle": lose_vehicle,
        "status": fleet["status"],
        "reason": fleet["reason"],
        "visited": fleet["progress"].get("visited"),
        "buoys": len(buoys),
        "buoys_lost": len(buoys) - (fleet["progress"].get("visited") or 0),
        "takeover_s": takeover_s,
        "followed_again_s": _event_after(fleet, FOLLOWED_AGAIN, kill_unix),
        "reattached_s": None if None in reattached_parts else max(reattached_parts),  # the last part's (not lost)
        "reshared_s": None
        if lose_vehicle is None
        else _event_after(fleet, f"vehicle {lose_vehicle} lost", kill_unix, True),
        "gap_s": max(part["gap_s"] for part in per_part),
        "gap_wall_s": max(part["gap_s"] for part in per_part) / stack.speed,
        "duplicates": sum(part["duplicates"] for part in per_part),
        "lost_beyond_gap": sum(part["lost_beyond_gap"] for part in per_part),
        "min_distance_m": fleet["fleet"]["separation"]["min_distance_m"],
        "coordinator": None if coordination is None else coordination.coordinator,
        "stored_min_distance_m": None if coordination is None else coordination.separation.min_distance_m,
        "parts": per_part,
        "speed": stack.speed,
        "load_before": load_before,
        "load_after": os.getloadavg()[0],
    }


LOST_VEHICLE_WAIT_S = 3.0  # the stand-by's --vehicle-wait when a vehicle is lost with the owner


def one_run(
    db_url: str, logs: Path, speed: float, vehicles: int = 1, lose_vehicle: int | None = None
) -> dict[str, Any]:
    wait_s = VEHICLE_WAIT_S if lose_vehicle is None else LOST_VEHICLE_WAIT_S
    stack = FailoverStack(db_url, logs, speed, vehicles=vehicles, standby_vehicle_wait_s=wait_s)
    try:
        stack.start()
        return fly_and_kill(stack, "owner") if vehicles == 1 else fly_fleet_and_kill(stack, lose_vehicle=lose_vehicle)
    finally:
        stack.close()


def print_table(runs: list[dict[str, Any]]) -> None:
    print(
        f"{'run':>3} {'take-over s':>11} {'re-attach s':>11} {'gap sim s':>9} {'gap wall s':>10} {'tail s':>6} "
        f"{'dups':>4} {'lost':>4} {'samples':>7} {'status':>9} {'visited':>7} {'load':>9}"
    )
    for i, run in enumerate(runs, 1):
        reattached = "-" if run["reattached_s"] is None else f"{run['reattached_s']:.2f}"
        print(
            f"{i:>3} {run['takeover_s']:>11.2f} {reattached:>11} {run['gap_s']:>9.2f} {run['gap_wall_s']:>10.2f} "
            f"{run['unflushed_tail_s']:>6.2f} {run['duplicates']:>4} {run['lost_beyond_gap']:>4} "
            f"{run['samples']:>7} {run['status']:>9} {run['visited']:>3}/{run['buoys']:<3} "
            f"{run['load_before']:>4.1f}-{run['load_after']:<4.1f}"
        )


def print_fleet_table(runs: list[dict[str, Any]]) -> None:
    print(
        f"{'run':>3} {'vehicles':>8} {'take-over s':>11} {'followed s':>10} {'re-attach s':>11} {'re-share s':>10} "
        f"{'gap sim s':>9} {'dups':>4} {'lost':>4} {'buoys lost':>10} {'status':>9} {'min 3-D m':>9} {'load':>9}"
    )
    for i, run in enumerate(runs, 1):
        followed, reattached, reshared = (
            "-" if run[key] is None else f"{run[key]:.2f}" for key in ("followed_again_s", "reattached_s", "reshared_s")
        )
        distance = "-" if run["min_distance_m"] is None else f"{run['min_distance_m']:.1f}"
        print(
            f"{i:>3} {run['vehicles']:>8} {run['takeover_s']:>11.2f} {followed:>10} {reattached:>11} {reshared:>10} "
            f"{run['gap_s']:>9.2f} {run['duplicates']:>4} {run['lost_beyond_gap']:>4} {run['buoys_lost']:>10} "
            f"{run['status']:>9} {distance:>9} {run['load_before']:>4.1f}-{run['load_after']:<4.1f}"
        )


def fleet_summary(runs: list[dict[str, Any]]) -> dict[str, Any]:
    takeovers = [run["takeover_s"] for run in runs]
    reattached = [run["reattached_s"] for run in runs if run["reattached_s"] is not None]
    return {
        "runs": len(runs),
        "vehicles": runs[0]["vehicles"],
        "completed": sum(run["status"] == "completed" and run["buoys_lost"] == 0 for run in runs),
        "buoys_lost": sum(run["buoys_lost"] for run in runs),
        "takeover_s": {"median": statistics.median(takeovers), "max": max(takeovers)},
        "takeover_within_requirement": sum(t <= TAKEOVER_REQUIREMENT_S for t in takeovers),
        "reattached_s": {"median": statistics.median(reattached), "max": max(reattached)} if reattached else None,
        "duplicates": sum(run["duplicates"] for run in runs),
        "lost_beyond_gap": sum(run["lost_beyond_gap"] for run in runs),
    }


def summary(runs: list[dict[str, Any]]) -> dict[str, Any]:
    takeovers = [run["takeover_s"] for run in runs]
    gaps = [run["gap_s"] for run in runs]
    return {
        "runs": len(runs),
        "completed": sum(run["status"] == "completed" and run["visited"] == run["buoys"] for run in runs),
        "takeover_s": {"median": statistics.median(takeovers), "max": max(takeovers)},
        "takeover_within_requirement": sum(t <= TAKEOVER_REQUIREMENT_S for t in takeovers),
        "gap_s": {"median": statistics.median(gaps), "max": max(gaps)},
        "duplicates": sum(run["duplicates"] for run in runs),
        "lost_beyond_gap": sum(run["lost_beyond_gap"] for run in runs),
    }


def rounded(value: Any) -> Any:
    """Floats to the millisecond (or 3 decimals) for the JSON file."""
    if isinstance(value, float):
        return round(value, 3)
    if isinstance(value, dict):
        return {key: rounded(item) for key, item in value.items()}
    if isinstance(value, list):
        return [rounded(item) for item in value]
    return value


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench.failover", description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--speed", type=float, default=4.0, help="the vehicle's pace, times the wall clock")
    parser.add_argument("--db", help="an empty PostgreSQL database (default: a throwaway server, a database per run)")
    parser.add_argument("--logs", type=Path, default=Path("/tmp/bench-failover"), help="the processes' logs")
    parser.add_argument(
        "--fleet", type=int, metavar="K", help="the fleet case: K vehicles (2-3 on 2 cores) flying one fleet mission"
    )
    parser.add_argument(
        "--lose-vehicle",
        type=int,
        metavar="SYSID",
        help="the fleet case: that vehicle killed with the owner (given up after 3 s, its buoys re-shared)",
    )
    args = parser.parse_args(argv)
    if args.fleet is not None and args.fleet < 2:
        parser.error("--fleet: a fleet has 2 vehicles or more")
    if args.lose_vehicle is not None and not 1 <= args.lose_vehicle <= (args.fleet or 0):
        parser.error("--lose-vehicle: the system id of one of the --fleet's vehicles")
    server = None
    if args.db is None:
        from tests.postgres_server import PostgresServer, postgres_bindir  # test infrastructure, reused

        bindir = postgres_bindir()
        if bindir is None:
            print("no PostgreSQL binaries (initdb, pg_ctl): install Debian's postgresql or pass --db URL")
            return 2
        server = PostgresServer(bindir).start()
    runs = []
    try:
        for i in range(args.runs):
            db_url = args.db or server.new_database()
            runs.append(one_run(db_url, args.logs / f"run-{i + 1}", args.speed, args.fleet or 1, args.lose_vehicle))
    finally:
        if server is not None:
            server.stop()
    if args.fleet is not None:
        return write_fleet_results(runs, args.speed)
    print_table(runs)
    figures = summary(runs)
    print(
        f"take-over median {figures['takeover_s']['median']:.2f} s, max {figures['takeover_s']['max']:.2f} s "
        f"(requirement {TAKEOVER_REQUIREMENT_S:g} s: {figures['takeover_within_requirement']}/{len(runs)}); "
        f"completed {figures['completed']}/{len(runs)}; cores {os.cpu_count()}"
    )
    document = {"speed": args.speed, "cores": os.cpu_count(), "summary": figures, "runs": runs}
    write_results(document | {key: value for key, value in _stored().items() if key == "fleet"})
    return 0


def write_fleet_results(runs: list[dict[str, Any]], speed: float) -> int:
    """Print the fleet case's table and store its rows under "fleet", keeping the single-vehicle rows."""
    print_fleet_table(runs)
    figures = fleet_summary(runs)
    print(
        f"fleet of {figures['vehicles']}: take-over median {figures['takeover_s']['median']:.2f} s, "
        f"max {figures['takeover_s']['max']:.2f} s; completed with every buoy {figures['completed']}/{len(runs)}, "
        f"buoys lost {figures['buoys_lost']}; cores {os.cpu_count()}"
    )
    fleet = {"speed": speed, "cores": os.cpu_count(), "summary": figures, "runs": runs}
    case = f"{figures['vehicles']} vehicles"
    if (lost := runs[0]["lost_vehicle"]) is not None:
        case += f", vehicle {lost} lost with the owner"
    stored = _stored()
    write_results(stored | {"fleet": stored.get("fleet", {}) | {case: fleet}})
    return 0


def _stored() -> dict[str, Any]:
    return json.loads(RESULTS.read_text()) if RESULTS.exists() else {}


def write_results(document: dict[str, Any]) -> None:
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text(json.dumps(rounded(document), indent=2))
    print(f"written {RESULTS.relative_to(REPO)}")


if __name__ == "__main__":
    sys.exit(main())
