"""The camera as its own MAVLink component (MAV_COMP_ID_CAMERA, 100) of the vehicle's system, camera protocol v2.

What it says and answers (MAVSDK 3's Camera plugin needs its HEARTBEAT and CAMERA_INFORMATION; findings of the
MAVSDK 4 CameraServer probe copied where MAVLink leaves a choice):
- HEARTBEAT at 1 Hz of wall clock (type MAV_TYPE_CAMERA, autopilot MAV_AUTOPILOT_INVALID) and
  CAMERA_CAPTURE_STATUS with it, from compid 100. A ground station finds cameras by that heartbeat's type.
- MAV_CMD_REQUEST_MESSAGE for CAMERA_INFORMATION, CAMERA_SETTINGS, CAMERA_CAPTURE_STATUS, STORAGE_INFORMATION and
  CAMERA_IMAGE_CAPTURED (p2 = the image index: a lost capture report can be asked for again), and the legacy
  MAV_CMD_REQUEST_CAMERA_* commands MAVSDK falls back to. Anything else addressed to the camera: UNSUPPORTED.
- MAV_CMD_IMAGE_START_CAPTURE (p1 camera id 0 or 100, p2 interval s, p3 count, 0 = until stopped, p4 sequence of
  a single shot): ACCEPTED once the capture is scheduled; DENIED for a negative count, an interval shorter than
  one tick with more than one image, or another camera id; TEMPORARILY_REJECTED while an interval sequence runs
  (stop it first); a single shot whose sequence number > 0 repeats the last one is a retry: ACCEPTED again,
  not captured twice (MAVSDK 3 always sends sequence 0, which is never taken for a retry).
  MAV_CMD_IMAGE_STOP_CAPTURE: ACCEPTED, whether or not a sequence ran.
- Each capture happens at its simulated instant (the first tick at or after it), is rendered from the true pose of
  the vehicle and the gimbal at that instant, written as JPEG to the image directory as IMG_<index>.jpg, and
  reported by CAMERA_IMAGE_CAPTURED once the file is written (a client downloads it on receipt): time_boot_ms and
  time_utc = the capture's instant, geotag = the vehicle's estimate then (what a real autopilot would tag with),
  q = the camera's attitude (FRD -> NED), file_url mftp://[;comp=100]/IMG_<index>.jpg (the MAVLink FTP URL of the
  file when the image directory is what the camera component serves), capture_result 0 if the file could not be
  written. Where the frame is made (sitl_quad.mavlink.camera_frames): in lockstep inside the loop, before the
  vehicle flies on, so the report follows its tick as exactly as the tick itself; paced, in a worker process, so
  the loop's ticks stay on time, and the report goes out when the loop next polls after the file is written
  (CAMERA_CAPTURE_STATUS's image_count counts reported images). Reports keep the images' order.
Commands addressed to component 0 reach the camera only if they are camera commands (the autopilot answers the
rest): PX4 re-emits a mission's camera items as broadcast commands, and here the navigator's camera items are
handed over directly (`run_mission_item`).
"""

from __future__ import annotations

import logging
import math
import shutil
import time
from collections import deque
from dataclasses import dataclass
from pathlib import Path

from sitl_quad.camera import (
    DEFAULT_SPEC,
    CameraSpec,
    CaptureSchedule,
    Environment,
    WorldView,
    camera_pose,
    image_name,
)
from sitl_quad.camera_render import CameraPose
from sitl_quad.gimbal import Gimbal
from sitl_quad.mavlink.camera_frames import FrameJob, FrameResult, FrameWorker, WorkerGoneError, write_frame
from sitl_quad.vehicle import CommandResult, Vehicle
from uavcore.buoy_world import World
from uavcore.mavlink import mavlink
from uavcore.mission import MissionItem
from uavcore.rotation import euler_from_quat

log = logging.getLogger(__name__)

