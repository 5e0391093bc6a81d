"""The gimbal camera's model: its sensor and lens, the capture schedule in simulated time, and the scene it sees.

Pure computation (the MAVLink camera component, sitl_quad.mavlink.camera, writes the files and talks):
- `CameraSpec`: the figures CAMERA_INFORMATION reports, from which the renderer's intrinsics follow
  (DEFAULT_SPEC gives sitl_quad.camera_render.DEFAULT_CAMERA).
- `CaptureSchedule`: MAV_CMD_IMAGE_START_CAPTURE's single shot or interval x count (0: until stopped), on the
  simulated clock, so a lockstep run captures the same instants at any speed. The first capture of a sequence is
  taken at once (the first tick at or after the start), capture k is due k intervals after it. Images are
  numbered from 0 for the camera's whole life (CAMERA_IMAGE_CAPTURED.image_index = image_count - 1, MAVLink's
  camera protocol).
- `WorldView`: the buoy world (uavcore.buoy_world) as the renderer's Scene at time t: each buoy where it floats
  in the wind and current, in its IALA paint, its light drawn only while its actual character shows it.
- `camera_pose`: the camera's pose for the renderer from the vehicle's local NED position (origin at home) and
  the gimbal's attitude: the renderer's sea is at down = 0, i.e. at 0 m AMSL.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from sitl_quad.camera_render import CameraPose, Intrinsics, RenderedBuoy, Scene
from uavcore.buoy_world import LIGHT_RGB, PAINT_RGB, World, WorldBuoy
from uavcore.geodesy import LocalFrame


@dataclass(frozen=True)
class CameraSpec:
    """Sensor, lens and image size as CAMERA_INFORMATION gives them."""

    vendor: str
    model: str
    focal_length_mm: float
    sensor_width_mm: float
    sensor_height_mm: float
    width_px: int
    height_px: int

    @property
    def intrinsics(self) -> Intrinsics:
        return Intrinsics.from_sensor(
            self.width_px, self.height_px, self.focal_length_mm, self.sensor_width_mm, self.sensor_height_mm
        )


# camera_render.DEFAULT_CAMERA's figures: a 1/2.3" sensor read out 16:9 behind a 4.5 mm lens
DEFAULT_SPEC = CameraSpec("buoy-sim", "SimCam 1/2.3", 4.5, 6.17, 6.17 * 9 / 16, 1280, 720)
MIN_CAMERA_HEIGHT_M = 0.1  # above the sea
TIME_TOLERANCE_S = 1e-9  # a capture due at t is taken by the tick at t despite floating-point sums


def image_name(index: int) -> str:
    """The image file's name: zero-padded index, so the directory lists in capture order."""
    return f"IMG_{index:06d}.jpg"


