"""The vehicle's camera (MAVLink camera protocol v2), as MAVSDK's Camera plugin and QGroundControl find and read it.

- Found by its HEARTBEAT: type MAV_TYPE_CAMERA from a component of the vehicle's system (PX4 and ArduPilot
  route a camera's messages through; MAVSDK's CameraServer sends one at 1 Hz).
- Its lens and sensor from CAMERA_INFORMATION, asked for with MAV_CMD_REQUEST_MESSAGE (what PX4's cameras and
  MAVSDK's CameraServer answer), falling back to the legacy MAV_CMD_REQUEST_CAMERA_INFORMATION as MAVSDK does.
- Each CAMERA_IMAGE_CAPTURED checked into a `Capture` (its geotag and file URL) or refused with
  `CaptureReportError` naming what is wrong: a camera is a peer nobody here wrote, and a report that does not
  add up is recorded, never trusted.
Names shown are the camera's own text: kept as text (the page never renders them as HTML).
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import time
from collections.abc import Iterator
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from gcs.domain.camera_geometry import CameraModel, FrameGeotag
from gcs.vehicle.errors import LinkError
from uavcore.mavlink import mavlink

if TYPE_CHECKING:
    from gcs.vehicle.link import LinkManager

log = logging.getLogger(__name__)

INFORMATION_TIMEOUT_S = 1.0  # per try, wall clock
INFORMATION_TRIES = 3
MAX_RESOLUTION_PX = 16384  # larger than any camera's sensor: a figure beyond is not a camera's
CAPTURED = "CAMERA_IMAGE_CAPTURED"


class CameraError(LinkError):
    """The camera did not answer or gave figures that are not a camera's."""


class CaptureReportError(ValueError):
    """A CAMERA_IMAGE_CAPTURED that cannot be used: the message names the field and the value."""


def _text(raw: Any) -> str:
    """A MAVLink char array / uint8 array as text (NULs and undecodable bytes dropped)."""
    data = bytes(raw) if isinstance(raw, list | tuple | bytes | bytearray) else str(raw).encode("latin-1", "replace")
    return data.split(b"\0", 1)[0].decode("utf-8", "replace")


@dataclass(frozen=True)
class CameraInfo:
    """A camera of the vehicle: its component id, names (the camera's text) and pinhole model."""

    component: int
    vendor: str
    model_name: str
    model: CameraModel

    @classmethod
    def from_message(cls, m: Any) -> CameraInfo:
        """From CAMERA_INFORMATION; raises CameraError when its lens or sensor figures are not a camera's."""
        figures = {
            "focal_length": m.focal_length,
            "sensor_size_h": m.sensor_size_h,
            "sensor_size_v": m.sensor_size_v,
        }
        for name, value in figures.items():
            if not (math.isfinite(value) and value > 0.0):
                raise CameraError(f"CAMERA_INFORMATION.{name} is {value!r}: the camera's lens is not known")
        for name in ("resolution_h", "resolution_v"):
            if not 0 < getattr(m, name) <= MAX_RESOLUTION_PX:
                raise CameraError(f"CAMERA_INFORMATION.{name} is {getattr(m, name)!r}")
        model = CameraModel(int(m.resolution_h), int(m.resolution_v), float(m.focal_length),
                            float(m.sensor_size_h), float(m.sensor_size_v))  # fmt: skip
        return cls(m.get_srcComponent(), _text(m.vendor_name), _text(m.model_name), model)


