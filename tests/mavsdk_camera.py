"""A camera nobody here wrote: MAVSDK 4's CameraServer and FtpServer as component 100 (MAV_COMP_ID_CAMERA) of
system 1, taking real frames of the buoy world.

MAVSDK answers the camera protocol and MAVLink FTP itself: the HEARTBEAT (MAV_TYPE_CAMERA), CAMERA_INFORMATION,
IMAGE_START_CAPTURE's interval and count (its own timer calls the take-photo callback), CAMERA_IMAGE_CAPTURED
(stamped with its own clock) and the files of --root. This file only plays the payload behind it:
- where the vehicle is: the autopilot's GLOBAL_POSITION_INT, and where the camera looks: the GIMBAL_DEVICE_SET_ATTITUDE
  the autopilot sends its gimbal (earth frame; level along the heading until the first), both read off the link
  with MavlinkDirectServer;
- each photo MAVSDK asks for is rendered (sitl_quad.camera_render: the --world buoys, their lights as they really
  show), written to --root as IMG_<n>.jpg (n counts the camera's life: MAVSDK's index restarts with each
  sequence) and answered with respond_take_photo: the position, the camera's attitude quaternion and the file's
  mftp:// URL. The exposures keep the commanded interval on the camera's own clock (the sequence's k-th at
  start + k x interval, the interval read off the IMAGE_START_CAPTURE that came), however late MAVSDK's timer
  calls on a busy machine. MAVSDK stamps CAMERA_IMAGE_CAPTURED's time_boot_ms as it sends it, not at the
  exposure; so each is answered REPORT_LATENCY_S after its exposure (a camera's pipeline), or as soon after as
  its rendering allows where the machine is too busy, and shows the world as it is at that instant: frames and
  stamps agree;
- faults on purpose, for the buoy nearest the vehicle: `--missing ID` answers with the URL of a file it never
  writes, `--not-image ID` writes text where the JPEG should be.
Each capture is written to --records as a JSON line ({"capture": n, "buoy": ID, "file": NAME, "fault": ...}), for
the test (not to stdout, where MAVSDK's own log lines can cut into it).

    python tests/mavsdk_camera.py --connect udpout://127.0.0.1:PORT --root DIR --world WORLD.geojson --records FILE

It prints "ready" once serving and runs until SIGTERM.
"""

from __future__ import annotations

import argparse
import json
import math
import queue
import signal
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from mavsdk import ComponentType, Configuration, Mavsdk
from mavsdk.plugins.camera_server import CameraFeedback, CameraServer, CaptureInfo, Information, Position, Quaternion
from mavsdk.plugins.ftp_server import FtpServer
from mavsdk.plugins.mavlink_direct_server import MavlinkDirectServer, MavlinkMessage

from sitl_quad.camera import CameraSpec, Environment, WorldView, camera_pose
from sitl_quad.camera_render import encode_jpeg, render
from uavcore.buoy_world import load_world
from uavcore.geodesy import DEFAULT_HOME, LocalFrame
from uavcore.mavlink import mavlink
from uavcore.rotation import quat_from_euler

AUTOPILOT = (1, 1)
COMPONENT = mavlink.MAV_COMP_ID_CAMERA  # 100
START_CAPTURE = mavlink.MAV_CMD_IMAGE_START_CAPTURE
JPEG_QUALITY = 80
NOT_AN_IMAGE = b"this is no image: the card's file system lost the frame\n" * 8
REPORT_LATENCY_S = 0.5  # exposure to report: the slack rendering has on a busy machine
Report = tuple[float, CaptureInfo | None, dict]  # when it is due (time.monotonic()), what, the record written


@dataclass(frozen=True)
class Fix:
    """GLOBAL_POSITION_INT as the camera keeps it."""

    lat: float
    lon: float
    alt_m: float  # AMSL
    relative_alt_m: float
    heading_rad: float


