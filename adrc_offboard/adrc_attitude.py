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

The step is the numba kernel `adrc_attitude_torque` on flat arrays (the channels' `adrc.AdrcChannel` kernels, the
bookkeeping angles and the actuator model), so the vehicle's compiled inner loop (sitl_quad.attitude_loops)
runs the very same code; `AdrcAttitudeController` is its Python face. The channels are nonlinear ADRC channels.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from adrc_offboard.adrc import (
    CHANNEL_STATE_SIZE,
    AdrcChannel,
    AdrcChannelParameters,
    AdrcParameterError,
    adrc_channel_control,
    adrc_channel_observe,
)
from adrc_offboard.gains import channel_parameters, load_gains
from uavcore.airframe import Airframe
from uavcore.kernel_cache import cached_kernel
from uavcore.quaternion_kernels import error_quaternion
from uavcore.state import AttitudeTarget, VehicleState

AXES = ("roll", "pitch", "yaw")
# the loop's own state beside the channels': the gyro-integrated bookkeeping angles and the modelled actuator
L_THETA, L_ACTUATOR = 0, 3
LOOP_STATE_SIZE = 6
_NO_FEEDFORWARD = np.zeros(3)


@cached_kernel
def attitude_errors(q: np.ndarray, qd: np.ndarray) -> tuple[float, float, float]:
    """(roll, pitch, yaw) errors in rad from the attitude q to the target qd (module docstring: tilt first)."""
    # q_err = conj(q) * q_target (rotation current body -> target body, body axes)
    ew, ex, ey, ez = error_quaternion((q[0], q[1], q[2], q[3]), (qd[0], qd[1], qd[2], qd[3]))
    # Tilt first (PX4's reduced attitude): the target's thrust axis seen from the current body,
    # z_t = R(q_err) e3, and the shortest rotation taking the body z axis onto it.
    zx = 2.0 * (ex * ez + ew * ey)
    zy = 2.0 * (ey * ez - ew * ex)
    zz = 1.0 - 2.0 * (ex * ex + ey * ey)
    sin_tilt = math.sqrt(zx * zx + zy * zy)
    if sin_tilt > 1e-9:
        scale = math.atan2(sin_tilt, zz) / sin_tilt
        roll_error, pitch_error = -zy * scale, zx * scale
    elif zz > 0.0:  # aligned
        roll_error, pitch_error = 0.0, 0.0
    else:  # exactly upside down: roll over
        roll_error, pitch_error = math.pi, 0.0
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
    return roll_error, pitch_error, yaw_error


