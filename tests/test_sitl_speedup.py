"""SIM_SPEEDUP over the wire: a cap on the simulation's pace, set while it runs. In lockstep (vehicle and its
offboard controller, answering every tick) and paced (`--speed`) alike, SIM_SPEEDUP N holds simulated time to at
most N times the wall clock, and 0 lets it run as fast as it did before.

The rate is measured from the vehicle's time_boot_ms against time.monotonic() over a few wall seconds. The cap only
ever slows the vehicle, so the bounds hold on a loaded machine: at most a little over N (a vehicle that was behind
when the interval began may catch up by up to sitl_quad.pacing.RESYNC_BEHIND_S), and more than a low bound; the cap
is set below real time so that even a loaded machine's uncapped lockstep is well above it.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Iterator

import pytest
from conftest import connected
from sitl_process import GroundStation, start_lockstep_pair

from bench.processes import free_udp_port, stop_reading_output
from sitl_quad.pacing import RESYNC_BEHIND_S
from uavcore.mavlink import mavlink

pytestmark = [pytest.mark.integration, pytest.mark.timeout(300)]

REAL32 = mavlink.MAV_PARAM_TYPE_REAL32
# Below real time, so that the cap is what limits the pace even on a loaded machine, where lockstep uncapped may
# run at only 1-2x real time (beside two CPU burners: 1.4x): a cap above that would not be seen, and the uncapped
# rate could come out below it. Any machine this runs on does better than 1x uncapped.
CAP = 0.25
CAPPED_S = 6.0  # wall seconds measured at the cap: a catch-up of RESYNC_BEHIND_S is then at most 0.08x more
FREE_S = 3.0
STARTED_S = 60.0  # a backstop for a loaded machine's start-up (numba's kernels load in each process)


def fresh_sample(gcs: GroundStation) -> tuple[float, float]:
    """(wall time, simulated time) now: the first ATTITUDE after everything queued was dropped."""
    gcs.drain()
    attitude = gcs.recv("ATTITUDE", timeout=10)
    assert attitude is not None, "no ATTITUDE from the vehicle"
    return time.monotonic(), attitude.time_boot_ms / 1000.0


def sim_rate(gcs: GroundStation, wall_s: float) -> float:
    """Simulated seconds per wall second over about `wall_s` wall seconds."""
    wall0, sim0 = fresh_sample(gcs)
    while time.monotonic() < wall0 + wall_s:
        gcs.send_heartbeat()  # stay a live peer of the vehicle
        time.sleep(min(0.5, max(0.0, wall0 + wall_s - time.monotonic())))
    wall1, sim1 = fresh_sample(gcs)
    return (sim1 - sim0) / (wall1 - wall0)


def set_speedup(gcs: GroundStation, value: float) -> None:
    answer = gcs.set_param("SIM_SPEEDUP", value, REAL32)
    assert answer is not None and answer.param_type == REAL32 and answer.param_value == value


@contextlib.contextmanager
def lockstep_vehicle(tmp_path) -> Iterator[GroundStation]:
    """A lockstep vehicle whose offboard controller answers every tick (its DEBUG_VECT proves it), and a GCS on it."""
    port = free_udp_port()
    vehicle, controller = start_lockstep_pair(port, seed=3, log=tmp_path / "flight.csv")
    gcs = GroundStation(port)
    try:
        gcs.connect(timeout=STARTED_S)
        answering = gcs.recv("DEBUG_VECT", timeout=STARTED_S, condition=lambda m: m.get_srcComponent() == 191)
        assert answering is not None, "the offboard controller never answered a tick"
        yield gcs
    finally:
        gcs.close()
        errors = [stop_reading_output(p, 20)[1] for p in (controller, vehicle)]
    assert all("Traceback" not in e for e in errors), errors


@contextlib.contextmanager
def paced_vehicle(start_sitl) -> Iterator[GroundStation]:
    gcs = connected(start_sitl(speed=20.0))
    try:
        yield gcs
    finally:
        gcs.close()


@pytest.mark.parametrize("pacing", ["lockstep", "paced"])
def test_sim_speedup_caps_the_pace_while_it_runs_and_0_lifts_the_cap(tmp_path, start_sitl, pacing):
    vehicle = lockstep_vehicle(tmp_path) if pacing == "lockstep" else paced_vehicle(start_sitl)
    with vehicle as gcs:
        assert gcs.read_param("SIM_SPEEDUP").param_value == 0.0  # the default: lockstep as fast as it goes
        set_speedup(gcs, CAP)
        capped = sim_rate(gcs, CAPPED_S)
        set_speedup(gcs, 0.0)
        free = sim_rate(gcs, FREE_S)
        refused = gcs.set_param("SIM_SPEEDUP", -1.0, REAL32)  # out of range: answered with the value kept
        assert refused is not None and refused.param_value == 0.0
    print(f"{pacing}: {capped:.2f}x with SIM_SPEEDUP {CAP:g}, {free:.2f}x with 0")
    assert 0.5 * CAP < capped <= 1.1 * CAP + RESYNC_BEHIND_S / CAPPED_S
    assert free >= 2.0 * capped  # the cap lifted: lockstep as fast as it goes (paced: --speed 20), far over 0.25x
