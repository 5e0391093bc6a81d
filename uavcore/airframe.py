"""The quadrotor's physical parameters as plain data: the paper's Table 2 plus the simulator's own choices.

Every field is a float so the vehicle can map MAVLink parameters onto them by name (``Airframe.replace``) and
the physics kernel can take them as one flat array (``Airframe.as_array``, field order).

Choices beyond Table 2, and why:
- ``motor_time_constant`` 0.02 s: first-order lag from rotor-speed command to rotor speed, typical of a
  1-1.5 kg quadrotor's ESC + motor + propeller. The paper's filter constant tau_D = 0.0023 s (eq. 5, 8) is
  ten times faster; it belongs to its channel model G_e, a filtered differentiator, not to a motor.
- ``rotor_speed_max`` 500 rad/s: hover needs sqrt(m g / (4 kl)) = 334.5 rad/s, so the thrust-to-weight ratio
  is (500 / 334.5)^2 = 2.23, the usual ~2 of a camera quadrotor.
- drag (body axes, against the air-relative velocity): horizontal 0.10 N/(m/s) linear + 0.017 N/(m/s)^2
  quadratic gives 2.7 N at 10 m/s, i.e. a steady tilt of atan(2.7 / (m g)) = 12 deg when cruising at the
  paper's 10 m/s in still air; vertical 0.20 + 0.05 (a larger area faces the vertical flow).
"""

from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

TABLE2_PATH = Path(__file__).parent / "airframes" / "table2.json"


class ModelParameterError(ValueError):
    """A simulator or controller parameter is unknown, missing or out of range (the message says which)."""


@dataclass(frozen=True)
class Airframe:
    """Quadrotor parameters. Defaults are Table 2 of the paper (see ``airframes/table2.json``)."""

    mass: float = 1.3  # kg
    ixx: float = 0.085  # kg m^2, roll inertia
    iyy: float = 0.083  # kg m^2, pitch inertia
    izz: float = 0.151  # kg m^2, yaw inertia
    arm_length: float = 0.5  # m, the paper's L: moment arm of every rotor about the roll and pitch axes
    kl: float = 2.85e-5  # N s^2, lift coefficient: rotor thrust = kl * Omega^2
    kf: float = 7.47e-7  # N s^2, the paper's drag coefficient kf: yaw moment = L * kf * sum(+-Omega^2), eq. (1)
    g: float = 9.81  # m/s^2
    motor_time_constant: float = 0.02  # s, first-order rotor-speed lag
    rotor_speed_min: float = 0.0  # rad/s
    rotor_speed_max: float = 500.0  # rad/s
    drag_linear_xy: float = 0.10  # N/(m/s), body x and y
    drag_quadratic_xy: float = 0.017  # N/(m/s)^2, body x and y
    drag_linear_z: float = 0.20  # N/(m/s), body z
    drag_quadratic_z: float = 0.05  # N/(m/s)^2, body z

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
                raise ModelParameterError(f"airframe parameter {f.name} must be a finite number, got {value!r}")
            object.__setattr__(self, f.name, float(value))
        for name in ("mass", "ixx", "iyy", "izz", "arm_length", "kl", "kf", "g", "motor_time_constant"):
            if getattr(self, name) <= 0:
                raise ModelParameterError(f"airframe parameter {name} must be positive, got {getattr(self, name)}")
        for name in ("rotor_speed_min", "drag_linear_xy", "drag_quadratic_xy", "drag_linear_z", "drag_quadratic_z"):
            if getattr(self, name) < 0:
                raise ModelParameterError(f"airframe parameter {name} must be >= 0, got {getattr(self, name)}")
        if self.rotor_speed_max <= self.rotor_speed_min:
            raise ModelParameterError("airframe parameter rotor_speed_max must exceed rotor_speed_min")

    @classmethod
    def field_names(cls) -> tuple[str, ...]:
        return tuple(f.name for f in dataclasses.fields(cls))

    @classmethod
    def table2(cls) -> Airframe:
        """The paper's Table 2 vehicle, read from the packaged data file."""
        return cls.from_file(TABLE2_PATH)

    @classmethod
    def from_file(cls, path: str | Path) -> Airframe:
        """Load a JSON object of field -> number; missing fields keep Table 2's values, keys starting with
        ``_`` are comments. Raises ModelParameterError for an unreadable file or an unknown field."""
        try:
            data = json.loads(Path(path).read_text())
        except (OSError, json.JSONDecodeError) as error:
            raise ModelParameterError(f"cannot read airframe file {path}: {error}") from error
        if not isinstance(data, dict):
            raise ModelParameterError(f"airframe file {path} must hold a JSON object")
        values = {key: value for key, value in data.items() if not key.startswith("_")}
        return cls().replace(**values)

    def replace(self, **changes: float) -> Airframe:
        """A copy with some fields changed by name; unknown names raise ModelParameterError."""
        unknown = sorted(set(changes) - set(self.field_names()))
        if unknown:
            raise ModelParameterError(f"unknown airframe parameter(s): {', '.join(unknown)}")
        return dataclasses.replace(self, **changes)

    def as_array(self) -> np.ndarray:
        """The fields as float64 in declaration order, for the physics kernel."""
        return np.array([getattr(self, name) for name in self.field_names()], dtype=np.float64)

    @property
    def hover_rotor_speed(self) -> float:
        """rad/s at which the four rotors together carry the weight: sqrt(m g / (4 kl)), from eq. (3)."""
        return math.sqrt(self.mass * self.g / (4.0 * self.kl))

    @property
    def max_thrust_n(self) -> float:
        """Collective thrust with every rotor at rotor_speed_max, N."""
        return 4.0 * self.kl * self.rotor_speed_max**2

    @property
    def hover_thrust(self) -> float:
        """Hover thrust as a fraction of max_thrust_n (the normalised thrust of AttitudeTarget)."""
        return self.mass * self.g / self.max_thrust_n

    @property
    def thrust_to_weight(self) -> float:
        return self.max_thrust_n / (self.mass * self.g)


# Index of each field in Airframe.as_array(); the numba kernel reads the array through these constants.
_INDEX = {name: i for i, name in enumerate(Airframe.field_names())}
P_MASS = _INDEX["mass"]
P_IXX = _INDEX["ixx"]
P_IYY = _INDEX["iyy"]
P_IZZ = _INDEX["izz"]
P_ARM = _INDEX["arm_length"]
P_KL = _INDEX["kl"]
P_KF = _INDEX["kf"]
P_G = _INDEX["g"]
P_MOTOR_TAU = _INDEX["motor_time_constant"]
P_OMEGA_MIN = _INDEX["rotor_speed_min"]
P_OMEGA_MAX = _INDEX["rotor_speed_max"]
P_DRAG_LIN_XY = _INDEX["drag_linear_xy"]
P_DRAG_QUAD_XY = _INDEX["drag_quadratic_xy"]
P_DRAG_LIN_Z = _INDEX["drag_linear_z"]
P_DRAG_QUAD_Z = _INDEX["drag_quadratic_z"]