@cached_kernel
def adrc_attitude_torque(
    channel_params: np.ndarray,
    channel_states: np.ndarray,
    loop_state: np.ndarray,
    actuator_step: float,
    use_measured_rate: bool,
    q: np.ndarray,
    rates: np.ndarray,
    qd: np.ndarray,
    feedforward: np.ndarray,
    dt: float,
    torque: np.ndarray,
) -> None:
    """One attitude step: write the torques (N m) into torque and advance the channels' states (rows of
    channel_states, parameters the rows of channel_params) and loop_state (`L_*`). q and rates are the measured
    attitude and gyro rates, qd the target and feedforward its body rates (only the yaw rate is used);
    actuator_step is the fraction of the way the modelled actuator moves toward its command in one step."""
    errors = attitude_errors(q, qd)
    for i in range(3):
        angle = loop_state[L_THETA + i]
        rate = rates[i]
        reference_rate = feedforward[2] if i == 2 else 0.0  # the yaw channel's from the feed-forward
        u = adrc_channel_control(
            channel_params[i], channel_states[i], angle + errors[i], angle, reference_rate, 0.0, rate, use_measured_rate
        )
        # the ESO gets the torque the rotors deliver during this step, not the command
        actuator = loop_state[L_ACTUATOR + i]
        actuator += (u - actuator) * actuator_step
        loop_state[L_ACTUATOR + i] = actuator
        adrc_channel_observe(channel_params[i], channel_states[i], actuator)
        torque[i] = u
        loop_state[L_THETA + i] = angle + rate * dt


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
    """Three ADRC channels at the attitude-loop rate; torques in N m [roll, pitch, yaw].

    ``kernel_arguments(target)`` gives `adrc_attitude_torque`'s arguments up to the measurement; a compiled loop
    calling the kernel with them advances this controller's own state.
    """

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
        self.channel_states = np.zeros((3, CHANNEL_STATE_SIZE))  # the channels' states, one row each
        self.channels: list[AdrcChannel] = []
        for inertia, spec, state in zip(
            (Ix, Iy, Iz), (gains.roll, gains.pitch, gains.yaw), self.channel_states, strict=True
        ):
            if not (math.isfinite(inertia) and inertia > 0):
                raise AdrcParameterError(f"inertias must be positive, got {(Ix, Iy, Iz)}")
            spec = dict(spec)
            b0 = spec.pop("b0_scale", 1.0) / inertia
            parameters = channel_parameters(spec, b0)
            if not isinstance(parameters, AdrcChannelParameters):
                raise AdrcParameterError(f"the attitude loop's channels are nonlinear ADRC channels, got {spec}")
            self.channels.append(AdrcChannel(parameters, self.h, state))
        self.channel_params = np.stack([channel.kernel_params for channel in self.channels])
        self._use_rate = gains.use_measured_rate
        if not (math.isfinite(actuator_time_constant) and actuator_time_constant >= 0):
            raise AdrcParameterError(f"actuator_time_constant must be >= 0, got {actuator_time_constant}")
        self.actuator_time_constant = actuator_time_constant  # s; 0: the torque is applied as commanded
        # fraction of the way a first-order actuator moves toward its command in one step
        self._actuator_step = 1.0 - math.exp(-self.h / actuator_time_constant) if actuator_time_constant else 1.0
        self.loop_state = np.zeros(LOOP_STATE_SIZE)  # bookkeeping angles and modelled actuator (L_*)

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
        self.channel_states[:] = 0.0
        self.loop_state[:] = 0.0

    def kernel_arguments(self, target: AttitudeTarget) -> tuple:
        """`adrc_attitude_torque`'s first arguments for this controller (channel_params .. use_measured_rate)
        and, after the measurement, the target's quaternion and feed-forward rates: (before, qd, feedforward)."""
        qd = _floats(target.quaternion)
        feedforward = _NO_FEEDFORWARD if target.body_rates is None else _floats(target.body_rates)
        if qd.shape != (4,) or feedforward.shape != (3,):  # the kernel reads them unchecked
            raise ValueError(f"an attitude target needs a quaternion of 4 and body rates of 3, got {target}")
        state = (self.channel_params, self.channel_states, self.loop_state, self._actuator_step, self._use_rate)
        return state, qd, feedforward

    def update(self, target: AttitudeTarget, state: VehicleState, dt: float) -> np.ndarray:
        """Torque for this step. The channels are fixed-step at 1/rate_hz (the paper's discrete
        equations); dt only advances the gyro-integrated bookkeeping angles."""
        controller, qd, feedforward = self.kernel_arguments(target)
        torque = np.empty(3)
        adrc_attitude_torque(
            *controller, _floats(state.quaternion), _floats(state.angular_velocity), qd, feedforward, dt, torque
        )
        return torque

    def disturbance_estimates(self) -> dict[str, float]:
        """Each axis's ESO z3: total angular-acceleration disturbance in rad/s^2."""
        return {axis: channel.disturbance for axis, channel in zip(AXES, self.channels, strict=True)}


def _floats(values) -> np.ndarray:
    """A contiguous float64 copy-free view where possible, as the kernels take their vectors."""
    return np.ascontiguousarray(values, dtype=np.float64)
