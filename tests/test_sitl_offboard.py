"""Offboard control over real UDP: a SET_ATTITUDE_TARGET stream is obeyed, its loss triggers the failsafe,
and the real adrc_offboard process flies a mission in lockstep, deterministically."""

from __future__ import annotations

import contextlib
import csv
import math
import os
import signal
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest
from sitl_process import GroundStation, start_lockstep_pair
from test_sitl_vehicle import FRAME

from bench.processes import free_udp_port, stop_reading_output
from sitl_quad.config import FailsafeConfig
from uavcore.mavlink import mavlink
from uavcore.rotation import quat_from_euler

pytestmark = pytest.mark.integration

OFFBOARD = 6
AUTO, LOITER, MISSION = 4, 3, 4
# OFFB_LOSS_T in simulated seconds: at 2x real time a gap of half that in the stream's wall clock triggers the
# failsafe, so the stream runs from a thread of its own and the timeout leaves a loaded machine's scheduler room.
LOSS_TIMEOUT_S = 1.0
LOADED_BACKSTOP_S = 90.0  # a wait's deadline: only reached when the behaviour is wrong, never by a slow machine


def main_mode(heartbeat) -> int:
    return (heartbeat.custom_mode >> 16) & 0xFF


class AttitudeStream:
    """SET_ATTITUDE_TARGET every `period_s` (100 Hz) wall clock from a thread of its own, as an offboard computer
    streams, until stop(): the test changes `roll`/`thrust` while it runs and never leaves a gap in the stream (a
    gap longer than OFFB_LOSS_T of the vehicle's time would trigger the failsafe before the test means it to)."""

    def __init__(self, station: GroundStation, roll: float, thrust: float, period_s: float = 0.01) -> None:
        self.station, self.roll, self.thrust, self.period_s = station, roll, thrust, period_s
        self.longest_gap_s = 0.0  # between two sends, wall clock: a loaded machine may hold this thread back
        self._running = True
        self._thread = threading.Thread(target=self._run, name="attitude-stream", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        ignore_rates = 7
        last = None
        while self._running:
            q = [float(c) for c in quat_from_euler(self.roll, 0.0, 0.0)]
            self.station.mav.set_attitude_target_send(0, 1, 1, ignore_rates, q, 0.0, 0.0, 0.0, self.thrust)
            now = time.monotonic()
            if last is not None:
                self.longest_gap_s = max(self.longest_gap_s, now - last)
            last = now
            time.sleep(self.period_s)

    def stop(self) -> None:
        self._running = False
        self._thread.join(timeout=5)


def hold_roll(gcs: GroundStation, roll: float, tolerance: float, count: int = 10) -> None:
    """Wait until `count` ATTITUDE messages in a row show the roll within tolerance of `roll` (the vehicle's pace
    on a loaded machine decides how long that takes: the deadline is only a backstop)."""
    deadline, held, last = time.monotonic() + LOADED_BACKSTOP_S, 0, None
    while held < count:
        assert time.monotonic() < deadline, f"roll never held at {roll}: last {last}"
        gcs.send_heartbeat()  # stay a live peer of the vehicle
        attitude = gcs.recv("ATTITUDE", timeout=1.0)
        if attitude is not None:
            last = attitude.roll
            held = held + 1 if abs(attitude.roll - roll) <= tolerance else 0


HOVER_THRUST = 1.3 * 9.81 / (4 * 2.85e-5 * 500.0**2)  # m g / max thrust of Table 2 at 500 rad/s


@dataclass
class OffboardFlight:
    """A ground station and an onboard computer's station on one vehicle, and the attitude stream once started."""

    gcs: GroundStation
    onboard: GroundStation
    stream: AttitudeStream | None = None

    def take_off_into_offboard(self, period_s: float = 0.01) -> AttitudeStream:
        """Arm, take off to 5 m, and switch to OFFBOARD: refused until a setpoint stream exists, then accepted
        (once the stream's first setpoint has reached the vehicle) while a level hover streams."""
        gcs = self.gcs
        assert gcs.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == mavlink.MAV_RESULT_ACCEPTED
        assert gcs.command(mavlink.MAV_CMD_NAV_TAKEOFF).result == mavlink.MAV_RESULT_ACCEPTED
        assert gcs.recv("LOCAL_POSITION_NED", timeout=LOADED_BACKSTOP_S, condition=lambda m: m.z < -4.5) is not None
        assert gcs.set_mode(OFFBOARD).result == mavlink.MAV_RESULT_TEMPORARILY_REJECTED
        self.stream = AttitudeStream(self.onboard, 0.0, HOVER_THRUST, period_s)
        deadline = time.monotonic() + LOADED_BACKSTOP_S
        while (ack := gcs.set_mode(OFFBOARD)) is not None and ack.result == mavlink.MAV_RESULT_TEMPORARILY_REJECTED:
            assert time.monotonic() < deadline, "OFFBOARD still refused while the setpoints stream"
        assert ack is not None and ack.result == mavlink.MAV_RESULT_ACCEPTED
        return self.stream


@contextlib.contextmanager
def offboard_flight(vehicle) -> Iterator[OffboardFlight]:
    gcs = GroundStation(vehicle.port)
    gcs.connect()
    flight = OffboardFlight(gcs, GroundStation(vehicle.port, sysid=1, compid=mavlink.MAV_COMP_ID_ONBOARD_COMPUTER))
    try:
        yield flight
    finally:
        if flight.stream is not None:
            flight.stream.stop()
        flight.onboard.close()
        gcs.close()


def flight_log(vehicle, log: Path) -> list[dict[str, str]]:
    """The vehicle's --log CSV, one row per outer tick, once the vehicle has stopped and closed it."""
    vehicle.stop()
    with open(log) as f:
        return list(csv.DictReader(f))


def test_attitude_stream_is_obeyed_and_its_loss_lands_gently(start_sitl, tmp_path):
    log = tmp_path / "flight.csv"
    vehicle = start_sitl(
        speed=2.0,
        extra_args=("--param", "OFFB_LOSS_ACT=1", "--param", f"OFFB_LOSS_T={LOSS_TIMEOUT_S:g}", "--log", str(log)),
    )
    with offboard_flight(vehicle) as flight:
        gcs = flight.gcs
        stream = flight.take_off_into_offboard()
        # obeyed: a 0.25 rad roll command shows up in the vehicle's attitude and stays
        roll_target = 0.25
        stream.roll, stream.thrust = roll_target, HOVER_THRUST / math.cos(roll_target)
        hold_roll(gcs, roll_target, 0.05)
        stream.roll, stream.thrust = 0.0, HOVER_THRUST
        hold_roll(gcs, 0.0, 0.05)
        # stop streaming: the failsafe (land) takes over (timed below, in simulated time, from the flight log)
        stream.stop()
        diagnostic = gcs.recv("STATUSTEXT", LOADED_BACKSTOP_S, lambda m: m.text.startswith("OFFB lost"))
        heartbeat = gcs.wait_heartbeat(lambda m: main_mode(m) != OFFBOARD, timeout=LOADED_BACKSTOP_S)
        assert heartbeat is not None and (main_mode(heartbeat), heartbeat.custom_mode >> 24) == (AUTO, 6)
        # the vehicle says why: the newest setpoint older than OFFB_LOSS_T in simulated time, and on the wall clock
        # at least OFFB_LOSS_T / speed since it arrived (the stream really stopped; the simulator did not lag)
        assert diagnostic is not None, "no OFFB lost diagnostic"
        sim_age, wall_age = (float(word[:-1]) for word in diagnostic.text.split()[3:6:2])
        assert sim_age > LOSS_TIMEOUT_S and wall_age >= LOSS_TIMEOUT_S / 2.0 - 0.02, diagnostic.text
        # it lands and disarms without touching the water faster than 1 m/s
        worst = 0.0
        deadline = time.monotonic() + LOADED_BACKSTOP_S
        while time.monotonic() < deadline:
            msg = gcs.recv(["LOCAL_POSITION_NED", "HEARTBEAT"], timeout=2)
            if msg is None:
                continue
            if msg.get_type() == "HEARTBEAT":
                if not msg.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED:
                    break
                gcs.send_heartbeat()
            elif msg.z > -0.5:
                worst = max(worst, msg.vz)
        else:
            pytest.fail("the vehicle did not land and disarm")
        assert worst < 1.0
    rows = flight_log(vehicle, log)
    switch = next(i for i, r in enumerate(rows) if i and rows[i - 1]["mode"] == "OFFBOARD" and r["mode"] != "OFFBOARD")

    # The log holds each setpoint's age at the end of its 20 ms tick; the failsafe looks at the start. The tick
    # that switched saw the setpoint older than OFFB_LOSS_T, by at most one tick; the tick before had it fresh.
    def age_at_tick_start(row: dict) -> float:
        return float(row["offboard_age"]) - 0.02

    limit = LOSS_TIMEOUT_S + 1e-6
    assert age_at_tick_start(rows[switch - 1]) <= limit < age_at_tick_start(rows[switch]) <= limit + 0.02


# Suspended for less than the 0.5 s after which it re-anchors, the vehicle sprints through the time it missed
# (sitl_quad.pacing). With the setpoints it then read stamped at the late tick that read them, a 10 Hz stream was
# 0.5 s old at the end of each sprint: on the edge of OFFB_LOSS_T's default then (0.5 s), which a MAVSDK example's 20 Hz
# stream crossed in a loaded test run.
STALL_S = 0.48
STALLS = 6
TICK_S = 0.02  # the vehicle's outer loop (50 Hz): the flight log holds each setpoint's age at the end of a tick


def test_a_vehicle_process_the_machine_stalls_counts_setpoints_from_their_arrival(start_sitl, tmp_path):
    """A loaded machine can leave the vehicle's process unscheduled for a while (here SIGSTOP, 0.48 s): the
    setpoints a 10 Hz stream (PX4 asks for more than 2 Hz) sent meanwhile count from when they arrived, so no
    setpoint looks older than the stream's longest gap, and the vehicle stays in OFFBOARD through every stall."""
    log = tmp_path / "flight.csv"
    vehicle = start_sitl(speed=1.0, extra_args=("--log", str(log)))
    with offboard_flight(vehicle) as flight:
        gcs = flight.gcs
        stream = flight.take_off_into_offboard(period_s=0.1)
        modes, texts = set(), []
        for _ in range(STALLS):
            os.kill(vehicle.process.pid, signal.SIGSTOP)
            time.sleep(STALL_S)
            os.kill(vehicle.process.pid, signal.SIGCONT)
            gcs.send_heartbeat()
            heartbeats = 0
            while heartbeats < 2:  # what the vehicle did after the stall: two heartbeats (1 Hz) and all before
                msg = gcs.recv(["HEARTBEAT", "STATUSTEXT"], timeout=LOADED_BACKSTOP_S)
                assert msg is not None, "the vehicle fell silent"
                if msg.get_type() == "HEARTBEAT":
                    heartbeats += 1
                    modes.add(main_mode(msg))
                else:
                    texts.append(msg.text)
    rows = flight_log(vehicle, log)
    ages = [float(r["offboard_age"]) for r in rows if r["mode"] == "OFFBOARD"]
    # a setpoint's age: at most the stream's own longest gap (at 1x, wall = simulated), one tick for the log's
    # end-of-tick age and one for rounding down to the physics step
    assert len(ages) > STALLS * STALL_S / TICK_S and max(ages) <= stream.longest_gap_s + 2 * TICK_S
    if stream.longest_gap_s < FailsafeConfig().offboard_loss_timeout_s - 2 * TICK_S:  # never paused for OFFB_LOSS_T
        assert modes == {OFFBOARD} and not [t for t in texts if "setpoints lost" in t], texts


def _fly_lockstep_mission(tmp_path, tag: str, seed: int) -> list[list[str]]:
    """Vehicle + adrc_offboard in lockstep; a pymavlink GCS uploads a short mission, arms and starts it."""
    port = free_udp_port()
    log = tmp_path / f"{tag}.csv"
    vehicle, controller = start_lockstep_pair(port, seed, log)
    gcs = GroundStation(port)
    try:
        gcs.connect(timeout=60)
        # Wait until the controller answers ticks (its ESO estimates, forwarded by the vehicle, prove it), so
        # the vehicle is in lockstep before the mission starts; a mission started while the vehicle still
        # runs freely would hand over to the controller after a timing-dependent number of ticks.
        assert gcs.recv("DEBUG_VECT", timeout=60, condition=lambda m: m.get_srcComponent() == 191) is not None
        items = []
        for seq, (command, north, east, alt) in enumerate([(22, 0, 0, 5), (16, 30, 20, 5), (21, 30, 20, 0)]):
            lat, lon, _ = FRAME.from_ned(north, east, 0.0)
            items.append(
                mavlink.MAVLink_mission_item_int_message(
                    1,
                    1,
                    seq,
                    mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
                    command,
                    int(seq == 0),
                    1,
                    0.5,
                    1.0,
                    0,
                    math.nan,
                    round(float(lat) * 1e7),
                    round(float(lon) * 1e7),
                    alt,
                    0,
                )
            )
        assert gcs.upload_mission(items).type == mavlink.MAV_MISSION_ACCEPTED
        assert gcs.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == mavlink.MAV_RESULT_ACCEPTED
        assert gcs.command(mavlink.MAV_CMD_MISSION_START, 0, 0).result == mavlink.MAV_RESULT_ACCEPTED
        modes = set()
        deadline = time.monotonic() + 300  # lockstep runs at the machine's pace: a loaded one is slower
        while time.monotonic() < deadline:
            gcs.send_heartbeat()
            hb = gcs.recv("HEARTBEAT", timeout=2, condition=lambda m: m.get_srcComponent() == 1)
            if hb is None:
                continue
            modes.add(main_mode(hb))
            if OFFBOARD in modes and not hb.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED:
                break
        else:
            pytest.fail(f"mission did not finish; modes seen {modes}")
    finally:
        gcs.close()
        errors = [stop_reading_output(p, 20)[1] for p in (controller, vehicle)]
    assert all("Traceback" not in e for e in errors), errors
    with open(log) as f:
        return list(csv.reader(f))


def test_adrc_offboard_flies_a_mission_in_lockstep_deterministically(tmp_path):
    first = _fly_lockstep_mission(tmp_path, "first", seed=7)
    header = first[0]
    col = {name: header.index(name) for name in header}
    flown = [r for r in first[1:] if r[col["source"]] == "offboard"]
    assert len(flown) > 500  # most of the flight under the offboard ADRC
    errors = [
        math.dist([float(r[col[k]]) for k in ("x", "y", "z")], [float(r[col[k]]) for k in ("x_ref", "y_ref", "z_ref")])
        for r in flown
    ]
    airborne = [e for r, e in zip(flown, errors, strict=True) if float(r[col["z"]]) < -1.0]
    assert max(airborne) < 1.0
    second = _fly_lockstep_mission(tmp_path, "second", seed=7)

    # The same seed in lockstep gives the same flight, tick by tick from takeoff, although the ground
    # station's commands reached the vehicle at different ticks of the two runs.
    def flight(rows: list[list[str]]) -> list[list[str]]:
        return [r[1:] for r in rows[1:] if r[col["source"]] == "offboard"]  # every column but absolute time

    assert len(flight(first)) > 500
    assert flight(first) == flight(second)
