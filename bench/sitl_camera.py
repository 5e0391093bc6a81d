"""What the camera costs the vehicle: frames per second and the lockstep speed with the camera capturing at 10 Hz.

    .venv/bin/python -m bench.sitl_camera      # prints a table, writes bench/results/sitl_camera.json

Rows, each the vehicle as a process with a world of a few buoys ahead of home and a GCS that arms, takes off and
(with the camera) starts an endless 10 Hz capture (MAV_CMD_IMAGE_START_CAPTURE to component 100):
- lockstep, an outer-loop controller in a second process (bench.hover_offboard) at 50 Hz: simulated s per wall s
  without a camera, with a camera not capturing, and capturing at 10 Hz of simulated time; images written per
  wall second; the vehicle's own wall time per frame (render + JPEG + write, --stats): in lockstep each frame is
  made inside the loop at its simulated instant, so the loop waits for it;
- --speed 1, capturing at 10 Hz: how late the 50 Hz ticks start (--stats), while a worker process makes the frames
  (sitl_quad.mavlink.camera_frames), and how long after its tick each CAMERA_IMAGE_CAPTURED went out (the frame's
  making, and the wait for the loop's next poll).
"""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path

from bench.sitl import HOVER_CONTROLLER, lockstep_full_loop
from tests.sitl_process import GroundStation, SitlProcess
from uavcore.buoy_world import World
from uavcore.geodesy import DEFAULT_HOME, LocalFrame
from uavcore.mavlink import mavlink

REPO = Path(__file__).resolve().parent.parent
RESULTS = REPO / "bench" / "results" / "sitl_camera.json"
PACED_SIM_S = 15.0
CAPTURE_HZ = 10.0
CAMERA = mavlink.MAV_COMP_ID_CAMERA


def write_world(path: Path) -> Path:
    """Eight buoys 30-100 m north of home, alternately 10 m west and east."""
    frame = LocalFrame(*DEFAULT_HOME)
    positions = [frame.from_ned(30.0 + 10 * k, 10.0 * (-1) ** k, 0.0)[:2] for k in range(8)]
    world = World.default(positions, [f"B{k}" for k in range(8)])
    path.write_text(json.dumps(world.to_geojson()))
    return path


def start_capturing(gcs: GroundStation) -> None:
    gcs.mav.command_long_send(1, CAMERA, mavlink.MAV_CMD_IMAGE_START_CAPTURE, 0, 0, 1 / CAPTURE_HZ, 0, 0, 0, 0, 0)
    ack = gcs.recv("COMMAND_ACK", timeout=10, condition=lambda m: m.get_srcComponent() == CAMERA)
    if ack is None or ack.result != mavlink.MAV_RESULT_ACCEPTED:
        raise RuntimeError(f"the camera did not start capturing: {ack}")


def camera_args(workdir: Path, camera: bool) -> list[str]:
    if not camera:
        return []
    return ["--world", str(write_world(workdir / "world.geojson")), "--image-dir", str(workdir / "images")]


def lockstep(camera: bool, capture: bool) -> dict:
    """Vehicle --lockstep + the hover controller (bench.sitl's loop); simulated s per wall s once airborne."""
    workdir = Path(tempfile.mkdtemp(prefix="bench_camera_"))
    stats = workdir / "stats.json"
    vehicle_args = ("--stats", str(stats), *camera_args(workdir, camera))
    run = lockstep_full_loop(list(HOVER_CONTROLLER), vehicle_args, start_capturing if capture else None)
    result = {"camera": camera, "capture_hz": CAPTURE_HZ if capture else 0.0, **run}
    if capture:
        result["images_per_wall_s"] = CAPTURE_HZ * run["real_time_factor"]
        result["images_written"] = len(list((workdir / "images").glob("IMG_*.jpg")))
        result["frame_ms"] = json.loads(stats.read_text())["camera"]["frame_ms"]
    return result


def paced_tick_lateness() -> dict:
    """--speed 1, capturing at 10 Hz: the vehicle's tick lateness (ms) and frame cost."""
    workdir = Path(tempfile.mkdtemp(prefix="bench_camera_"))
    stats = workdir / "stats.json"
    extra = ("--duration", f"{PACED_SIM_S:g}", "--stats", str(stats), *camera_args(workdir, True))
    vehicle = SitlProcess(speed=1.0, extra_args=extra)
    vehicle.start()
    gcs = GroundStation(vehicle.port)
    try:
        gcs.connect(timeout=60)
        start_capturing(gcs)
        while vehicle.alive():
            gcs.send_heartbeat()
            gcs.recv("HEARTBEAT", timeout=1.0)
        vehicle.process.wait(30)
    finally:
        gcs.close()
        vehicle.cleanup()
    counters = json.loads(stats.read_text())
    return {"tick_lateness_ms": counters["tick_lateness_ms"], "camera": counters["camera"]}


def main() -> None:
    rows = {
        "lockstep_no_camera": lockstep(camera=False, capture=False),
        "lockstep_camera_idle": lockstep(camera=True, capture=False),
        "lockstep_camera_10hz": lockstep(camera=True, capture=True),
    }
    paced = paced_tick_lateness()
    print(f"{'lockstep run':24} {'sim s':>7} {'wall s':>7} {'x real':>7} {'img/s':>7} {'ms/frame p50':>13}")
    for name, r in rows.items():
        frame = r.get("frame_ms") or {}
        print(
            f"{name:24} {r['sim_s']:7.1f} {r['wall_s']:7.1f} {r['real_time_factor']:7.2f} "
            f"{r.get('images_per_wall_s', 0):7.1f} {frame.get('p50', float('nan')):13.1f}"
        )
    lateness, camera = paced["tick_lateness_ms"], paced["camera"]
    print(
        f"--speed 1, 10 Hz capture: tick lateness p50 {lateness['p50']:.2f} ms, p99 {lateness['p99']:.2f} ms, "
        f"max {lateness['max']:.1f} ms; {camera['images']} images made in the {camera['frames_made']}, frame p50 "
        f"{camera['frame_ms']['p50']:.1f} ms, reported p50 {camera['report_after_ms']['p50']:.0f} ms "
        f"(max {camera['report_after_ms']['max']:.0f} ms) after its tick"
    )
    result = {"machine_load_average_1_5_15": list(os.getloadavg()), **rows, "speed_1_capture_10hz": paced}
    RESULTS.write_text(json.dumps(result, indent=2) + "\n")
    print(f"\nwrote {RESULTS}")


if __name__ == "__main__":
    main()