CAMERA_COMPID = mavlink.MAV_COMP_ID_CAMERA  # 100
HEARTBEAT_PERIOD_S = 1.0
FIRMWARE_VERSION = 1 | (0 << 8) | (0 << 16)  # 1.0.0: major in the low byte (CAMERA_INFORMATION)
CAPABILITIES = mavlink.CAMERA_CAP_FLAGS_CAPTURE_IMAGE
JPEG_QUALITY = 85
CAMERA_COMMANDS = frozenset(
    {
        mavlink.MAV_CMD_IMAGE_START_CAPTURE,
        mavlink.MAV_CMD_IMAGE_STOP_CAPTURE,
        mavlink.MAV_CMD_REQUEST_CAMERA_INFORMATION,
        mavlink.MAV_CMD_REQUEST_CAMERA_SETTINGS,
        mavlink.MAV_CMD_REQUEST_STORAGE_INFORMATION,
        mavlink.MAV_CMD_REQUEST_CAMERA_CAPTURE_STATUS,
    }
)
# the legacy request commands, by the message each asks for
LEGACY_REQUESTS = {
    mavlink.MAV_CMD_REQUEST_CAMERA_INFORMATION: mavlink.MAVLINK_MSG_ID_CAMERA_INFORMATION,
    mavlink.MAV_CMD_REQUEST_CAMERA_SETTINGS: mavlink.MAVLINK_MSG_ID_CAMERA_SETTINGS,
    mavlink.MAV_CMD_REQUEST_STORAGE_INFORMATION: mavlink.MAVLINK_MSG_ID_STORAGE_INFORMATION,
    mavlink.MAV_CMD_REQUEST_CAMERA_CAPTURE_STATUS: mavlink.MAVLINK_MSG_ID_CAMERA_CAPTURE_STATUS,
}


def _uint8_name(text: str) -> list[int]:
    """CAMERA_INFORMATION's vendor_name / model_name: uint8_t[32], not char[32]."""
    return list(text.encode()[:32].ljust(32, b"\0"))


def file_url(name: str) -> str:
    return f"mftp://[;comp={CAMERA_COMPID}]/{name}"


@dataclass(frozen=True)
class _Capture:
    """A capture whose frame is being made: its report's fields, all taken at its instant."""

    index: int
    time_boot_ms: int
    time_utc_us: int
    lat_e7: int
    lon_e7: int
    alt_mm: int
    relative_alt_mm: int
    q: tuple[float, float, float, float]
    taken_at: float  # wall clock (time.monotonic)