class CaptureSchedule:
    """Which simulated instants are captures (module docstring)."""

    def __init__(self) -> None:
        self.interval_s = 0.0
        self.remaining: int | None = 0  # captures left in the sequence; None: until stopped
        self.next_at: float | None = None
        self.image_count = 0  # captured in the camera's life
        self._start = 0.0
        self._step = 0

    @property
    def interval_running(self) -> bool:
        """A sequence of more than one capture is under way (CAMERA_CAPTURE_STATUS image_status 2/3)."""
        return self.next_at is not None and self.interval_s > 0 and self.remaining != 1

    def start(self, t: float, interval_s: float, count: int) -> None:
        """From t: count captures (0: until stop()) interval_s apart; count 1 is a single shot.

        The interval is taken to the microsecond: MAVLink carries it as a float32 (0.1 s arrives as
        0.10000000149 s), whose excess would otherwise make every capture meant for a tick wait for the next one.
        """
        interval = round(interval_s, 6) if math.isfinite(interval_s) else 0.0
        if count < 0 or (count != 1 and not interval > 0):
            raise ValueError(f"capture sequence of {count} images every {interval_s} s")
        self.interval_s = interval if count != 1 else 0.0
        self.remaining = None if count == 0 else count
        self._start = t  # set again by the first capture
        self._step = 0  # next_at = start + step * interval, never a running sum
        self.next_at = t

    def stop(self) -> None:
        self.next_at, self.remaining, self.interval_s = None, 0, 0.0

    def take_due(self, t: float) -> int | None:
        """The index of the image due at t, if one is (and count it as taken); None otherwise. At most one per
        call: a sequence's interval is at least a tick (the MAVLink layer refuses a shorter one)."""
        if self.next_at is None or t < self.next_at - TIME_TOLERANCE_S:
            return None
        index = self.image_count
        self.image_count += 1
        if self._step == 0:  # the grid runs from the first capture: a command handled between two ticks is
            self._start = t  # taken at the next one, and the others follow it at whole intervals
        if self.remaining is not None:
            self.remaining -= 1
        if self.remaining == 0:
            self.stop()
        else:
            self._step += 1
            behind = t - (self._start + self._step * self.interval_s)
            if behind > TIME_TOLERANCE_S:  # a stall (the process was suspended): resume on the grid
                self._step += math.ceil(behind / self.interval_s)
            self.next_at = self._start + self._step * self.interval_s
        return index


@dataclass(frozen=True)
class Environment:
    """What moves the buoys on their moorings (uavcore.buoy_world.World.positions)."""

    wind_from_deg: float = 0.0
    wind_speed_m_s: float = 0.0
    current_to_deg: float = 0.0
    current_speed_m_s: float = 0.0


def rendered_buoy(buoy: WorldBuoy, position_ne: Sequence[float], t_s: float) -> RenderedBuoy:
    """A world buoy as the renderer draws it at t_s: its kind's appearance, its light only while it shows."""
    look = buoy.appearance
    colour = buoy.light_colour(t_s) if buoy.light_on(t_s) else None
    north, east = (float(c) for c in position_ne)
    return RenderedBuoy(
        position_ne=(north, east),
        bands=[PAINT_RGB[c] for c in look.colours],
        shape=look.shape,
        height_m=look.height_m,
        diameter_m=look.diameter_m,
        vertical_stripes=look.pattern == "vertical",
        topmark=look.topmark,
        topmark_rgb=PAINT_RGB[look.topmark_colour],
        light_rgb=LIGHT_RGB[colour] if colour is not None else None,
    )


class WorldView:
    """The world's buoys in the vehicle's local frame (origin at home)."""

    def __init__(self, world: World, frame: LocalFrame, sea_seed: int = 0) -> None:
        self.world = world
        self.sea_seed = sea_seed
        charted = [frame.to_ned(*b.charted, frame.alt0)[:2] for b in world.buoys]
        self._charted_ne = np.array(charted, dtype=float).reshape(-1, 2)

    def scene(self, t_s: float, environment: Environment) -> Scene:
        e = environment
        drift = self.world.positions(t_s, e.wind_from_deg, e.wind_speed_m_s, e.current_to_deg, e.current_speed_m_s)
        buoys = [rendered_buoy(buoy, self._charted_ne[i] + drift[i], t_s) for i, buoy in enumerate(self.world.buoys)]
        return Scene(buoys=buoys, sea_seed=self.sea_seed, t_s=t_s)


def camera_pose(position_ned: Sequence[float], home_alt_amsl_m: float, attitude: Sequence[float]) -> CameraPose:
    """The renderer's pose: the local NED position (origin at home, home_alt_amsl_m above the sea) moved so the
    sea is at down = 0; attitude camera FRD -> NED (w, x, y, z)."""
    north, east, down = (float(c) for c in position_ned)
    w, x, y, z = (float(c) for c in attitude)
    # the renderer needs the camera above the sea: a vehicle standing on a quay at 0 m AMSL has it just above
    return CameraPose((north, east, min(down - home_alt_amsl_m, -MIN_CAMERA_HEIGHT_M)), (w, x, y, z))
