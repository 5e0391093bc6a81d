"""The flight envelope an airframe allows: what its controllers may ask of it, derived from its parameters.

Both cascades used to carry fixed limits tuned for the Table 2 airframe (6 m/s^2, 35 deg tilt, 4 N m): on a lighter
or heavier airframe those are either out of reach or a fraction of what it can do. Here every limit follows from
the airframe (thrust-to-weight, arm, lift and drag coefficients, rotor-speed range, inertia, motor lag), with the
policy choices named:

- `THRUST_RESERVE` (20 % of the full thrust) is kept for attitude control: the collective never asks for more than
  the rest, so a tilt or climb at the limit still leaves the mixer room for the torques that hold the attitude. On
  a heavily loaded airframe that would leave less than 10 % above its weight, the reserve shrinks (to 5 % at
  least): it flies gently (small tilt, slow climb) rather than not at all; below a thrust-to-weight of 1.16 it is
  refused, naming the figure.
- Tilt: the largest tilt at which the usable thrust still carries the weight, cos(tilt) = m g / T_usable, capped at
  `MAX_TILT_POLICY_RAD` (45 deg, PX4's MPC_TILTMAX_AIR default). Horizontal acceleration: g tan(tilt), what that
  tilt gives at constant altitude.
- Climb: T_usable / m - g, capped at `MAX_UP_POLICY` (one g). Sink: gravity less the thrust that keeps every rotor
  at `MIN_ROTOR_THRUST_SHARE` of its hover thrust (the rotors stay spinning enough to hold the attitude), capped
  at `MAX_DOWN_POLICY` (PX4's MPC_ACC_DOWN_MAX, 3 m/s^2: a quadrotor sinking fast enters its own downwash).
- Torque: what the mixer delivers about each axis around hover without a rotor leaving its speed range
  (sitl_quad.rotors' eq. 3: four rotors, arm L on roll and pitch, L kf on yaw).
- Attitude bandwidth: a loop cannot be much faster than the motors that drive it; `attitude_bandwidth_limit` is
  1 / (MOTOR_LAG_SEPARATION tau), tau the motor time constant (12.5 rad/s for Table 2's 0.02 s). Yaw's weak
  authority (drag torque, about 1/70 of roll's angular acceleration on Table 2) is the loop's acceleration bound,
  not its bandwidth: its gains keep the bandwidth and bound the feedback's acceleration (adrc_offboard.design).

Pure computation on `uavcore.airframe.Airframe`; the controllers' gains are derived from it in adrc_offboard.design.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from uavcore.airframe import Airframe, ModelParameterError

THRUST_RESERVE = 0.2
MIN_THRUST_RESERVE = 0.05
MIN_MANOEUVRE_MARGIN = 0.1
MAX_TILT_POLICY_RAD = math.radians(45.0)
MAX_UP_POLICY_G = 1.0
MAX_DOWN_POLICY = 3.0
MIN_ROTOR_THRUST_SHARE = 0.25
MOTOR_LAG_SEPARATION = 4.0


@dataclass(frozen=True)
class Envelope:
    """What an airframe allows its controllers to ask (module docstring)."""

    thrust_to_weight: float
    usable_thrust_n: float  # collective thrust the position loops may ask for, N
    max_tilt_rad: float
    max_horizontal_acc: float  # m/s^2
    max_up_acc: float  # m/s^2
    max_down_acc: float  # m/s^2
    max_torque: tuple[float, float, float]  # N m about body x, y, z around hover
    max_angular_acc: tuple[float, float, float]  # rad/s^2: max_torque / inertia
    attitude_bandwidth_limit: float  # rad/s

    def as_dict(self) -> dict[str, float | list[float]]:
        return {k: list(v) if isinstance(v, tuple) else v for k, v in self.__dict__.items()}


def hover_torque_authority(airframe: Airframe) -> tuple[float, float, float]:
    """Body torque (N m) the mixer can add about x, y and z at hover before a rotor reaches its speed limit.

    At hover every rotor turns at Omega_h (s_h = Omega_h^2); a roll or pitch torque moves two rotors up and two down
    by the same squared speed, a yaw torque the two pairs of opposite spin (rotors.rotor_wrench), so the room is
    4 min(s_max - s_h, s_h - s_min) times L kl (roll, pitch) or L kf (yaw)."""
    s_hover = airframe.hover_rotor_speed**2
    room = 4.0 * min(airframe.rotor_speed_max**2 - s_hover, s_hover - airframe.rotor_speed_min**2)
    room = max(room, 0.0)
    lift = airframe.arm_length * airframe.kl * room
    return lift, lift, airframe.arm_length * airframe.kf * room


def envelope(airframe: Airframe) -> Envelope:
    """The envelope of `airframe` (module docstring)."""
    weight = airframe.mass * airframe.g
    # the reserve shrinks (to MIN_THRUST_RESERVE) on an airframe that would otherwise keep less than
    # MIN_MANOEUVRE_MARGIN above its weight: a heavily loaded vehicle flies gently rather than not at all
    usable = max((1.0 - THRUST_RESERVE) * airframe.max_thrust_n, (1.0 + MIN_MANOEUVRE_MARGIN) * weight)
    usable = min(usable, (1.0 - MIN_THRUST_RESERVE) * airframe.max_thrust_n)
    if usable < (1.0 + MIN_MANOEUVRE_MARGIN) * weight:
        needed = (1.0 + MIN_MANOEUVRE_MARGIN) / (1.0 - MIN_THRUST_RESERVE)
        raise ModelParameterError(
            f"the airframe's thrust ({airframe.max_thrust_n:.3g} N, thrust-to-weight {airframe.thrust_to_weight:.2f}) "
            f"leaves no room to manoeuvre once {MIN_THRUST_RESERVE:.0%} is kept for attitude control: it needs a "
            f"thrust-to-weight of at least {needed:.2f}"
        )
    tilt = min(math.acos(weight / usable), MAX_TILT_POLICY_RAD)
    up = max(0.0, min(usable / airframe.mass - airframe.g, MAX_UP_POLICY_G * airframe.g))
    min_thrust = MIN_ROTOR_THRUST_SHARE * weight
    down = max(0.0, min(airframe.g - min_thrust / airframe.mass, MAX_DOWN_POLICY))
    torque = hover_torque_authority(airframe)
    inertia = (airframe.ixx, airframe.iyy, airframe.izz)
    angular = tuple(t / i for t, i in zip(torque, inertia, strict=True))
    return Envelope(
        thrust_to_weight=airframe.thrust_to_weight,
        usable_thrust_n=usable,
        max_tilt_rad=tilt,
        max_horizontal_acc=airframe.g * math.tan(tilt),
        max_up_acc=up,
        max_down_acc=down,
        max_torque=(torque[0], torque[1], torque[2]),
        max_angular_acc=(angular[0], angular[1], angular[2]),
        attitude_bandwidth_limit=1.0 / (MOTOR_LAG_SEPARATION * airframe.motor_time_constant),
    )
