"""Offboard setpoints beyond attitude, as PX4 takes them: position/velocity/acceleration/yaw targets and body
rates with thrust, turned into what the vehicle's own loops fly.

PX4's MAVLink receiver accepts SET_POSITION_TARGET_LOCAL_NED / _GLOBAL_INT (any mix of position, velocity,
acceleration, yaw and yaw rate, chosen by type_mask) and SET_ATTITUDE_TARGET with body rates and thrust; it
turns each into the local-frame setpoint its position (or rate) controller flies, and the stream is the proof of
life that keeps OFFBOARD alive. Here:
- `PositionTarget` is such a request in the local NED frame, NaN where an axis is not controlled;
  `local_position_target` converts the frames MAVSDK and QGC send (LOCAL_NED; LOCAL_OFFSET_NED; BODY_NED and
  BODY_OFFSET_NED, whose vectors PX4 rotates by the vehicle's heading when the message arrives) and
  `global_to_local` the GLOBAL_INT frames' latitude/longitude/altitude;
- `wants_takeoff` is PX4's trigger for leaving the ground in OFFBOARD (FlightTask::_checkTakeoff): a position
  setpoint more than 0.2 m above the vehicle, or a climb faster than 0.3 m/s;
- `OffboardTracker` makes the tick's reference: a TrajectorySetpoint for the built-in position loop (a yaw-rate
  command integrates a yaw reference, no yaw command holds the heading), or an attitude reference integrated
  from commanded body rates for the attitude loop.

Pure computation: no MAVLink, no clocks (dt is the vehicle's outer-loop period).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum

import numpy as np

from uavcore.geodesy import LocalFrame
from uavcore.mission import MavFrame
from uavcore.rotation import euler_from_quat, quat_multiply, wrap_pi
from uavcore.state import AttitudeTarget, TrajectorySetpoint, VehicleState

Vector3 = tuple[float, float, float]
NAN3: Vector3 = (math.nan, math.nan, math.nan)

TAKEOFF_MIN_ALTITUDE_M = 0.2  # a position setpoint this far above the vehicle asks for a takeoff (PX4)
TAKEOFF_MIN_CLIMB_M_S = 0.3  # an upward velocity setpoint faster than this asks for a takeoff (PX4)

LOCAL_FRAMES = frozenset({MavFrame.LOCAL_NED, MavFrame.LOCAL_OFFSET_NED, MavFrame.BODY_NED, MavFrame.BODY_OFFSET_NED})
OFFSET_FRAMES = frozenset({MavFrame.LOCAL_OFFSET_NED, MavFrame.BODY_OFFSET_NED})  # position relative to the vehicle
BODY_FRAMES = frozenset({MavFrame.BODY_NED, MavFrame.BODY_OFFSET_NED})  # vectors along the vehicle's heading


class SetpointKind(Enum):
    """What the latest offboard setpoint asks the vehicle to fly."""

    ATTITUDE = "attitude"  # attitude + thrust: the attitude loop directly (the ADRC offboard controller)
    RATES = "rates"  # body rates + thrust: an attitude reference integrated from the rates
    TRAJECTORY = "trajectory"  # position/velocity/acceleration/yaw: the built-in position loop


class SetpointError(ValueError):
    """A setpoint the vehicle cannot fly (an unsupported frame, nothing controlled)."""


@dataclass(frozen=True)
class PositionTarget:
    """A SET_POSITION_TARGET_* request in the local NED frame (metres, m/s, m/s^2, radians); NaN = ignored."""

    position: Vector3 = NAN3
    velocity: Vector3 = NAN3
    acceleration: Vector3 = NAN3
    yaw: float = math.nan
    yaw_rate: float = math.nan

    def __post_init__(self) -> None:
        controlled = [*self.position, *self.velocity, *self.acceleration]
        if not any(math.isfinite(c) for c in controlled):
            raise SetpointError("a position target must control a position, velocity or acceleration")


@dataclass(frozen=True)
class RatesTarget:
    """SET_ATTITUDE_TARGET with the attitude ignored: body rates (rad/s, FRD) and normalised thrust."""

    body_rates: Vector3
    thrust: float


def _rotate_by_heading(vector: Vector3, yaw: float) -> Vector3:
    """(forward, right, down) along a heading -> (north, east, down)."""
    forward, right, down = vector
    c, s = math.cos(yaw), math.sin(yaw)
    return forward * c - right * s, forward * s + right * c, down


def local_position_target(
    frame: int,
    position: Vector3,
    velocity: Vector3,
    acceleration: Vector3,
    yaw: float,
    yaw_rate: float,
    here: VehicleState,
) -> PositionTarget:
    """The request of a SET_POSITION_TARGET_LOCAL_NED in `frame`, in the local NED frame, given the vehicle's
    estimate when it arrived. Raises SetpointError for a frame PX4 does not take there."""
    if frame not in LOCAL_FRAMES:
        raise SetpointError(f"frame {frame} is not a local frame")
    heading = euler_from_quat(here.quaternion)[2]
    if frame in BODY_FRAMES:
        velocity = _rotate_by_heading(velocity, heading)
        acceleration = _rotate_by_heading(acceleration, heading)
    if frame in OFFSET_FRAMES:
        offset = _rotate_by_heading(position, heading) if frame == MavFrame.BODY_OFFSET_NED else position
        position = tuple(float(p) + o for p, o in zip(here.position, offset, strict=True))
    return PositionTarget(position, velocity, acceleration, yaw, yaw_rate)


def global_to_local(
    frame: LocalFrame, home_altitude: float, lat: float, lon: float, altitude: float, relative: bool
) -> Vector3:
    """A GLOBAL_INT / GLOBAL_RELATIVE_ALT_INT position as NED metres; NaN latitude/longitude or altitude stay NaN
    (not controlled). `relative`: altitude above home, else AMSL."""
    north = east = math.nan
    if math.isfinite(lat) and math.isfinite(lon):
        if not (-90 <= lat <= 90 and -180 <= lon <= 180):
            raise SetpointError(f"({lat}, {lon}) is not a latitude/longitude")
        n, e, _ = frame.to_ned(lat, lon, frame.alt0)
        north, east = float(n), float(e)
    down = -(altitude if relative else altitude - home_altitude) if math.isfinite(altitude) else math.nan
    return north, east, down


def wants_takeoff(target: PositionTarget, here: VehicleState) -> bool:
    """PX4's takeoff trigger: the setpoint asks the vehicle on the ground to go up."""
    down = target.position[2]
    climb = target.velocity[2]
    above = math.isfinite(down) and down < float(here.position[2]) - TAKEOFF_MIN_ALTITUDE_M
    return above or (math.isfinite(climb) and climb < -TAKEOFF_MIN_CLIMB_M_S)


