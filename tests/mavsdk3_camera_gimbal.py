"""MAVSDK-Python 3 (.venv-mavsdk3) drives the vehicle's camera and gimbal: run by tests/test_sitl_camera_mavsdk.py.

    .venv-mavsdk3/bin/python tests/mavsdk3_camera_gimbal.py VEHICLE_PORT GRPC_PORT ROI_LAT ROI_LON ROI_ALT PITCH YAW DIR

Each step prints one JSON line {"step", "ok", "value" or "error"}; the test judges them. The calls are those of
MAVSDK's Camera, Gimbal and Ftp plugins a ground station makes (camera selected by component id, gimbal by id;
the first capture's file downloaded into DIR).
"""

from __future__ import annotations

import asyncio
import json
import sys
import time

from mavsdk import System
from mavsdk.gimbal import ControlMode, GimbalMode, SendMode

STEP_TIMEOUT_S = 30.0


def report(step: str, ok: bool, **detail) -> None:
    print(json.dumps({"step": step, "ok": ok, **detail}, default=str), flush=True)


async def step(name: str, awaitable, timeout: float = STEP_TIMEOUT_S):
    try:
        async with asyncio.timeout(timeout):
            value = await awaitable
    except Exception as exc:  # the test reads the exact error
        report(name, False, error=f"{type(exc).__name__}: {exc}")
        return None
    report(name, True, value=value)
    return value


async def first(stream, condition):
    async for value in stream:
        if condition(value):
            return value
    return None


async def settled_attitude(drone, gimbal_id: int, pitch: float, yaw: float, tolerance: float = 1.0):
    """The gimbal's attitude once its forward-frame pitch and yaw are within tolerance (deg) of the target."""
    deadline = time.monotonic() + STEP_TIMEOUT_S
    while time.monotonic() < deadline:
        attitude = await drone.gimbal.get_attitude(gimbal_id)
        euler = attitude.euler_angle_forward
        if abs(euler.pitch_deg - pitch) < tolerance and abs(euler.yaw_deg - yaw) < tolerance:
            return euler
        await asyncio.sleep(0.2)
    raise TimeoutError(f"attitude {euler} never reached pitch {pitch} yaw {yaw}")


async def run(
    vehicle_port: int,
    grpc_port: int,
    roi: tuple[float, float, float],
    roi_angles: tuple[float, float],
    download_dir: str,
):
    drone = System(port=grpc_port)
    await drone.connect(system_address=f"udpout://127.0.0.1:{vehicle_port}")
    await step("connected", first(drone.core.connection_state(), lambda s: s.is_connected))

    # ----- camera
    cameras = await step("camera_list", first(drone.camera.camera_list(), lambda c: len(c.cameras) > 0))
    component = cameras.cameras[0].component_id if cameras else 100
    report("camera_component", True, value=component)
    captures: list = []

    async def collect():
        async for info in drone.camera.capture_info():
            captures.append(info)
            report("capture_info", True, value={"index": info.index, "ok": info.is_success, "url": info.file_url,
                                                 "lat": info.position.latitude_deg,
                                                 "rel_alt": info.position.relative_altitude_m})  # fmt: skip

    collector = asyncio.ensure_future(collect())
    await asyncio.sleep(0.5)  # the subscription is in place before the first capture
    await step("take_photo", drone.camera.take_photo(component))
    await step("wait single capture", first_capture(captures, 1))
    await step("start_photo_interval", drone.camera.start_photo_interval(component, 0.5))
    await step("wait interval captures", first_capture(captures, 5))
    await step("stop_photo_interval", drone.camera.stop_photo_interval(component))
    collector.cancel()

    # ----- the first capture's file, by MAVSDK's Ftp plugin from the camera's component (the URL's path)
    if captures:
        await step("ftp set_target_compid", drone.ftp.set_target_compid(component))
        path = captures[0].file_url.split("]", 1)[-1]  # mftp://[;comp=100]/IMG_000000.jpg -> /IMG_000000.jpg
        await step("ftp download", last(drone.ftp.download(path, download_dir, False)))

    # ----- gimbal
    gimbals = await step("gimbal_list", first(drone.gimbal.gimbal_list(), lambda g: len(g.gimbals) > 0))
    gimbal_id = gimbals.gimbals[0].gimbal_id if gimbals else 1
    report("gimbal_item", True, value=gimbals.gimbals[0] if gimbals else None)
    await step("take_control", drone.gimbal.take_control(gimbal_id, ControlMode.PRIMARY))
    await step("control_status", drone.gimbal.get_control_status(gimbal_id))
    await step("set_angles", drone.gimbal.set_angles(gimbal_id, 0, -45, 30, GimbalMode.YAW_FOLLOW, SendMode.ONCE))
    await step("attitude after set_angles", settled_attitude(drone, gimbal_id, -45, 30))
    await step("set_roi_location", drone.gimbal.set_roi_location(gimbal_id, *roi))
    await step("attitude after roi", settled_attitude(drone, gimbal_id, *roi_angles))
    await step("release_control", drone.gimbal.release_control(gimbal_id))
    await step("set_angles after release", drone.gimbal.set_angles(gimbal_id, 0, -20, 0, GimbalMode.YAW_FOLLOW,
                                                                   SendMode.ONCE), 10)  # fmt: skip


async def last(stream):
    """The stream's last value (a download's progress: its end)."""
    value = None
    async for value in stream:  # noqa: B007  (the last one is kept)
        pass
    return value


async def first_capture(captures: list, count: int) -> int:
    while len(captures) < count:
        await asyncio.sleep(0.1)
    return len(captures)


if __name__ == "__main__":
    port, grpc, lat, lon, alt, pitch, yaw, downloads = sys.argv[1:9]
    asyncio.run(run(int(port), int(grpc), (float(lat), float(lon), float(alt)), (float(pitch), float(yaw)), downloads))