@dataclass(frozen=True)
class Capture:
    """One image the camera says it took: where (the geotag), which (its index) and where to fetch it."""

    component: int
    geotag: FrameGeotag
    file_url: str
    received_at: float  # time.monotonic()

    @classmethod
    def from_message(cls, m: Any) -> Capture:
        """From CAMERA_IMAGE_CAPTURED; raises CaptureReportError naming the field that makes it unusable."""
        if m.capture_result != 1:
            raise CaptureReportError(f"capture_result is {m.capture_result}: the camera says the capture failed")
        if not (-900_000_000 <= m.lat <= 900_000_000 and -1_800_000_000 <= m.lon <= 1_800_000_000):
            raise CaptureReportError(f"lat/lon ({m.lat}, {m.lon}) are not a position (degE7)")
        q = [float(c) for c in m.q]
        norm = math.sqrt(sum(c * c for c in q)) if all(math.isfinite(c) for c in q) else math.nan
        if not abs(norm - 1.0) < 0.01:
            raise CaptureReportError(f"q {q} is not a unit quaternion: the camera's attitude is not known")
        url = _text(m.file_url)
        if not url:
            raise CaptureReportError("file_url is empty: the image cannot be fetched")
        if m.image_index < 0:
            raise CaptureReportError(f"image_index is {m.image_index}")
        geotag = FrameGeotag.from_capture(m.lat, m.lon, m.relative_alt, q, m.time_boot_ms, m.image_index)
        return cls(m.get_srcComponent(), geotag, url, time.monotonic())


class CameraClient:
    """The camera of one vehicle link: which component it is, its CAMERA_INFORMATION, and its captures."""

    def __init__(self, link: LinkManager) -> None:
        self._link = link
        self.component: int | None = None  # the first camera heard on the vehicle's system (None: none yet)
        self.info: CameraInfo | None = None
        self._since = time.monotonic()  # when the vehicle was adopted: its camera is heard within a second or so

    def heard(self, m: Any) -> None:
        """A HEARTBEAT from the vehicle's system: remember the first camera component."""
        if m.type == mavlink.MAV_TYPE_CAMERA and self.component is None:
            self.component = m.get_srcComponent()
            log.info("camera found: component %s", self.component)

    def forget(self) -> None:
        """A new vehicle: its camera is found again."""
        self.component, self.info, self._since = None, None, time.monotonic()

    async def wait_heard(self, within_s: float) -> bool:
        """Whether the vehicle has a camera, waiting for its heartbeat until `within_s` after the vehicle was
        adopted (a camera's heartbeat comes at 1 Hz): a vehicle heard long ago without one has none."""
        while self.component is None and time.monotonic() - self._since < within_s:
            await asyncio.sleep(0.1)
        return self.component is not None

    async def information(self) -> CameraInfo:
        """The camera's CAMERA_INFORMATION (asked for once, then kept); raises CameraError when there is no
        camera, it does not answer, or its figures are not a camera's."""
        if self.info is not None:
            return self.info
        component = self.component
        if component is None:
            raise CameraError("the vehicle has no camera")
        requests = [
            (mavlink.MAV_CMD_REQUEST_MESSAGE, mavlink.MAVLINK_MSG_ID_CAMERA_INFORMATION),
            (mavlink.MAV_CMD_REQUEST_CAMERA_INFORMATION, 1),
        ]
        with self._link.subscribe({"CAMERA_INFORMATION"}, component=component) as answers:
            for attempt in range(INFORMATION_TRIES):
                command, param1 = requests[min(attempt, 1)]
                self._link.send(
                    self._link.encoder.command_long_encode(
                        self._link.target[0], component, command, 0, param1, 0, 0, 0, 0, 0, 0
                    )
                )
                with contextlib.suppress(TimeoutError):
                    async with asyncio.timeout(INFORMATION_TIMEOUT_S):
                        message = await answers.get()
                    self.info = CameraInfo.from_message(message)
                    return self.info
        raise CameraError(f"the camera (component {component}) did not send its CAMERA_INFORMATION")

    @contextlib.contextmanager
    def captures(self) -> Iterator[asyncio.Queue]:
        """A queue of every CAMERA_IMAGE_CAPTURED message from the camera while the block runs (check each with
        Capture.from_message)."""
        if self.component is None:
            raise CameraError("the vehicle has no camera")
        with self._link.subscribe({CAPTURED}, component=self.component) as queue:
            yield queue
