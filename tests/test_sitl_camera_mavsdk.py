"""A peer nobody here wrote: MAVSDK-Python 3.15 (its bundled mavsdk_server) finds and drives the vehicle's camera
(component 100) and gimbal (manager on the autopilot, device 1) with its Camera and Gimbal plugins, and downloads a
captured frame with its Ftp plugin.

tests/mavsdk3_camera_gimbal.py runs under .venv-mavsdk3 against the vehicle (real time: MAVSDK's waits are wall
clock) and prints one JSON line per step; the steps are judged here.
"""

from __future__ import annotations

import json
import math
import os
import subprocess

import pytest
from sitl_process import REPO

from bench.processes import free_tcp_port
from uavcore.geodesy import DEFAULT_HOME, LocalFrame

pytestmark = [pytest.mark.integration, pytest.mark.slow, pytest.mark.timeout(300)]

MAVSDK3_PYTHON = REPO / ".venv-mavsdk3" / "bin" / "python"
SCRIPT = REPO / "tests" / "mavsdk3_camera_gimbal.py"
ROI_NED = (30.0, 30.0, -10.0)  # 42 m away to the north-east, 10 m above the sea: pitch +13.3 deg, yaw 45 deg


def test_mavsdk3_camera_and_gimbal_plugins(start_sitl, tmp_path):
    assert MAVSDK3_PYTHON.exists(), f"{MAVSDK3_PYTHON} is missing: `make test` creates it (.venv-mavsdk3)"
    vehicle = start_sitl(speed=1.0, extra_args=("--camera", "--image-dir", str(tmp_path / "images")))
    lat, lon, alt = LocalFrame(*DEFAULT_HOME).from_ned(*ROI_NED)
    # the vehicle stands at home, its camera 0.1 m above the sea (sitl_quad.camera.camera_pose)
    pitch = math.degrees(math.atan2(-ROI_NED[2] - 0.1, math.hypot(*ROI_NED[:2])))
    args = [str(MAVSDK3_PYTHON), str(SCRIPT), str(vehicle.port), str(free_tcp_port())]
    downloads = tmp_path / "downloads"
    downloads.mkdir()
    args += [f"{lat:.8f}", f"{lon:.8f}", f"{alt:.3f}", f"{pitch:.3f}", "45", str(downloads)]
    run = subprocess.run(
        args, cwd=REPO, capture_output=True, text=True, timeout=240, env={**os.environ, "PYTHONUNBUFFERED": "1"}
    )
    steps: dict[str, list[dict]] = {}
    for line in run.stdout.splitlines():
        if line.startswith("{"):
            record = json.loads(line)
            steps.setdefault(record["step"], []).append(record)
    describe = f"exit {run.returncode}\nstdout:\n{run.stdout}\nstderr:\n{run.stderr[-3000:]}"
    assert run.returncode == 0, describe

    def ok(name: str) -> dict:
        assert name in steps and steps[name][-1]["ok"], f"step {name!r} failed\n{describe}"
        return steps[name][-1]

    for name in ("connected", "camera_list", "take_photo", "wait single capture", "start_photo_interval",
                 "wait interval captures", "stop_photo_interval", "gimbal_list", "take_control", "set_angles",
                 "attitude after set_angles", "set_roi_location", "attitude after roi", "release_control"):  # fmt: skip
        ok(name)
    assert ok("camera_component")["value"] == 100
    captures = [s["value"] for s in steps["capture_info"]]
    indices = [c["index"] for c in captures]
    assert indices == list(range(len(indices))) and len(indices) >= 5, describe
    assert all(c["ok"] and c["url"] == f"mftp://[;comp=100]/IMG_{c['index']:06d}.jpg" for c in captures)
    assert all((tmp_path / "images" / f"IMG_{i:06d}.jpg").exists() for i in indices)
    # MAVSDK's Ftp plugin fetched the first capture's file from the camera's component, byte for byte
    ok("ftp download")
    first = "IMG_000000.jpg"
    assert (downloads / first).read_bytes() == (tmp_path / "images" / first).read_bytes()
    assert "PRIMARY" in ok("control_status")["value"]
    # after release_control the manager denies angles: MAVSDK reports it as an error
    refused = steps["set_angles after release"][-1]
    assert not refused["ok"] and "GimbalError" in refused["error"], describe