class CameraComponent:
    def __init__(
        self,
        vehicle: Vehicle,
        link,
        gimbal: Gimbal,
        image_dir: Path,
        world: World | None = None,
        environment: Environment | None = None,
        spec: CameraSpec = DEFAULT_SPEC,
        boot_unix_us: int | None = None,
        frames_in_loop: bool = True,
    ) -> None:
        """boot_unix_us: the vehicle's UTC at boot (sitl_quad.mavlink.telemetry's), so time_utc agrees with
        SYSTEM_TIME; the image directory must exist. frames_in_loop: each frame made before the loop flies on
        (lockstep), else in a worker process (module docstring)."""
        self.vehicle = vehicle
        self.link = link
        link.add_component(CAMERA_COMPID)
        self.gimbal = gimbal
        self.image_dir = image_dir
        self.spec = spec
        self.intrinsics = spec.intrinsics
        self.view = WorldView(world or World(()), vehicle.frame, sea_seed=vehicle.seed)
        self.current = environment or Environment()  # the water's current; the wind is the vehicle's
        self.schedule = CaptureSchedule()
        self.captured: list = []  # CAMERA_IMAGE_CAPTURED by index, for REQUEST_MESSAGE(263, index)
        self.last_sequence: int | None = None
        self.render_s: list[float] = []  # wall time spent per frame (render + JPEG + write), for --stats
        self.report_s: list[float] = []  # wall time from each capture's tick to its report, for --stats
        self._next_heartbeat = 0.0
        self.boot_unix_us = int(time.time() * 1e6) if boot_unix_us is None else boot_unix_us
        self._in_hand: deque[_Capture] = deque()  # captures handed to the worker, oldest first
        self.frames_in_loop = frames_in_loop
        self.worker: FrameWorker | None = None
        self.worker_lost = False
        if not frames_in_loop:
            self.worker = FrameWorker(warm_up=self._job(0, vehicle.t))

    # ----- sending as the camera
    def send(self, msg, peer=None) -> None:
        self.link.send(msg, peer, compid=CAMERA_COMPID)

    def poll(self, now: float) -> None:
        """Wall-clock timers: the heartbeat and a capture status with it; the reports of frames finished."""
        self.report_finished()
        if now >= self._next_heartbeat:
            self._next_heartbeat = max(self._next_heartbeat + HEARTBEAT_PERIOD_S, now)
            heartbeat = mavlink.MAVLink_heartbeat_message(
                mavlink.MAV_TYPE_CAMERA, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, mavlink.MAV_STATE_ACTIVE, 3
            )
            self.send(heartbeat)
            self.send(self.capture_status())

    # ----- commands addressed to the camera
    def handles(self, msg) -> bool:
        """Whether this message is the camera's to answer: addressed to it, or a camera command to everyone."""
        if msg.get_type() not in ("COMMAND_LONG", "COMMAND_INT"):
            return False
        if msg.target_component == CAMERA_COMPID:
            return True
        return msg.target_component == 0 and msg.command in CAMERA_COMMANDS

    def command(self, peer, msg) -> None:
        p = (msg.param1, msg.param2, msg.param3, msg.param4)
        if msg.command == mavlink.MAV_CMD_IMAGE_START_CAPTURE:
            result = self.start_capture(*p)
        elif msg.command == mavlink.MAV_CMD_IMAGE_STOP_CAPTURE:
            result = self.stop_capture()
        elif msg.command == mavlink.MAV_CMD_REQUEST_MESSAGE:
            result = self.request_message(p[0], p[1])
        elif msg.command in LEGACY_REQUESTS:
            result = self.request_message(LEGACY_REQUESTS[msg.command], math.nan)
        else:
            result = CommandResult.UNSUPPORTED
        ack = mavlink.MAVLink_command_ack_message(
            msg.command, int(result), 0, 0, msg.get_srcSystem(), msg.get_srcComponent()
        )
        self.send(ack, peer)

    def start_capture(self, camera_id: float, interval_s: float, count: float, sequence: float) -> CommandResult:
        if math.isfinite(camera_id) and int(camera_id) not in (0, CAMERA_COMPID):
            return CommandResult.DENIED
        images = int(count) if math.isfinite(count) else 1
        interval = interval_s if math.isfinite(interval_s) else 0.0
        if images < 0 or (images != 1 and interval < self.vehicle.outer_dt - 1e-9):
            return CommandResult.DENIED
        if self.schedule.interval_running:
            return CommandResult.TEMPORARILY_REJECTED  # busy, as MAVSDK's camera server answers BUSY
        if images == 1 and math.isfinite(sequence) and sequence > 0:
            if int(sequence) == self.last_sequence:
                return CommandResult.ACCEPTED  # a retry of the shot already taken (the spec's purpose of p4)
            self.last_sequence = int(sequence)
        self.schedule.start(self.vehicle.t, interval, images)
        return CommandResult.ACCEPTED

    def stop_capture(self) -> CommandResult:
        self.schedule.stop()
        self.send(self.capture_status())
        return CommandResult.ACCEPTED

    def request_message(self, msg_id: float, param2: float) -> CommandResult:
        builders = {
            mavlink.MAVLINK_MSG_ID_CAMERA_INFORMATION: self.camera_information,
            mavlink.MAVLINK_MSG_ID_CAMERA_SETTINGS: self.camera_settings,
            mavlink.MAVLINK_MSG_ID_CAMERA_CAPTURE_STATUS: self.capture_status,
            mavlink.MAVLINK_MSG_ID_STORAGE_INFORMATION: self.storage_information,
        }
        if msg_id == mavlink.MAVLINK_MSG_ID_CAMERA_IMAGE_CAPTURED:
            index = int(param2) if math.isfinite(param2) else -1
            if not 0 <= index < len(self.captured):
                return CommandResult.DENIED
            self.send(self.captured[index])
            return CommandResult.ACCEPTED
        builder = builders.get(int(msg_id)) if math.isfinite(msg_id) else None
        if builder is None:
            return CommandResult.DENIED  # as the MAVSDK camera server answers an unknown request
        self.send(builder())
        return CommandResult.ACCEPTED

    # ----- mission items (handed over by the navigator)
    def run_mission_item(self, item: MissionItem) -> bool:
        """IMAGE_START_CAPTURE / IMAGE_STOP_CAPTURE items; False if the item is not the camera's."""
        if item.command == mavlink.MAV_CMD_IMAGE_START_CAPTURE:
            self.start_capture(item.param1, item.param2, item.param3, item.param4)
        elif item.command == mavlink.MAV_CMD_IMAGE_STOP_CAPTURE:
            self.stop_capture()
        else:
            return False
        return True

    # ----- capturing, on simulated time
    def capture_due(self) -> None:
        """Called after each tick: take the image due now, if any (in the loop: made and reported at once)."""
        index = self.schedule.take_due(self.vehicle.t)
        if index is None:
            return
        capture = self._describe(index)
        job = self._job(index, self.vehicle.t)
        if self.worker is not None:
            try:
                self.worker.submit(job)
                self._in_hand.append(capture)
                return
            except WorkerGoneError as exc:
                self._lose_worker(exc)
        self._report(capture, write_frame(job))

    def report_finished(self, timeout: float = 0.0) -> None:
        """Report the frames the worker has written (polled by the loop)."""
        if self.worker is None or not self._in_hand:
            return
        try:
            results = self.worker.finished(timeout)
        except WorkerGoneError as exc:
            self._lose_worker(exc)
            return
        for result in results:
            self._report(self._in_hand.popleft(), result)

    def close(self) -> None:
        """Stop the worker once the frames in hand are written, and report them."""
        if self.worker is None:
            return
        worker, self.worker = self.worker, None
        for result in worker.close():
            self._report(self._in_hand.popleft(), result)
        self._fail_in_hand()

    def _lose_worker(self, exc: Exception) -> None:
        """The worker died: its frames in hand are reported failed, the next ones made in the loop."""
        log.error("%s: frames are made in the loop from now on", exc)
        self.worker = None
        self.worker_lost = True
        self._fail_in_hand()

    def _fail_in_hand(self) -> None:
        while self._in_hand:
            capture = self._in_hand.popleft()
            self._report(capture, FrameResult(capture.index, False, 0.0))

    def _job(self, index: int, t: float) -> FrameJob:
        """Frame `index` as the camera sees it now: the true pose of the vehicle and the gimbal, the world at t."""
        v = self.vehicle
        truth = v.sim.state
        _, _, true_yaw = euler_from_quat(truth.quaternion)
        pose: CameraPose = camera_pose(truth.position, v.home[2], self.gimbal.camera_quaternion(true_yaw))
        wind = v.config.wind
        environment = Environment(
            wind.direction_from_deg, wind.speed_m_s, self.current.current_to_deg, self.current.current_speed_m_s
        )
        path = self.image_dir / image_name(index)
        return FrameJob(index, path, pose, self.intrinsics, self.view.scene(t, environment), JPEG_QUALITY)

    def _describe(self, index: int) -> _Capture:
        """The report's fields at the capture's instant: the estimate's geotag, the camera's attitude."""
        v = self.vehicle
        n, e, d = (float(c) for c in v.estimate.position)
        lat, lon, alt = (float(c) for c in v.frame.from_ned(n, e, d))
        _, _, est_yaw = euler_from_quat(v.estimate.quaternion)
        return _Capture(
            index, v.time_boot_ms, self._unix_us(), round(lat * 1e7), round(lon * 1e7), round(alt * 1000),
            round(-d * 1000), self.gimbal.camera_quaternion(est_yaw), time.monotonic(),
        )  # fmt: skip

    def _report(self, capture: _Capture, result: FrameResult) -> None:
        """CAMERA_IMAGE_CAPTURED (the file written, or capture_result 0) and the capture status after it."""
        self.render_s.append(result.seconds)
        c = capture
        msg = mavlink.MAVLink_camera_image_captured_message(
            c.time_boot_ms, c.time_utc_us, 0, c.lat_e7, c.lon_e7, c.alt_mm, c.relative_alt_mm, list(c.q), c.index,
            int(result.ok), file_url(image_name(c.index)).encode(),
        )  # fmt: skip
        self.captured.append(msg)
        self.report_s.append(time.monotonic() - c.taken_at)
        self.send(msg)
        self.send(self.capture_status())

    def _unix_us(self) -> int:
        """The vehicle's UTC on simulated time (SYSTEM_TIME's clock: wall time at boot + simulated time)."""
        return self.boot_unix_us + self.vehicle.time_boot_ms * 1000

    def stats(self) -> dict:
        """For --stats: images taken, the wall time each cost (render, JPEG, write) and from its tick to its
        report, and where frames were made."""

        def summary(seconds: list[float]) -> dict[str, float] | None:
            ms = sorted(s * 1000 for s in seconds)
            return {"p50": ms[len(ms) // 2], "max": ms[-1]} if ms else None

        return {
            "images": self.schedule.image_count,
            "frames_made": "loop" if self.frames_in_loop else "worker",
            "worker_lost": self.worker_lost,
            "frame_ms": summary(self.render_s),
            "report_after_ms": summary(self.report_s),
        }

    # ----- messages
    def camera_information(self):
        s = self.spec
        return mavlink.MAVLink_camera_information_message(
            self.vehicle.time_boot_ms, _uint8_name(s.vendor), _uint8_name(s.model),
            FIRMWARE_VERSION, s.focal_length_mm, s.sensor_width_mm, s.sensor_height_mm, s.width_px, s.height_px,
            0, CAPABILITIES, 0, b"", 0, 0,
        )  # fmt: skip

    def camera_settings(self):
        return mavlink.MAVLink_camera_settings_message(
            self.vehicle.time_boot_ms, mavlink.CAMERA_MODE_IMAGE, math.nan, math.nan, 0
        )

    def capture_status(self):
        schedule = self.schedule
        image_status = 2 if schedule.interval_running else 0  # 2: interval set (captures are instantaneous)
        return mavlink.MAVLink_camera_capture_status_message(
            self.vehicle.time_boot_ms, image_status, 0, schedule.interval_s, 0,
            self._free_mib(), len(self.captured), 0,
        )  # fmt: skip

    def storage_information(self):
        total, used, free = self._disk_mib()
        return mavlink.MAVLink_storage_information_message(
            self.vehicle.time_boot_ms, 1, 1, mavlink.STORAGE_STATUS_READY, total, used, free, 0.0, 0.0,
            mavlink.STORAGE_TYPE_OTHER, b"images", 0,
        )  # fmt: skip

    def _disk_mib(self) -> tuple[float, float, float]:
        try:
            usage = shutil.disk_usage(self.image_dir)
        except OSError:
            return 0.0, 0.0, 0.0
        mib = 1024.0 * 1024.0
        return usage.total / mib, usage.used / mib, usage.free / mib

    def _free_mib(self) -> float:
        return self._disk_mib()[2]
