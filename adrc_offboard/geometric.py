"""The geometric tracking controller on SE(3) of Lee, Leok and McClamroch: its outer (position) part.

T. Lee, M. Leok, N. H. McClamroch, "Geometric tracking control of a quadrotor UAV on SE(3)", 49th IEEE CDC,
2010, pp. 5420-5425 (equation numbers as in the paper and its arXiv version 1003.2005): the controller most
quadrotor simulators ship as their reference (RotorPy's SE3Control, ...), here a third baseline beside the ADRC
and the PID cascades. Its attitude half is the vehicle's inner loop MC_ATT_CTRL = 2 (sitl_quad.attitude_geometric);
this module is the offboard outer loop, with the `uavcore.control.OuterLoopController` interface of
`adrc_offboard.outer_loop`'s AdrcOuterLoop and PidOuterLoop, at the same rate and on the same measurements.

The paper's frame is NED-like (e3 points down, m xdd = m g e3 - f R e3, eq. 2), so its equations hold as written
in NED with R the body (FRD) -> world rotation. With e_x = x - x_d, e_v = v - v_d (eq. 6, 7) and gains per unit
mass (acceleration gains, kx = k_x / m, kv = k_v / m, diagonal: horizontal for north and east, vertical for down):

    F     = m (kx e_x + kv e_v + g e3 - xdd_d)      the force the rotors must push with, in -b3: minus the
                                                    paper's -k_x e_x - k_v e_v - m g e3 + m xdd_d
    b3d   = F / |F|                                 (eq. 12: the desired body z axis, down)
    b2d   = b3d x b1d / |b3d x b1d|, Rd = [b2d x b3d, b2d, b3d]   (Sec. III-B, b1d from the setpoint's yaw)
    f     = F . R e3                                (eq. 15: projected on the *current* body z axis)

The target sent is Rd as a quaternion, the normalised thrust f / max thrust clipped to [0, 1] and the body-rate
feed-forward Rd^T e3 yaw_rate (the setpoint's yaw rate in the target's body axes, as the other outer loops send:
uavcore.rotation.acceleration_to_attitude). Note Lee's b1 is b1d projected on the plane normal to b3d, so the
target's heading differs from the yaw setpoint when the thrust is tilted obliquely to the heading (worst case
over directions, measured: 0.3 deg at 1 m/s^2 of horizontal demand, 1.2 deg at 2, 9 deg at 6 m/s^2);
acceleration_to_attitude keeps the heading exact instead. The paper's construction is kept.

Limits: the paper has none but thrust saturation (here the clip to [0, 1] of the airframe's maximum). It has no
acceleration limits (the other outer loops' `AccelerationLimits`) and no integral action. As a safety net only,
the commanded tilt is capped at `GeometricGains.max_tilt_deg` (60 deg in gains/geometric.json, far above the
35 deg of the other loops and above what the missions ask), keeping F's vertical part, and F is never allowed
to point up (b3d at least 0.1 g downward), which would ask the vehicle to flip.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from adrc_offboard.adrc import AdrcParameterError
from adrc_offboard.gains import load_gains
from uavcore.rotation import quat_from_matrix
from uavcore.state import AttitudeTarget, TrajectorySetpoint, VehicleState

AXES = ("x", "y", "z")


def _positive(name: str, value: Any) -> float:
    if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
        raise AdrcParameterError(f"geometric gain {name} must be finite and positive, got {value!r}")
    return float(value)


@dataclass(frozen=True)
class GeometricGains:
    """Lee's gains: position kx (1/s^2), kv (1/s) per unit mass, horizontal and vertical; the attitude loop's
    bandwidths (rad/s) and damping, from which the vehicle's k_R = J w^2, k_Omega = 2 zeta J w; the safety tilt
    cap (deg)."""

    kx_horizontal: float = 4.0
    kv_horizontal: float = 4.0
    kx_vertical: float = 6.25
    kv_vertical: float = 5.0
    omega_roll_pitch: float = 12.0
    omega_yaw: float = 4.0
    zeta: float = 1.0
    max_tilt_deg: float = 60.0

    def __post_init__(self) -> None:
        for name in self.__dataclass_fields__:
            _positive(name, getattr(self, name))
        if not self.max_tilt_deg < 90.0:
            raise AdrcParameterError(f"max_tilt_deg must lie in (0, 90), got {self.max_tilt_deg!r}")

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> GeometricGains:
        unknown = set(data) - {"horizontal", "vertical", "attitude", "max_tilt_deg", "comment"}
        if unknown or "horizontal" not in data or "vertical" not in data:
            raise AdrcParameterError(f"geometric gains need 'horizontal' and 'vertical'; got {sorted(data)}")
        values: dict[str, Any] = {}
        try:
            for axis in ("horizontal", "vertical"):
                spec = dict(data[axis])
                if set(spec) != {"kx", "kv"}:
                    raise AdrcParameterError(f"geometric {axis} gains need exactly kx and kv, got {sorted(spec)}")
                values[f"kx_{axis}"], values[f"kv_{axis}"] = spec["kx"], spec["kv"]
            attitude = dict(data.get("attitude", {}))
            if set(attitude) - {"omega_roll_pitch", "omega_yaw", "zeta"}:
                raise AdrcParameterError(f"unknown geometric attitude gains {sorted(attitude)}")
            values.update(attitude)
        except (TypeError, ValueError) as exc:
            raise AdrcParameterError(f"bad geometric gains {data}: {exc}") from exc
        if "max_tilt_deg" in data:
            values["max_tilt_deg"] = data["max_tilt_deg"]
        return cls(**values)

    @classmethod
    def load(cls, source: str | Path = "geometric") -> GeometricGains:
        return cls.from_dict(load_gains(source))

    @classmethod
    def for_bandwidth(cls, omega_c_horizontal: float, omega_c_vertical: float, **others: float) -> GeometricGains:
        """The critically damped pair kx = wc^2, kv = 2 wc per axis (the other outer loops' bandwidth)."""
        wh, wv = _positive("omega_c_horizontal", omega_c_horizontal), _positive("omega_c_vertical", omega_c_vertical)
        return cls(kx_horizontal=wh * wh, kv_horizontal=2 * wh, kx_vertical=wv * wv, kv_vertical=2 * wv, **others)


class GeometricOuterLoop:
    """Lee's position law (module docstring): setpoint + estimate -> attitude target. No observer, no integrator."""

    def __init__(
        self,
        mass: float,
        g: float,
        max_thrust_n: float,
        gains: GeometricGains | None = None,
        rate_hz: float = 50.0,
    ) -> None:
        for name, value in (("mass", mass), ("g", g), ("max_thrust_n", max_thrust_n), ("rate_hz", rate_hz)):
            _positive(name, value)
        if max_thrust_n <= mass * g:
            raise AdrcParameterError(f"max thrust {max_thrust_n} N cannot lift {mass} kg")
        self.mass, self.g, self.max_thrust_n = mass, g, max_thrust_n
        self.gains = gains if gains is not None else GeometricGains.load()
        k = self.gains
        self._kx = (k.kx_horizontal, k.kx_horizontal, k.kx_vertical)
        self._kv = (k.kv_horizontal, k.kv_horizontal, k.kv_vertical)
        self._tan_tilt = math.tan(math.radians(k.max_tilt_deg))
        self.h = 1.0 / rate_hz
        self._telemetry: dict[str, float] = {}

    def reset(self) -> None:
        """Nothing to forget: the law has no state."""

    def update(self, setpoint: TrajectorySetpoint, estimate: VehicleState, dt: float) -> AttitudeTarget:
        position, velocity = estimate.position.tolist(), estimate.velocity.tolist()
        reference, reference_rate = setpoint.position.tolist(), setpoint.velocity.tolist()
        reference_acc = setpoint.acceleration.tolist()
        # eq. (6), (7): e_x = x - x_d, e_v = v - v_d; the wanted acceleration xdd_d - kx e_x - kv e_v
        demanded = [
            reference_acc[i]
            - self._kx[i] * (position[i] - reference[i])
            - self._kv[i] * (velocity[i] - reference_rate[i])
            for i in range(3)
        ]
        # F = m (kx e_x + kv e_v + g e3 - xdd_d): minus the paper's vector in eq. (12) and (15), pointing along b3
        fx, fy, fz = (-self.mass * demanded[0], -self.mass * demanded[1], self.mass * (self.g - demanded[2]))
        fz = max(fz, 0.1 * self.mass * self.g)  # safety: never ask for b3d pointing up (a flip)
        horizontal = math.hypot(fx, fy)
        if horizontal > fz * self._tan_tilt:  # safety tilt cap (module docstring), keeping the vertical part
            scale = fz * self._tan_tilt / horizontal
            fx, fy = fx * scale, fy * scale
        norm = math.sqrt(fx * fx + fy * fy + fz * fz)
        b3 = np.array([fx, fy, fz]) / norm  # eq. (12)
        b1d = np.array([math.cos(setpoint.yaw), math.sin(setpoint.yaw), 0.0])
        b2 = np.cross(b3, b1d)
        b2 /= np.linalg.norm(b2)  # b3d is never horizontal (fz > 0), so b3d x b1d never vanishes
        b1 = np.cross(b2, b3)
        rd = np.column_stack([b1, b2, b3])
        # eq. (15): f = F . R e3, R e3 the current body z axis (third column of R(q))
        w, x, y, z = estimate.quaternion.tolist()
        body_z = (2.0 * (x * z + w * y), 2.0 * (y * z - w * x), 1.0 - 2.0 * (x * x + y * y))
        thrust_n = fx * body_z[0] + fy * body_z[1] + fz * body_z[2]
        thrust = min(1.0, max(0.0, thrust_n / self.max_thrust_n))
        body_rates = rd[2, :] * float(setpoint.yaw_rate)  # Rd^T e3 yaw_rate: the third row of Rd
        self._telemetry = {f"acc_demand_{a}": v for a, v in zip(AXES, demanded, strict=True)}
        self._telemetry.update(thrust_n=thrust_n, force_n=norm, tilt_deg=math.degrees(math.acos(min(1.0, b3[2]))))
        return AttitudeTarget(quaternion=quat_from_matrix(rd), thrust=thrust, body_rates=body_rates)

    def disturbance_estimates(self) -> dict[str, float]:
        return {}  # no observer

    def telemetry(self) -> dict[str, float]:
        return dict(self._telemetry)
