"""How fast the vehicle runs: physics alone, the full lockstep loop over UDP, and tick jitter at --speed 1.

    .venv/bin/python -m bench.sitl          # prints a table, writes bench/results/sitl.json

Rows:
- physics alone (RK4 at 1 kHz with wind, Dryden turbulence, the paper's D terms and sensor noise), and the
  vehicle's whole onboard loop (250 Hz PID attitude + mixer + physics): simulated s per wall s;
- the full loop in --lockstep with an outer-loop controller in a second process at 50 Hz, flying a mission:
  a minimal pymavlink controller (a PD hover law in adrc_offboard's node) and the real ADRC controller;
- --speed 1: the jitter of the 50 Hz state ticks as an onboard peer receives them (p50/p99 of the deviation
  of each interval from 20 ms).
Targets (issue: sitl_quad): physics >= 40x, lockstep full loop >= 20x, jitter p99 <= 2 ms.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from bench.processes import stop_process
from bench.sitl_physics import physics_alone, vehicle_loop
from tests.sitl_process import GroundStation, SitlProcess
from uavcore.mavlink import mavlink

REPO = Path(__file__).resolve().parent.parent
RESULTS = REPO / "bench" / "results"
LOCKSTEP_SIM_S = 60.0
JITTER_SIM_S = 12.0
HOVER_CONTROLLER = ("-m", "bench.hover_offboard")


def lockstep_full_loop(
    controller: list[str],
    vehicle_args: tuple[str, ...] = (),
    after_takeoff: Callable[[GroundStation], None] | None = None,
) -> dict:
    """Vehicle --lockstep (with `vehicle_args`) + a controller process; a GCS arms and takes off (then runs
    `after_takeoff`, e.g. starts a camera's capture); simulated s per wall s."""
    vehicle = SitlProcess()
    vehicle.args = [sys.executable, "-m", "sitl_quad", "--port", str(vehicle.port), "--lockstep", *vehicle_args]
    vehicle.start()
    process = subprocess.Popen(
        [sys.executable, *controller, "--connect", f"udpout:127.0.0.1:{vehicle.port}", "--no-engage"],
        cwd=REPO,
        stdout=subprocess.DEVNULL,
    )
    gcs = GroundStation(vehicle.port)
    try:
        gcs.connect(timeout=60)
        gcs.recv("HEARTBEAT", timeout=60, condition=lambda m: m.get_srcComponent() == 191)
        gcs.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1)
        gcs.command(mavlink.MAV_CMD_NAV_TAKEOFF)
        if after_takeoff is not None:
            after_takeoff(gcs)
        first = gcs.recv("LOCAL_POSITION_NED", timeout=10)
        wall0, sim0 = time.monotonic(), first.time_boot_ms / 1000
        last = first
        while last.time_boot_ms / 1000 - sim0 < LOCKSTEP_SIM_S:
            gcs.send_heartbeat()
            msg = gcs.recv("LOCAL_POSITION_NED", timeout=10)
            if msg is None:
                raise RuntimeError("vehicle stopped sending state")
            last = msg
        wall = time.monotonic() - wall0
        sim = last.time_boot_ms / 1000 - sim0
        return {"sim_s": sim, "wall_s": wall, "real_time_factor": sim / wall}
    finally:
        gcs.close()
        stop_process(process, 10)
        vehicle.stop()
        vehicle.cleanup()


def tick_jitter_at_speed_1() -> dict:
    """--speed 1 with an onboard peer attached: how late each 50 Hz tick starts (the vehicle's own count,
    --stats) and how evenly the per-tick state reaches the peer (its arrival intervals against 20 ms)."""
    stats_path = Path(tempfile.mkstemp(suffix=".json")[1])
    vehicle = SitlProcess(speed=1.0, extra_args=("--duration", f"{JITTER_SIM_S:g}", "--stats", str(stats_path)))
    vehicle.start()
    peer = GroundStation(vehicle.port, sysid=1, compid=mavlink.MAV_COMP_ID_ONBOARD_COMPUTER)
    try:
        peer.connect(timeout=60)
        arrivals: list[float] = []
        next_heartbeat = 0.0
        while vehicle.alive():
            if time.monotonic() > next_heartbeat:
                peer.send_heartbeat()
                next_heartbeat = time.monotonic() + 1.0
            msg = peer.conn.recv_match(type="LOCAL_POSITION_NED", blocking=True, timeout=0.5)
            if msg is not None:
                arrivals.append(time.monotonic())
        vehicle.process.wait(30)
        lateness = json.loads(stats_path.read_text())["tick_lateness_ms"]
        intervals = np.diff(np.array(arrivals[50:]))  # the first second includes the peer's discovery
        deviation_ms = np.abs(intervals - 0.02) * 1000
        return {
            "tick_lateness_ms": lateness,
            "ticks_received": len(intervals),
            "arrival_deviation_p50_ms": float(np.percentile(deviation_ms, 50)),
            "arrival_deviation_p99_ms": float(np.percentile(deviation_ms, 99)),
        }
    finally:
        peer.close()
        vehicle.cleanup()
        stats_path.unlink(missing_ok=True)


def main() -> None:
    result = {"machine_load_average_1_5_15": list(os.getloadavg())}
    physics = physics_alone(20)
    loop = vehicle_loop()
    minimal = lockstep_full_loop(list(HOVER_CONTROLLER))
    adrc = lockstep_full_loop(["-m", "adrc_offboard"])
    jitter = tick_jitter_at_speed_1()
    result["physics_alone"] = physics
    result["vehicle_onboard_loop"] = loop
    result["lockstep_minimal_controller"] = minimal
    result["lockstep_adrc_offboard"] = adrc
    result["speed_1_tick_jitter"] = jitter
    result["targets"] = {"physics_real_time_factor": 40.0, "lockstep_real_time_factor": 20.0, "jitter_p99_ms": 2.0}
    rows = [
        ("physics alone (RK4 1 kHz, wind, turbulence, D, noise)", f"{physics['real_time_factor']:.0f}x", ">= 40x"),
        ("vehicle onboard loop (PID 250 Hz + mixer + physics)", f"{loop['real_time_factor']:.0f}x", ""),
        ("lockstep, minimal pymavlink controller, 50 Hz", f"{minimal['real_time_factor']:.1f}x", ">= 20x"),
        ("lockstep, adrc_offboard (ADRC), 50 Hz", f"{adrc['real_time_factor']:.1f}x", ""),
        (
            "--speed 1 outer-loop tick lateness p50 / p99",
            f"{jitter['tick_lateness_ms']['p50']:.2f} / {jitter['tick_lateness_ms']['p99']:.2f} ms",
            "p99 <= 2 ms",
        ),
        (
            "--speed 1 state arrival at the peer, |interval - 20 ms| p50 / p99",
            f"{jitter['arrival_deviation_p50_ms']:.2f} / {jitter['arrival_deviation_p99_ms']:.2f} ms",
            "",
        ),
    ]
    width = max(len(r[0]) for r in rows)
    print(f"{'case':{width}}  {'measured':>18}  target")
    for name, value, target in rows:
        print(f"{name:{width}}  {value:>18}  {target}")
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / "sitl.json").write_text(json.dumps(result, indent=2) + "\n")
    print(f"\nwrote {RESULTS / 'sitl.json'}")


if __name__ == "__main__":
    main()
