"""The robustness conditions, as data: each a name, a group and what it changes from the nominal short flight.

The nominal flight is bench.control.scenario.short_scenario: the reference route's longest leg and the next (a turn
between), 10 m/s at 5 m, 5 m/s crosswind, the 4 m/s 1-cosine gust halfway along the first leg, Dryden sigma
1 m/s, D-term variance 0.05, sitl_quad.sensors' default noise, the Table 2 airframe. A condition's keys:

- true_airframe: {field or "inertia" or "drag": factor}: the vehicle's real airframe is Table 2 with these
  fields scaled ("inertia" = ixx, iyy, izz; "drag" = the four drag_* coefficients); the controllers keep the
  nominal Table 2 (VehicleConfig.design_airframe): model error;
- airframe_file: another airframe (uavcore/airframes/NAME) that the controllers also know (design = true),
  flown at the shipped designs, with the gains and limits derived for it (adrc_offboard.design);
- wind_mean_m_s: the mean crosswind, with the gust and the Dryden intensity scaled with it (gust 0.8 x mean,
  sigma 0.2 x mean, as 4 and 1 m/s are at the nominal 5 m/s);
- wander: {"std_m_s", "time_constant_s"}: the mean wind wanders (sitl_quad.wind's Ornstein-Uhlenbeck drift);
- wind_pulse: {"amplitude_m_s", "duration_s"}: the paper's T = [0.5, 0.6] s disturbance: instead of the nominal
  gust, a step-like wind change of that amplitude lasting duration_s (1-cosine edges of 10 ms), at the gust's
  instant halfway along the first leg;
- d_variance: the D terms' variance on every channel (DisturbanceConfig; the paper's is 15), held 0.5 s;
- noise_scale: every sensor-noise standard deviation times this; delay_s: sensor delay (SensorNoise.delay_s).
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from bench.control.scenario import Scenario
from sitl_quad.config import VehicleConfig
from sitl_quad.disturbances import DisturbanceConfig
from sitl_quad.sensors import SensorNoise
from uavcore.airframe import TABLE2_PATH, Airframe

AIRFRAMES_DIR = TABLE2_PATH.parent
NOMINAL_WIND_M_S = 5.0
GUST_PER_MEAN = 0.8
PULSE_EDGE_S = 0.01

CONDITIONS: list[dict] = [
    {"name": "nominal", "group": "nominal"},
    # model error: the vehicle differs from the model the controllers are designed for
    {"name": "mass-30%", "group": "model", "true_airframe": {"mass": 0.7}},
    {"name": "mass+30%", "group": "model", "true_airframe": {"mass": 1.3}},
    {"name": "inertia-30%", "group": "model", "true_airframe": {"inertia": 0.7}},
    {"name": "inertia+30%", "group": "model", "true_airframe": {"inertia": 1.3}},
    {"name": "motor_tau_x0.5", "group": "model", "true_airframe": {"motor_time_constant": 0.5}},
    {"name": "motor_tau_x2", "group": "model", "true_airframe": {"motor_time_constant": 2.0}},
    {"name": "motor_tau_x3", "group": "model", "true_airframe": {"motor_time_constant": 3.0}},
    {"name": "thrust_kl-20%", "group": "model", "true_airframe": {"kl": 0.8}},
    {"name": "thrust_kl+20%", "group": "model", "true_airframe": {"kl": 1.2}},
    {"name": "yaw_kf-20%", "group": "model", "true_airframe": {"kf": 0.8}},
    {"name": "yaw_kf+20%", "group": "model", "true_airframe": {"kf": 1.2}},
    {"name": "drag_x0", "group": "model", "true_airframe": {"drag": 0.0}},
    {"name": "drag_x3", "group": "model", "true_airframe": {"drag": 3.0}},
    # wind
    {"name": "wind_0", "group": "wind", "wind_mean_m_s": 0.0},
    {"name": "wind_4", "group": "wind", "wind_mean_m_s": 4.0},
    {"name": "wind_8", "group": "wind", "wind_mean_m_s": 8.0},
    {"name": "wind_12", "group": "wind", "wind_mean_m_s": 12.0},
    {"name": "wind_wander_3ms_30s", "group": "wind", "wander": {"std_m_s": 3.0, "time_constant_s": 30.0}},
    # the paper's disturbances
    {"name": "wind_pulse_0.1s_8ms", "group": "paper", "wind_pulse": {"amplitude_m_s": 8.0, "duration_s": 0.1}},
    {"name": "d_var_0.05", "group": "paper", "d_variance": 0.05},
    {"name": "d_var_0.5", "group": "paper", "d_variance": 0.5},
    {"name": "d_var_2", "group": "paper", "d_variance": 2.0},
    {"name": "d_var_5", "group": "paper", "d_variance": 5.0},
    {"name": "d_var_15", "group": "paper", "d_variance": 15.0},
    # sensors
    {"name": "noise_x0", "group": "sensors", "noise_scale": 0.0},
    {"name": "noise_x3", "group": "sensors", "noise_scale": 3.0},
    {"name": "delay_20ms", "group": "sensors", "delay_s": 0.02},
    {"name": "delay_60ms", "group": "sensors", "delay_s": 0.06},
    # other airframes (each family at its shipped design: gains and limits derived for the airframe)
    {"name": "airframe_hummingbird_0.5kg", "group": "airframe", "airframe_file": "hummingbird.json"},
    {"name": "airframe_x500_3kg", "group": "airframe", "airframe_file": "x500_3kg.json"},
]
BY_NAME = {c["name"]: c for c in CONDITIONS}
GROUPS = tuple(dict.fromkeys(c["group"] for c in CONDITIONS))


def select(spec: str | None) -> list[dict]:
    """Conditions named (or whose group is named) in the comma-separated spec; all for None."""
    if not spec:
        return list(CONDITIONS)
    wanted = [s.strip() for s in spec.split(",") if s.strip()]
    unknown = [w for w in wanted if w not in BY_NAME and w not in GROUPS]
    if unknown:
        raise ValueError(f"unknown condition(s) {', '.join(unknown)}: names {', '.join(BY_NAME)}; groups {GROUPS}")
    return [c for c in CONDITIONS if c["name"] in wanted or c["group"] in wanted]


def scaled_airframe(base: Airframe, factors: dict[str, float]) -> Airframe:
    changes: dict[str, float] = {}
    for name, factor in factors.items():
        fields = {"inertia": ("ixx", "iyy", "izz"), "drag": tuple(f for f in base.field_names() if "drag" in f)}
        for field in fields.get(name, (name,)):
            changes[field] = getattr(base, field) * factor
    return base.replace(**changes)


def build(condition: dict, base: Scenario) -> tuple[VehicleConfig, Scenario]:
    """The vehicle's configuration and the scenario (its wind, for the gust metrics) of one condition (each
    controller's inner loop is set on it by bench.control.flight.configure_vehicle)."""
    scenario = base
    config = base.config()
    nominal = config.airframe
    if "true_airframe" in condition:
        config.airframe = scaled_airframe(nominal, condition["true_airframe"])
        config.design_airframe = nominal
    if "airframe_file" in condition:
        config.airframe = Airframe.from_file(Path(AIRFRAMES_DIR) / condition["airframe_file"])
    wind = base.wind
    if "wind_mean_m_s" in condition:
        scale = condition["wind_mean_m_s"] / NOMINAL_WIND_M_S
        wind = replace(
            wind,
            speed_m_s=condition["wind_mean_m_s"],
            gust_amplitude_m_s=GUST_PER_MEAN * condition["wind_mean_m_s"],
            turbulence_w20_m_s=base.wind.turbulence_w20_m_s * scale,
        )
    if "wander" in condition:
        w = condition["wander"]
        wind = replace(wind, wander_std_m_s=w["std_m_s"], wander_time_constant_s=w["time_constant_s"])
    if "wind_pulse" in condition:
        p = condition["wind_pulse"]
        wind = replace(
            wind,
            gust_amplitude_m_s=p["amplitude_m_s"],
            gust_rise_time_s=PULSE_EDGE_S,
            gust_hold_s=max(p["duration_s"] - PULSE_EDGE_S, 0.0),
        )
    if wind != base.wind:
        config.wind = wind
        scenario = replace(base, wind=wind)
    if "d_variance" in condition:
        v = condition["d_variance"]
        config.disturbance = DisturbanceConfig(v, v, v, v, v, v, base.disturbance.sample_time_s)
    noise = config.sensor_noise
    if "noise_scale" in condition:
        k = condition["noise_scale"]
        noise = SensorNoise(
            noise.position_std_m * k, noise.velocity_std_m_s * k, noise.attitude_std_rad * k, noise.gyro_std_rad_s * k
        )
    if "delay_s" in condition:
        noise = replace(noise, delay_s=condition["delay_s"])
    config.sensor_noise = noise
    return config, scenario