class Payload:
    def __init__(self, args: argparse.Namespace) -> None:
        self.args = args
        self.root: Path = args.root
        self.spec = CameraSpec("MAVSDK", "CameraServer payload", 4.5, 6.17, 6.17 * args.height / args.width,
                               args.width, args.height)  # fmt: skip
        self.world = load_world(args.world)
        self.home = LocalFrame(*args.home)
        self.view = WorldView(self.world, self.home)
        self.buoys_ne = np.array([self.home.to_ned(*b.charted, args.home[2])[:2] for b in self.world.buoys])
        self.lock = threading.Lock()
        self.fix: Fix | None = None
        self.gimbal_q: tuple[float, float, float, float] | None = None  # earth frame; None: not commanded yet
        self.interval_s = 0.0  # the last IMAGE_START_CAPTURE's (0: a single shot)
        self.sequence_start_s = 0.0  # when MAVSDK asked for the sequence's first photo (index 0)
        self.count = 0
        self.jobs: queue.Queue[tuple[float, Fix | None, tuple[float, float, float, float] | None] | None]
        self.jobs = queue.Queue()
        self.reports: queue.Queue[Report | None] = queue.Queue()

        configuration = Configuration.create_with_component_type(ComponentType.CAMERA)  # 1/100
        self.mavsdk = Mavsdk(configuration)
        result = self.mavsdk.add_any_connection(args.connect)
        if int(result) != 0:
            raise SystemExit(f"MAVSDK cannot open {args.connect}: {result!r}")
        component = self.mavsdk.server_component()
        self.camera = CameraServer(component)
        self.ftp = FtpServer(component)
        self.ftp.set_root_dir(str(self.root))
        self.direct = MavlinkDirectServer(component)
        s = self.spec
        information = Information(vendor_name=s.vendor, model_name=s.model, firmware_version="4.1.0.0",
                                  focal_length_mm=s.focal_length_mm, horizontal_sensor_size_mm=s.sensor_width_mm,
                                  vertical_sensor_size_mm=s.sensor_height_mm, horizontal_resolution_px=s.width_px,
                                  vertical_resolution_px=s.height_px, lens_id=0, definition_file_version=0,
                                  definition_file_uri="", image_in_video_mode_supported=False,
                                  video_in_image_mode_supported=False)  # fmt: skip
        self.camera.set_information(information)
        self.direct.subscribe_message("GLOBAL_POSITION_INT", self._on_position)
        self.direct.subscribe_message("GIMBAL_DEVICE_SET_ATTITUDE", self._on_gimbal)
        self.direct.subscribe_message("COMMAND_LONG", self._on_command)
        self.camera.subscribe_take_photo(self._on_take_photo)
        self.threads = [threading.Thread(target=self._render, name="camera-render"),
                        threading.Thread(target=self._report, name="camera-report")]  # fmt: skip
        for thread in self.threads:
            thread.start()

    # ----- MAVSDK's callbacks (its threads): only note what came
    def _on_position(self, message: MavlinkMessage, _user_data) -> None:
        if (message.system_id, message.component_id) != AUTOPILOT:
            return
        f = json.loads(message.fields_json)
        fix = Fix(f["lat"] * 1e-7, f["lon"] * 1e-7, f["alt"] / 1000.0, f["relative_alt"] / 1000.0,
                  math.radians(f["hdg"] / 100.0) if f["hdg"] != 65535 else 0.0)  # fmt: skip
        with self.lock:
            self.fix = fix

    def _on_gimbal(self, message: MavlinkMessage, _user_data) -> None:
        if (message.system_id, message.component_id) != AUTOPILOT:
            return
        w, x, y, z = (float(c) for c in json.loads(message.fields_json)["q"])
        with self.lock:
            self.gimbal_q = (w, x, y, z)

    def _on_command(self, message: MavlinkMessage, _user_data) -> None:
        f = json.loads(message.fields_json)  # CameraServer answers it; only its interval is noted here
        if f["command"] == START_CAPTURE and f["target_component"] in (0, COMPONENT):
            with self.lock:
                self.interval_s = f["param2"] if f["param3"] != 1 else 0.0

    def _on_take_photo(self, index: int, _user_data) -> None:
        """MAVSDK asks for a photo: its exposure time and the pose now; rendered and answered by the worker."""
        with self.lock:
            now = time.monotonic()
            if index == 0 or self.interval_s == 0.0:
                self.sequence_start_s = now
            exposure_s = self.sequence_start_s + index * self.interval_s if self.interval_s else now
            self.jobs.put((exposure_s, self.fix, self.gimbal_q))

    # ----- the frames: rendered as soon as asked for (one thread), reported when due (another)
    def _render(self) -> None:
        render_s = 0.05  # how long a frame takes (a running estimate)
        report_s = 0.0
        while (job := self.jobs.get()) is not None:
            exposure_s, fix, gimbal_q = job
            started_s = time.monotonic()
            # the instant the report can be made, which MAVSDK stamps it with: the frame shows the world then
            report_s = max(exposure_s + REPORT_LATENCY_S, started_s + 2.0 * render_s, report_s + 0.01)
            if fix is None:  # no position heard yet: the camera cannot geotag
                self.reports.put((report_s, None, {}))
                continue
            self.reports.put(self._capture(report_s, fix, gimbal_q))
            render_s = 0.8 * render_s + 0.2 * (time.monotonic() - started_s)
        self.reports.put(None)

    def _capture(self, t_s: float, fix: Fix, gimbal_q: tuple[float, float, float, float] | None) -> Report:
        """The frame of instant t_s (time.monotonic(), MAVSDK's clock), to be reported at t_s."""
        q = gimbal_q or tuple(float(c) for c in quat_from_euler(0.0, 0.0, fix.heading_rad))
        north, east, down = self.home.to_ned(fix.lat, fix.lon, fix.alt_m)
        buoy = self.world.buoys[int(np.argmin(np.linalg.norm(self.buoys_ne - [north, east], axis=1)))]
        index, self.count = self.count, self.count + 1
        name = f"IMG_{index:06d}.jpg"
        fault = "missing" if buoy.id in self.args.missing else "not-image" if buoy.id in self.args.not_image else None
        if fault is None:
            pose = camera_pose((north, east, down), self.args.home[2], q)
            frame = render(pose, self.spec.intrinsics, self.view.scene(t_s, Environment()))
            self._write(name, encode_jpeg(frame, JPEG_QUALITY))
        elif fault == "not-image":
            self._write(name, NOT_AN_IMAGE)
        info = CaptureInfo(
            position=Position(fix.lat, fix.lon, fix.alt_m, fix.relative_alt_m),
            attitude_quaternion=Quaternion(*q),
            time_utc_us=round((time.time() + t_s - time.monotonic()) * 1e6),
            is_success=True,
            index=index,
            file_url=f"mftp://[;comp=100]/{name}",
        )
        return t_s, info, {"capture": index, "buoy": buoy.id, "file": name, "fault": fault, "t_s": t_s}

    def _report(self) -> None:
        while (report := self.reports.get()) is not None:
            due_s, info, record = report
            late_s = time.monotonic() - due_s  # > 0: rendering fell behind, MAVSDK's stamp is late by that much
            time.sleep(max(0.0, -late_s))
            if info is None:
                self.camera.respond_take_photo(CameraFeedback.FAILED, CaptureInfo())
                continue
            self.camera.respond_take_photo(CameraFeedback.OK, info)
            with self.args.records.open("a") as records:
                records.write(json.dumps(record | {"late_s": late_s}) + "\n")

    def _write(self, name: str, data: bytes) -> None:
        """Whole or not at all: the file appears under its name once written."""
        partial = self.root / f".{name}.part"
        partial.write_bytes(data)
        partial.replace(self.root / name)

    def close(self) -> None:
        self.jobs.put(None)
        for thread in self.threads:
            thread.join(timeout=10)
        self.mavsdk.destroy()


