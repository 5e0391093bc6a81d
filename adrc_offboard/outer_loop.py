"""The outer (position) loop: trajectory setpoint + state estimate -> attitude target, with ADRC or PID.

Both controllers have the same structure so the comparison is fair: per NED axis, a second-order channel
turns the position setpoint (with its velocity and acceleration as feed-forward) and the measured position
into a desired acceleration; the vector is limited (`AccelerationLimits`: horizontal norm, climb, sink) and
mapped by `uavcore.rotation.acceleration_to_attitude` (tilt and thrust limits) to a quaternion and a
normalised thrust. Both run at the same rate and see the same measurements (position and velocity).

- `AdrcOuterLoop`: one ADRC channel per axis with b0 = 1 (the control is acceleration). The navigator's
  setpoint is already smooth, so by default there is no TD: its velocity and acceleration are the channel's
  v2 and feed-forward (re-differentiating a smooth setpoint would only add lag); a spec with "r0" turns the
  paper's TD on instead. The ESO works on the measured position; with `use_measured_velocity` (the
  default) the measured velocity replaces z2 in the rate error, as the PID uses it: under the simulator's
  sensor noise the z2 of a 50 Hz position-only ESO is noisier than the measured velocity. Each ESO is fed
  the acceleration actually commanded after every limit, recovered from the attitude target, so saturation
  never winds it up. z3 is the total disturbance acceleration in NED, m/s^2: a wind pushing north at
  1.5 m/s^2 gives z3_x ~ +1.5.
- `PidOuterLoop`: a = a_ref + kp e + kd (v_ref - v) + i, i = integral of ki e with conditional integration
  (frozen while the axis is saturated in the direction the error pushes) and a clamp.

Yaw is not a feedback channel here: the setpoint's yaw goes straight into the target quaternion and the
attitude loop (ADRC or PID, at 250 Hz) tracks it, which also handles the wrap-around at +-180 deg. The
setpoint's yaw rate (the navigator's turns) goes with it as the target's body-rate feed-forward, R^T e_z
yaw_rate in the target's body axes (PX4's yaw-rate feed-forward; `acceleration_to_attitude`), so the attitude
loop turns with the reference instead of chasing it.

`matched_gains()` gives both the same closed-loop bandwidth (the shipped gains come from adrc_offboard.design).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from adrc_offboard.adrc import AdrcParameterError, bandwidth_parameters
from adrc_offboard.gains import Channel, ChannelParameters, channel_parameters, load_gains, make_channel
from uavcore.rotation import acceleration_to_attitude
from uavcore.state import AttitudeTarget, TrajectorySetpoint, VehicleState

AXES = ("x", "y", "z")
MIN_PATH_SPEED = 0.5  # m/s: below it the reference has no direction worth keeping to (hovering, turning on the spot)


@dataclass(frozen=True)
class AccelerationLimits:
    """Limits on the desired acceleration, m/s^2, shared by both controllers."""

    max_horizontal: float = 6.0  # norm of the north-east demand
    max_up: float = 4.0  # climb acceleration (NED a_z >= -max_up)
    max_down: float = 3.0  # sink acceleration (NED a_z <= max_down)

    def __post_init__(self) -> None:
        for name in ("max_horizontal", "max_up", "max_down"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
                raise AdrcParameterError(f"acceleration limit {name} must be finite and positive, got {value!r}")

    @classmethod
    def load(cls, source: str | Path = "outer_limits") -> AccelerationLimits:
        data = load_gains(source)
        data.pop("comment", None)
        try:
            return cls(**data)
        except TypeError as exc:
            raise AdrcParameterError(f"bad acceleration limits {data}: {exc}") from exc

    def apply(
        self, ax: float, ay: float, az: float, along: tuple[float, float] | None = None
    ) -> tuple[float, float, float]:
        """The demand limited. Over the horizontal limit, with `along` (the path's horizontal direction, a unit
        vector) the cross-track part is kept first and the along-track part gets what is left: the vehicle stays on
        its path and falls behind along it, then catches up, instead of being pushed off it by a demand scaled
        as a whole. Without `along` the horizontal demand is scaled down as a whole."""
        horizontal = math.hypot(ax, ay)
        if horizontal > self.max_horizontal:
            if along is None:
                scale = self.max_horizontal / horizontal
                ax, ay = ax * scale, ay * scale
            else:
                ux, uy = along
                a_along = ax * ux + ay * uy
                cx, cy = ax - a_along * ux, ay - a_along * uy  # cross-track part
                cross = math.hypot(cx, cy)
                if cross >= self.max_horizontal:
                    ax, ay = cx * self.max_horizontal / cross, cy * self.max_horizontal / cross
                else:
                    room = math.sqrt(self.max_horizontal**2 - cross * cross)
                    a_along = max(-room, min(room, a_along))
                    ax, ay = cx + a_along * ux, cy + a_along * uy
        return ax, ay, min(self.max_down, max(-self.max_up, az))


def applied_acceleration(
    target: AttitudeTarget, mass: float, g: float, max_thrust_n: float
) -> tuple[float, float, float]:
    """The NED acceleration an attitude target really asks for (after the tilt and thrust limits):
    thrust along body -z rotated into the world, plus gravity."""
    w, x, y, z = target.quaternion.tolist()
    specific = target.thrust * max_thrust_n / mass
    # body z axis in the world frame: third column of R(q)
    return (
        -specific * 2.0 * (x * z + w * y),
        -specific * 2.0 * (y * z - w * x),
        -specific * (1.0 - 2.0 * (x * x + y * y)) + g,
    )


@dataclass(frozen=True)
class AdrcOuterGains:
    """Channel specs parsed with b0 = 1: horizontal (x and y) and vertical (z)."""

    horizontal: ChannelParameters
    vertical: ChannelParameters
    use_measured_velocity: bool = True

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> AdrcOuterGains:
        unknown = set(data) - {"horizontal", "vertical", "use_measured_velocity", "comment"}
        if unknown or "horizontal" not in data or "vertical" not in data:
            raise AdrcParameterError(f"ADRC outer gains need 'horizontal' and 'vertical' specs; got {sorted(data)}")
        return cls(
            channel_parameters(data["horizontal"], 1.0),
            channel_parameters(data["vertical"], 1.0),
            bool(data.get("use_measured_velocity", True)),
        )

    @classmethod
    def load(cls, source: str | Path = "outer_adrc") -> AdrcOuterGains:
        return cls.from_dict(load_gains(source))


@dataclass(frozen=True)
class PidAxisGains:
    kp: float  # 1/s^2
    ki: float  # 1/s^3
    kd: float  # 1/s
    i_max: float  # m/s^2, clamp on the integrator's contribution

    def __post_init__(self) -> None:
        for name in ("kp", "ki", "kd", "i_max"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value >= 0):
                raise AdrcParameterError(f"PID gain {name} must be finite and >= 0, got {value!r}")


@dataclass(frozen=True)
class PidOuterGains:
    horizontal: PidAxisGains
    vertical: PidAxisGains

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> PidOuterGains:
        try:
            return cls(PidAxisGains(**data["horizontal"]), PidAxisGains(**data["vertical"]))
        except (KeyError, TypeError) as exc:
            raise AdrcParameterError(f"PID outer gains need horizontal and vertical kp, ki, kd, i_max: {exc}") from exc

    @classmethod
    def load(cls, source: str | Path = "outer_pid") -> PidOuterGains:
        return cls.from_dict(load_gains(source))


class _ThrustVectorOutput:
    """What both controllers share: airframe figures, limits, and acceleration -> attitude target."""

    def __init__(
        self,
        mass: float,
        g: float,
        max_thrust_n: float,
        max_tilt_rad: float,
        limits: AccelerationLimits | None,
        rate_hz: float,
    ) -> None:
        for name, value in (("mass", mass), ("g", g), ("max_thrust_n", max_thrust_n), ("rate_hz", rate_hz)):
            if not (math.isfinite(value) and value > 0):
                raise AdrcParameterError(f"{name} must be finite and positive, got {value!r}")
        if not 0 < max_tilt_rad < math.pi / 2:
            raise AdrcParameterError(f"max_tilt_rad must lie in (0, pi/2), got {max_tilt_rad!r}")
        if max_thrust_n <= mass * g:
            raise AdrcParameterError(f"max thrust {max_thrust_n} N cannot lift {mass} kg")
        self.mass, self.g, self.max_thrust_n, self.max_tilt_rad = mass, g, max_thrust_n, max_tilt_rad
        self.limits = limits if limits is not None else AccelerationLimits.load()
        self.h = 1.0 / rate_hz
        self.demanded = (0.0, 0.0, 0.0)
        self.applied = (0.0, 0.0, 0.0)

    def output(self, demanded: tuple[float, float, float], setpoint: TrajectorySetpoint) -> AttitudeTarget:
        """The attitude target for the demanded acceleration, facing the setpoint's yaw and turning at its yaw rate
        (body-rate feed-forward)."""
        self.demanded = demanded
        vx, vy = float(setpoint.velocity[0]), float(setpoint.velocity[1])
        speed = math.hypot(vx, vy)
        along = (vx / speed, vy / speed) if speed > MIN_PATH_SPEED else None
        limited = self.limits.apply(*demanded, along=along)
        target = acceleration_to_attitude(
            limited, setpoint.yaw, self.mass, self.g, self.max_thrust_n, self.max_tilt_rad, setpoint.yaw_rate
        )
        self.applied = applied_acceleration(target, self.mass, self.g, self.max_thrust_n)
        return target

    def acceleration_telemetry(self) -> dict[str, float]:
        out = {f"acc_demand_{a}": v for a, v in zip(AXES, self.demanded, strict=True)}
        out.update({f"acc_applied_{a}": v for a, v in zip(AXES, self.applied, strict=True)})
        return out


class AdrcOuterLoop:
    """ADRC position loop (x, y, z channels; yaw and yaw rate passed through). See the module docstring."""

    def __init__(
        self,
        mass: float,
        g: float,
        max_thrust_n: float,
        max_tilt_rad: float = math.radians(35.0),
        gains: AdrcOuterGains | None = None,
        limits: AccelerationLimits | None = None,
        rate_hz: float = 50.0,
    ) -> None:
        self._out = _ThrustVectorOutput(mass, g, max_thrust_n, max_tilt_rad, limits, rate_hz)
        self.gains = gains if gains is not None else AdrcOuterGains.load()
        h = self._out.h
        self.channels: list[Channel] = [
            make_channel(self.gains.horizontal, h),
            make_channel(self.gains.horizontal, h),
            make_channel(self.gains.vertical, h),
        ]

    def reset(self) -> None:
        for channel in self.channels:
            channel.reset()

    def update(self, setpoint: TrajectorySetpoint, estimate: VehicleState, dt: float) -> AttitudeTarget:
        """Fixed-step channels at 1/rate_hz (the paper's discrete equations); dt is not used."""
        position, velocity = estimate.position.tolist(), estimate.velocity.tolist()
        reference = setpoint.position.tolist()
        reference_rate, reference_acc = setpoint.velocity.tolist(), setpoint.acceleration.tolist()
        use_velocity = self.gains.use_measured_velocity
        demanded = tuple(
            channel.control(
                reference[i],
                position[i],
                reference_rate[i],
                reference_acc[i],
                velocity[i] if use_velocity else None,
            )
            for i, channel in enumerate(self.channels)
        )
        target = self._out.output(demanded, setpoint)
        for channel, applied in zip(self.channels, self._out.applied, strict=True):
            channel.observe_applied(applied)
        return target

    def disturbance_estimates(self) -> dict[str, float]:
        return {axis: channel.disturbance for axis, channel in zip(AXES, self.channels, strict=True)}

    def telemetry(self) -> dict[str, float]:
        out = self._out.acceleration_telemetry()
        for axis, channel in zip(AXES, self.channels, strict=True):
            out.update({f"{name}_{axis}": value for name, value in channel.state().items()})
        return out


class PidOuterLoop:
    """PID position loop with the same structure, limits, rate and measurements as `AdrcOuterLoop`."""

    def __init__(
        self,
        mass: float,
        g: float,
        max_thrust_n: float,
        max_tilt_rad: float = math.radians(35.0),
        gains: PidOuterGains | None = None,
        limits: AccelerationLimits | None = None,
        rate_hz: float = 50.0,
    ) -> None:
        self._out = _ThrustVectorOutput(mass, g, max_thrust_n, max_tilt_rad, limits, rate_hz)
        self.gains = gains if gains is not None else PidOuterGains.load()
        self._axis_gains = (self.gains.horizontal, self.gains.horizontal, self.gains.vertical)
        self.integrals = [0.0, 0.0, 0.0]

    def reset(self) -> None:
        self.integrals = [0.0, 0.0, 0.0]

    def update(self, setpoint: TrajectorySetpoint, estimate: VehicleState, dt: float) -> AttitudeTarget:
        position, velocity = estimate.position.tolist(), estimate.velocity.tolist()
        reference = setpoint.position.tolist()
        reference_rate, reference_acc = setpoint.velocity.tolist(), setpoint.acceleration.tolist()
        errors = [reference[i] - position[i] for i in range(3)]
        demanded = tuple(
            reference_acc[i] + k.kp * errors[i] + k.kd * (reference_rate[i] - velocity[i]) + self.integrals[i]
            for i, k in enumerate(self._axis_gains)
        )
        target = self._out.output(demanded, setpoint)
        step = dt if dt > 0 else self._out.h
        for i, k in enumerate(self._axis_gains):
            excess = demanded[i] - self._out.applied[i]
            if abs(excess) > 1e-6 and excess * errors[i] > 0:
                continue  # saturated and the error would push further in: freeze (anti-windup)
            self.integrals[i] = max(-k.i_max, min(k.i_max, self.integrals[i] + k.ki * errors[i] * step))
        return target

    def disturbance_estimates(self) -> dict[str, float]:
        return {}

    def telemetry(self) -> dict[str, float]:
        out = self._out.acceleration_telemetry()
        out.update({f"integral_{axis}": value for axis, value in zip(AXES, self.integrals, strict=True)})
        return out


def pid_gains_for_bandwidth(omega_c: float, integral_ratio: float = 0.25, i_max: float = 4.0) -> PidAxisGains:
    """PID on the double integrator with closed-loop poles (s + omega_c)^2 (s + integral_ratio omega_c):
    a critically damped pair at the bandwidth and a slower integrator pole."""
    if not (omega_c > 0 and integral_ratio > 0):
        raise AdrcParameterError("omega_c and integral_ratio must be positive")
    w, wi = omega_c, integral_ratio * omega_c
    return PidAxisGains(kp=w * w + 2 * w * wi, ki=w * w * wi, kd=2 * w + wi, i_max=i_max)


def matched_gains(
    omega_c_horizontal: float,
    omega_c_vertical: float,
    observer_ratio: float = 4.0,
    integral_ratio: float = 0.25,
    delta: float = 0.02,
    r1: tuple[float, float] = (5.0, 4.0),
    use_measured_velocity: bool = True,
) -> tuple[AdrcOuterGains, PidOuterGains]:
    """ADRC and PID outer-loop gains with the same closed-loop bandwidth per axis.

    ADRC: the NLSEF's linear zone is the PD kp = wc^2, kd = 2 wc, and the ESO's linearisation sits at
    omega_o = observer_ratio * wc (3-5 is the usual range). PID: the same critically damped pair at wc plus
    an integrator pole at integral_ratio * wc (`pid_gains_for_bandwidth`). r1 = (horizontal, vertical)
    bounds the NLSEF's acceleration for large errors; use_measured_velocity as in `AdrcOuterGains`.
    """
    adrc = AdrcOuterGains(
        horizontal=bandwidth_parameters(omega_c_horizontal, observer_ratio * omega_c_horizontal, 1.0, delta, r1[0]),
        vertical=bandwidth_parameters(omega_c_vertical, observer_ratio * omega_c_vertical, 1.0, delta, r1[1]),
        use_measured_velocity=use_measured_velocity,
    )
    pid = PidOuterGains(
        pid_gains_for_bandwidth(omega_c_horizontal, integral_ratio),
        pid_gains_for_bandwidth(omega_c_vertical, integral_ratio),
    )
    return adrc, pid
