"""The inner loop with ADRC: roll, pitch and yaw channels turning an attitude target into body torques.

Implements `uavcore.control.AttitudeController`. Each body axis is a second-order channel
  theta_i'' = f_i + b0_i tau_i,   b0_i = 1 / I_i
(the paper's eq. 1 and 4 with the gyroscopic coupling and wind moments lumped into f_i). The control here is
the torque tau_i in N m, so b0 = 1/I; the paper's U2..U4 are rotor forces with tau = L U, which would make
b0 = L/I: same loop, different units. A spec's optional "b0_scale" multiplies b0 (the paper's Remark 3:
a smaller b0 gives a faster, more aggressive response).

Attitude error comes from quaternions, not Euler angles: q_err = conj(q) * q_target is the rotation from
the current body to the target body, in body axes. As in PX4's attitude controller the thrust direction
comes first: the roll and pitch errors are the rotation vector of the shortest tilt that takes the body z
axis onto the target's, whatever the heading; the yaw error is the rotation about z that remains, taken
the short way round, so a yaw target of +179 deg seen from -179 deg is a 2 deg turn. (A plain rotation
vector of q_err would mix a large heading error into roll and pitch and tilt the thrust the wrong way
while the weak yaw axis catches up.)

Each channel's "measured output" is the body-axis angle theta_i integrated from the gyro rate, and its
reference is theta_i + e_i: the ESO then sees only the vehicle's motion, and a jump in the target (the outer
loop updates at 50 Hz) goes through the TD, not into the disturbance estimate. theta_i is only a
bookkeeping coordinate (its drift cancels in theta_i + e_i - theta_i).

The ESO is fed the torque the rotors deliver, not the command: with `actuator_time_constant` (the
airframe's motor lag, 0.02 s for Table 2, taken by `for_airframe`) the command goes through a first-order
lag first. Fed the raw command, the observer reads the lag as a disturbance (a 9 rad/s^2 phantom z3 on a
0.3 rad step in the simulator instead of 0.7).

Yaw-rate feed-forward: the yaw channel's reference theta_z + e_z moves at the target's body yaw rate, which
the outer loop sends as AttitudeTarget.body_rates[2] (the navigator's yaw rate in the target's body axes).
That rate is the reference's known derivative v', so the yaw TD tracks (v, v') (eq. 9 with fhan on
v1 - v, v2 - v'; `TrackingDifferentiator`) and its v2 becomes the turn rate itself rather than a lagging
estimate of it; the NLSEF (eq. 12) then acts on e2 = v2 - r, the error to the wanted rate, so the loop turns
with the reference instead of building up an angle error first. Only the yaw channel takes it: roll and pitch
track the thrust axis, which a turn leaves where it is (PX4's R^T e_z yaw_rate has roll/pitch components
when tilted; the PX4-style PID loop adds those as PX4 does). The thrust field is the mixer's business.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from adrc_offboard.adrc import AdrcParameterError
from adrc_offboard.gains import Channel, channel_parameters, load_gains, make_channel
from uavcore.airframe import Airframe
from uavcore.state import AttitudeTarget, VehicleState

AXES = ("roll", "pitch", "yaw")


@dataclass(frozen=True)
class AdrcAttitudeGains:
    """Channel specs (see `adrc_offboard.gains`) per axis, without b0, which the inertias give."""

    roll: dict[str, Any]
    pitch: dict[str, Any]
    yaw: dict[str, Any]
    use_measured_rate: bool = True  # the gyro rate is fresher than the ESO's z2

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> AdrcAttitudeGains:
        unknown = set(data) - {"roll", "pitch", "yaw", "use_measured_rate", "comment"}
        if unknown:
            raise AdrcParameterError(f"unknown keys {sorted(unknown)} in attitude gains")
        try:
            return cls(
                roll=dict(data["roll"]),
                pitch=dict(data["pitch"]),
                yaw=dict(data["yaw"]),
                use_measured_rate=bool(data.get("use_measured_rate", True)),
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise AdrcParameterError(f"attitude gains need roll, pitch and yaw channel specs: {exc}") from exc

    @classmethod
    def load(cls, source: str | Path = "attitude_adrc") -> AdrcAttitudeGains:
        return cls.from_dict(load_gains(source))


class AdrcAttitudeController:
    """Three ADRC channels at the attitude-loop rate; torques in N m [roll, pitch, yaw]."""

    def __init__(
        self,
        Ix: float,
        Iy: float,
        Iz: float,
        gains: AdrcAttitudeGains | None = None,
        rate_hz: float = 250.0,
        actuator_time_constant: float = 0.0,
    ) -> None:
        gains = gains if gains is not None else AdrcAttitudeGains.load()
        if not (math.isfinite(rate_hz) and rate_hz > 0):
            raise AdrcParameterError(f"rate_hz must be positive, got {rate_hz}")
        self.gains, self.h = gains, 1.0 / rate_hz
        self.channels: list[Channel] = []
        for inertia, spec in zip((Ix, Iy, Iz), (gains.roll, gains.pitch, gains.yaw), strict=True):
            if not (math.isfinite(inertia) and inertia > 0):
                raise AdrcParameterError(f"inertias must be positive, got {(Ix, Iy, Iz)}")
            spec = dict(spec)
            b0 = spec.pop("b0_scale", 1.0) / inertia
            self.channels.append(make_channel(channel_parameters(spec, b0), self.h))
        self._use_rate = gains.use_measured_rate
        self._theta = [0.0, 0.0, 0.0]
        if not (math.isfinite(actuator_time_constant) and actuator_time_constant >= 0):
            raise AdrcParameterError(f"actuator_time_constant must be >= 0, got {actuator_time_constant}")
        self.actuator_time_constant = actuator_time_constant  # s; 0: the torque is applied as commanded
        # fraction of the way a first-order actuator moves toward its command in one step
        self._actuator_step = 1.0 - math.exp(-self.h / actuator_time_constant) if actuator_time_constant else 1.0
        self._actuator = [0.0, 0.0, 0.0]

    @classmethod
    def for_airframe(
        cls, airframe: Airframe, gains: AdrcAttitudeGains | None = None, rate_hz: float = 250.0
    ) -> AdrcAttitudeController:
        """The inner loop for an airframe: its inertias give b0, and its motor lag is the actuator the observers
        model (the vehicle builds its ADRC attitude loop only this way)."""
        return cls(
            airframe.ixx,
            airframe.iyy,
            airframe.izz,
            gains=gains,
            rate_hz=rate_hz,
            actuator_time_constant=airframe.motor_time_constant,
        )

    def reset(self) -> None:
        for channel in self.channels:
            channel.reset()
        self._theta = [0.0, 0.0, 0.0]
        self._actuator = [0.0, 0.0, 0.0]

    def update(self, target: AttitudeTarget, state: VehicleState, dt: float) -> np.ndarray:
        """Torque for this step. The channels are fixed-step at 1/rate_hz (the paper's discrete
        equations); dt only advances the gyro-integrated bookkeeping angles."""
        w, x, y, z = state.quaternion.tolist()
        tw, tx, ty, tz = target.quaternion.tolist()
        # q_err = conj(q) * q_target (rotation current body -> target body, body axes)
        ew = w * tw + x * tx + y * ty + z * tz
        ex = w * tx - x * tw - y * tz + z * ty
        ey = w * ty + x * tz - y * tw - z * tx
        ez = w * tz - x * ty + y * tx - z * tw
        # Tilt first (PX4's reduced attitude): the target's thrust axis seen from the current body,
        # z_t = R(q_err) e3, and the shortest rotation taking the body z axis onto it.
        zx = 2.0 * (ex * ez + ew * ey)
        zy = 2.0 * (ey * ez - ew * ex)
        zz = 1.0 - 2.0 * (ex * ex + ey * ey)
        sin_tilt = math.sqrt(zx * zx + zy * zy)
        if sin_tilt > 1e-9:
            scale = math.atan2(sin_tilt, zz) / sin_tilt
            roll_error, pitch_error = -zy * scale, zx * scale
        else:  # aligned, or exactly upside down (then roll over)
            roll_error, pitch_error = (0.0, 0.0) if zz > 0.0 else (math.pi, 0.0)
        # Yaw: what is left of q_err after the tilt, q_rem = conj(q_tilt) * q_err, a rotation about z;
        # q_tilt = normalise(1 + zz, -zy, zx, 0) (the half-way quaternion from e3 to z_t).
        cw, cx, cy = 1.0 + zz, -zy, zx
        rem_w = cw * ew + cx * ex + cy * ey
        rem_z = cw * ez - cx * ey + cy * ex
        yaw_error = 2.0 * math.atan2(rem_z, rem_w)
        if yaw_error > math.pi:  # the short way round
            yaw_error -= 2.0 * math.pi
        elif yaw_error <= -math.pi:
            yaw_error += 2.0 * math.pi
        errors = (roll_error, pitch_error, yaw_error)
        rates = state.angular_velocity.tolist()
        # the reference rates: the yaw channel's from the feed-forward (module docstring), none for roll/pitch
        reference_rates = (0.0, 0.0, 0.0 if target.body_rates is None else float(target.body_rates[2]))
        theta, actuator, lag = self._theta, self._actuator, self._actuator_step
        torques = [0.0, 0.0, 0.0]
        for i, channel in enumerate(self.channels):
            angle = theta[i]
            rate = rates[i]
            torque = channel.control(
                angle + errors[i], angle, reference_rates[i], 0.0, rate if self._use_rate else None
            )
            # the ESO gets the torque the rotors deliver during this step, not the command
            actuator[i] += (torque - actuator[i]) * lag
            channel.observe_applied(actuator[i])
            torques[i] = torque
            theta[i] = angle + rate * dt
        return np.array(torques)

    def disturbance_estimates(self) -> dict[str, float]:
        """Each axis's ESO z3: total angular-acceleration disturbance in rad/s^2."""
        return {axis: channel.disturbance for axis, channel in zip(AXES, self.channels, strict=True)}