def _axis_angle_quaternion(rates: Vector3, dt: float) -> np.ndarray:
    """The rotation by body rates over dt, as a quaternion (w, x, y, z)."""
    angle = math.sqrt(sum(r * r for r in rates)) * dt
    if angle < 1e-12:
        return np.array([1.0, 0.0, 0.0, 0.0])
    half = angle / 2
    scale = math.sin(half) * dt / angle
    return np.array([math.cos(half), rates[0] * scale, rates[1] * scale, rates[2] * scale])


class OffboardTracker:
    """The references the vehicle's loops follow from offboard setpoints; see the module docstring.

    It remembers what must be continuous from tick to tick (the yaw reference, the integrated attitude) and
    starts them from the estimate whenever the kind of setpoint flown changes or `reset` is called.
    """

    def __init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        self._kind: SetpointKind | None = None
        self._yaw: float = math.nan
        self._attitude: np.ndarray | None = None

    def _start(self, kind: SetpointKind, here: VehicleState) -> None:
        if kind != self._kind:
            self._kind = kind
            self._yaw = euler_from_quat(here.quaternion)[2]
            self._attitude = np.array(here.quaternion, dtype=float)

    def trajectory_setpoint(self, target: PositionTarget, here: VehicleState, dt: float) -> TrajectorySetpoint:
        """The position loop's setpoint for a position target (NaN axes: that axis is not position-controlled)."""
        self._start(SetpointKind.TRAJECTORY, here)
        yaw_rate = target.yaw_rate if math.isfinite(target.yaw_rate) else 0.0
        if math.isfinite(target.yaw):
            self._yaw = wrap_pi(target.yaw)
        else:  # a yaw rate alone turns the yaw reference at that rate; neither holds the heading
            self._yaw = wrap_pi(self._yaw + yaw_rate * dt)
        return TrajectorySetpoint(
            position=np.array(target.position, dtype=float),
            velocity=np.array([c if math.isfinite(c) else 0.0 for c in target.velocity]),
            acceleration=np.array([c if math.isfinite(c) else 0.0 for c in target.acceleration]),
            yaw=self._yaw,
            yaw_rate=yaw_rate,
        )

    def rates_target(self, target: RatesTarget, here: VehicleState, dt: float) -> AttitudeTarget:
        """The attitude loop's target for body rates: the attitude reference turned by the rates over dt, with
        the rates as feed-forward."""
        self._start(SetpointKind.RATES, here)
        turned = quat_multiply(self._attitude, _axis_angle_quaternion(target.body_rates, dt))
        self._attitude = turned / np.linalg.norm(turned)
        return AttitudeTarget(
            quaternion=self._attitude.copy(), thrust=target.thrust, body_rates=np.array(target.body_rates, dtype=float)
        )