def parse_home(text: str) -> tuple[float, float, float]:
    lat, lon, alt = (float(part) for part in text.split(","))
    return lat, lon, alt


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--connect", required=True, help="MAVSDK connection URL, e.g. udpout://127.0.0.1:14550")
    parser.add_argument("--root", type=Path, required=True, help="the directory the frames are written to and served")
    parser.add_argument("--world", required=True, help="the buoy world's GeoJSON (uavcore.buoy_world)")
    parser.add_argument("--records", type=Path, required=True, help="JSON lines: one per capture reported")
    parser.add_argument("--home", type=parse_home, default=DEFAULT_HOME, help="lat,lon,alt (the sea at 0 m AMSL)")
    parser.add_argument("--width", type=int, default=384)  # a frame in about 20 ms (640 x 360: 80 ms)
    parser.add_argument("--height", type=int, default=216)
    parser.add_argument("--missing", action="append", default=[], help="a buoy whose frames are never written")
    parser.add_argument("--not-image", action="append", default=[], help="a buoy whose frames are text")
    args = parser.parse_args()
    payload = Payload(args)
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    signal.signal(signal.SIGINT, lambda *_: stop.set())
    print(f"MAVSDK {payload.mavsdk.version()} camera 1/100 on {args.connect}, serving {args.root}", flush=True)
    print("ready", flush=True)
    stop.wait()
    payload.close()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
