"""Both loops' gains from the airframe and a few dimensionless design numbers (bandwidth parameterisation).

A controller family is tuned once, as ratios (`adrc_offboard/gains/design.json`, written by `python -m bench.tune`),
and its gains for any airframe follow from that airframe's envelope (`uavcore.envelope`):

- the attitude loop's bandwidth is a fraction (`attitude_bandwidth`) of what the motors allow, 1 / (4 tau);
  yaw's is `yaw_ratio` of it; the position loop's horizontal bandwidth is the attitude bandwidth divided by
  `separation` (time-scale separation of the cascade) and the vertical one is `vertical_ratio` times that; every
  loop's bandwidth is at most 0.1 rad/s per Hz of its sampling rate (5 rad/s at 50 Hz, 25 rad/s at 250 Hz);
- the ADRC's observers sit at `observer_ratio` (outer) and `attitude_observer_ratio` (inner) times their loop's
  bandwidth (Gao's bandwidth parameterisation, `adrc.bandwidth_parameters`), b0 = 1 (outer, acceleration) and 1/I
  (inner, torque); the feedback's acceleration bounds r1 are shares of the envelope's accelerations, the torque
  limits u_max shares of the mixer's authority about each axis;
- the paper-literal ADRC ("adrc_paper") is the same cascade with the paper's TD in the outer loop (its acceleration
  bound `td_ratio` times the envelope's horizontal acceleration) and the ESO's z2 as the rate (no measured velocity);
- the PID's position loop puts a critically damped pair at its bandwidth and an integrator pole at
  `integral_ratio` of it (`outer_loop.pid_gains_for_bandwidth`); its attitude loop is PX4's: an attitude P equal
  to the attitude bandwidth feeding a rate PID whose P is I w_r, w_r = `rate_ratio` times the attitude bandwidth,
  I and D as `rate_integral` (1/s per unit of w_r) and `rate_derivative` (s times w_r);
- the geometric controller (Lee et al. 2010) has kR = J w^2 and kOmega = 2 zeta J w at the attitude bandwidth.

The acceleration limits of every position loop are the envelope's (`acceleration_limits`), the tilt limit its
max_tilt_rad. Nothing here depends on Table 2: a new airframe file gets gains by the same rules.
"""

from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass
from importlib import resources
from typing import Any

from adrc_offboard.adrc import AdrcParameterError
from adrc_offboard.adrc_attitude import AdrcAttitudeGains
from adrc_offboard.geometric import GeometricGains, GeometricOuterLoop
from adrc_offboard.outer_loop import (
    AccelerationLimits,
    AdrcOuterGains,
    AdrcOuterLoop,
    PidOuterGains,
    PidOuterLoop,
    pid_gains_for_bandwidth,
)
from uavcore.airframe import Airframe
from uavcore.envelope import Envelope, envelope

FAMILIES = ("adrc", "adrc_paper", "pid", "geometric")
OUTER_RATE_HZ = 50.0
ATTITUDE_RATE_HZ = 250.0

# fixed shares, not tuned (why, beside each)
SAMPLED_BANDWIDTH_SHARE = 0.1  # rad/s per Hz: omega h <= 0.1, where a discrete loop still behaves as designed
RATE_LOOP_SHARE = 0.3  # the PID's rate loop (P-dominant, no observer) may go to omega h = 0.3 at the attitude rate
OUTER_DELTA_M = 0.02  # fal's linear zone in the position channels: above the 2 cm position noise
ATTITUDE_DELTA_RAD = 0.005  # ... in the attitude channels: above the 0.3 deg attitude noise
R1_SHARE = 0.85  # NLSEF acceleration bound as a share of what the actuator gives (room for the observer's z3)
ROLL_PITCH_TORQUE_SHARE = 0.65  # roll/pitch torque limit: leaves the mixer room for collective and yaw
YAW_TORQUE_SHARE = 0.95  # yaw is the mixer's last priority anyway; the turns need nearly all of it
TD_ACCEL_FACTOR = 3.5  # the inner TD's bound r0 over r1: the TD must outrun the feedback it feeds
TD_STEPS = 10  # the inner TD's filter factor h0 in steps: filters the attitude noise without a lag that matters
OUTER_TD_H0_S = 0.04  # the paper-literal outer TD's filter factor (2 steps at 50 Hz)
PID_I_MAX_SHARE = 2.0 / 3.0  # PID position integrator clamp as a share of the horizontal acceleration limit
PID_ROLL_INTEGRATOR_SHARE = 0.08  # rate-integrator clamps as shares of the axis's torque authority
PID_YAW_INTEGRATOR_SHARE = 0.6

CASCADE = ("attitude_bandwidth", "yaw_ratio", "separation", "vertical_ratio")  # every family's bandwidths
ADRC_OBSERVERS = ("observer_ratio", "attitude_observer_ratio")
DESIGN_PARAMETERS: dict[str, tuple[str, ...]] = {
    "adrc": (*CASCADE, *ADRC_OBSERVERS),
    "adrc_paper": (*CASCADE, *ADRC_OBSERVERS, "td_ratio"),
    "pid": (*CASCADE, "integral_ratio", "rate_ratio", "rate_integral", "rate_derivative"),
    "geometric": (*CASCADE, "attitude_damping"),
}


@dataclass(frozen=True)
class Design:
    """One family's design numbers (module docstring); `values` holds exactly DESIGN_PARAMETERS[family]."""

    family: str
    values: dict[str, float]

    def __post_init__(self) -> None:
        if self.family not in DESIGN_PARAMETERS:
            raise AdrcParameterError(f"unknown controller family {self.family!r}; one of {', '.join(FAMILIES)}")
        expected = set(DESIGN_PARAMETERS[self.family])
        if set(self.values) != expected:
            raise AdrcParameterError(
                f"design of {self.family!r} needs exactly {sorted(expected)}, got {sorted(self.values)}"
            )
        for name, value in self.values.items():
            if (
                isinstance(value, bool)
                or not isinstance(value, int | float)
                or not (math.isfinite(value) and value > 0)
            ):
                raise AdrcParameterError(f"design number {self.family}.{name} must be finite and positive: {value!r}")

    def __getattr__(self, name: str) -> float:
        try:
            return self.__dict__["values"][name]
        except KeyError:
            raise AttributeError(name) from None

    def bandwidths(self, airframe: Airframe) -> dict[str, float]:
        """Attitude (roll/pitch), yaw, horizontal and vertical position bandwidths in rad/s for `airframe`, each at
        most SAMPLED_BANDWIDTH_SHARE of its loop's sampling rate (a fast airframe's motors allow more than a 50 Hz
        position loop or a 250 Hz attitude loop can sample)."""
        attitude = min(
            self.attitude_bandwidth * envelope(airframe).attitude_bandwidth_limit,
            SAMPLED_BANDWIDTH_SHARE * ATTITUDE_RATE_HZ,
        )
        outer_cap = SAMPLED_BANDWIDTH_SHARE * OUTER_RATE_HZ
        horizontal = min(attitude / self.separation, outer_cap)
        return {
            "attitude": attitude,
            "yaw": self.yaw_ratio * attitude,
            "horizontal": horizontal,
            "vertical": min(self.vertical_ratio * horizontal, outer_cap),
        }


def load_designs() -> dict[str, Design]:
    """The shipped designs (adrc_offboard/gains/design.json): one per family."""
    data = json.loads(resources.files("adrc_offboard.gains").joinpath("design.json").read_text())
    return {family: Design(family, dict(data["families"][family]["design"])) for family in FAMILIES}


def load_design(family: str) -> Design:
    designs = load_designs()
    if family not in designs:
        raise AdrcParameterError(f"unknown controller family {family!r}; one of {', '.join(FAMILIES)}")
    return designs[family]


def acceleration_limits(airframe: Airframe) -> AccelerationLimits:
    """The position loops' acceleration limits: the envelope's."""
    env = envelope(airframe)
    return AccelerationLimits(env.max_horizontal_acc, env.max_up_acc, env.max_down_acc)


def adrc_outer_specs(airframe: Airframe, design: Design) -> dict[str, Any]:
    """The ADRC position loop as outer_adrc.json holds it (channel specs in the designer's form, b0 = 1): with
    `td_ratio` the paper's TD (r0, h0) and the ESO's z2 as the rate (adrc_paper)."""
    env, w = envelope(airframe), design.bandwidths(airframe)
    paper = design.family == "adrc_paper"

    def channel(omega_c: float, max_acc: float) -> dict[str, float]:
        spec = {
            "omega_c": omega_c,
            "omega_o": design.observer_ratio * omega_c,
            "delta": OUTER_DELTA_M,
            "r1": R1_SHARE * max_acc,
        }
        return spec | ({"r0": design.td_ratio * max_acc, "h0": OUTER_TD_H0_S} if paper else {})

    return {
        "use_measured_velocity": not paper,
        "horizontal": channel(w["horizontal"], env.max_horizontal_acc),
        "vertical": channel(w["vertical"], env.max_up_acc),
    }


def adrc_outer_gains(airframe: Airframe, design: Design) -> AdrcOuterGains:
    """The ADRC position loop's parsed channels for `airframe` (`adrc_outer_specs`)."""
    return AdrcOuterGains.from_dict(adrc_outer_specs(airframe, design))


def adrc_attitude_gains(airframe: Airframe, design: Design) -> AdrcAttitudeGains:
    """The ADRC attitude loop's channel specs (b0 = 1/I comes from the inertias in the controller)."""
    env, w = envelope(airframe), design.bandwidths(airframe)
    inertia = (airframe.ixx, airframe.iyy, airframe.izz)
    specs = []
    for axis in range(3):
        omega_c = w["yaw"] if axis == 2 else w["attitude"]
        u_max = (YAW_TORQUE_SHARE if axis == 2 else ROLL_PITCH_TORQUE_SHARE) * env.max_torque[axis]
        r1 = R1_SHARE * u_max / inertia[axis]
        specs.append(
            {
                "omega_c": omega_c,
                "omega_o": design.attitude_observer_ratio * omega_c,
                "delta": ATTITUDE_DELTA_RAD,
                "r1": r1,
                "r0": TD_ACCEL_FACTOR * r1,
                "h0": TD_STEPS / ATTITUDE_RATE_HZ,
                "u_max": u_max,
            }
        )
    return AdrcAttitudeGains(roll=specs[0], pitch=specs[1], yaw=specs[2], use_measured_rate=True)


def pid_outer_gains(airframe: Airframe, design: Design) -> PidOuterGains:
    env, w = envelope(airframe), design.bandwidths(airframe)
    i_max = PID_I_MAX_SHARE * env.max_horizontal_acc
    return PidOuterGains(
        pid_gains_for_bandwidth(w["horizontal"], design.integral_ratio, i_max),
        pid_gains_for_bandwidth(w["vertical"], design.integral_ratio, i_max),
    )


def pid_attitude_gains(airframe: Airframe, design: Design) -> dict[str, float]:
    """The vehicle's PX4-style attitude PID (sitl_quad.attitude_pid.PidAttitudeGains' fields, lower-case PX4
    names), as plain numbers: the vehicle builds its controller from them (this package does not import it)."""
    env, w = envelope(airframe), design.bandwidths(airframe)
    out: dict[str, float] = {"mc_roll_p": w["attitude"], "mc_pitch_p": w["attitude"], "mc_yaw_p": w["yaw"]}
    for axis, name, inertia in ((0, "roll", airframe.ixx), (1, "pitch", airframe.iyy), (2, "yaw", airframe.izz)):
        rate_bandwidth = min(
            design.rate_ratio * (w["yaw"] if axis == 2 else w["attitude"]), RATE_LOOP_SHARE * ATTITUDE_RATE_HZ
        )
        p = inertia * rate_bandwidth
        out[f"mc_{name}rate_p"] = p
        out[f"mc_{name}rate_i"] = p * design.rate_integral * rate_bandwidth
        out[f"mc_{name}rate_d"] = p * design.rate_derivative / rate_bandwidth
    out["mc_rr_int_lim"] = PID_ROLL_INTEGRATOR_SHARE * env.max_torque[0]
    out["mc_pr_int_lim"] = PID_ROLL_INTEGRATOR_SHARE * env.max_torque[1]
    out["mc_yr_int_lim"] = PID_YAW_INTEGRATOR_SHARE * env.max_torque[2]
    return out


def geometric_gains(airframe: Airframe, design: Design) -> GeometricGains:
    """Lee et al.'s gains: position kx = w^2, kv = 2 w per unit mass (critically damped at the position bandwidth);
    the attitude loop's bandwidths and damping, from which the vehicle's kR = J w^2, kOmega = 2 zeta J w."""
    w = design.bandwidths(airframe)
    return GeometricGains(
        kx_horizontal=w["horizontal"] ** 2,
        kv_horizontal=2.0 * w["horizontal"],
        kx_vertical=w["vertical"] ** 2,
        kv_vertical=2.0 * w["vertical"],
        omega_roll_pitch=w["attitude"],
        omega_yaw=w["yaw"],
        zeta=design.attitude_damping,
    )


def describe(airframe: Airframe, design: Design) -> dict[str, Any]:
    """What a design gives on an airframe, for reports: bandwidths and the envelope."""
    env: Envelope = envelope(airframe)
    return {"family": design.family, "design": design.values, "bandwidths": design.bandwidths(airframe)} | {
        "envelope": env.as_dict()
    }


def outer_loop_for(
    family: str, airframe: Airframe, design: Design | None = None, rate_hz: float = OUTER_RATE_HZ
) -> AdrcOuterLoop | PidOuterLoop | GeometricOuterLoop:
    """The position loop of `family` for `airframe` at its design (the shipped one by default), with the envelope's
    acceleration and tilt limits: what the offboard process and the benchmarks fly."""
    design = design if design is not None else load_design(family)
    if design.family != family:
        raise AdrcParameterError(f"a {design.family!r} design cannot build the {family!r} loop")
    env = envelope(airframe)
    common = {
        "mass": airframe.mass,
        "g": airframe.g,
        "max_thrust_n": airframe.max_thrust_n,  # normalises the thrust (the vehicle multiplies back by its own)
        "max_tilt_rad": env.max_tilt_rad,
        "limits": acceleration_limits(airframe),
        "rate_hz": rate_hz,
    }
    if family in ("adrc", "adrc_paper"):
        return AdrcOuterLoop(gains=adrc_outer_gains(airframe, design), **common)
    if family == "pid":
        return PidOuterLoop(gains=pid_outer_gains(airframe, design), **common)
    # Lee's law as published: its own safety tilt cap (GeometricGains.max_tilt_deg), no acceleration limits
    return GeometricOuterLoop(
        airframe.mass, airframe.g, airframe.max_thrust_n, geometric_gains(airframe, design), rate_hz
    )


def gains_files(airframe: Airframe, designs: dict[str, Design]) -> dict[str, dict[str, Any]]:
    """What the gains files (outer_adrc.json, outer_pid.json, outer_limits.json, attitude_adrc.json) hold: the
    shipped designs' gains on `airframe` (Table 2), written by `python -m bench.tune --write` (or --regenerate) so
    that a loop built from a file flies what one built from the design flies."""
    source = " Generated from design.json by `python -m bench.tune` (adrc_offboard/design.py's rules); edit the design."
    limits = acceleration_limits(airframe)
    pid = pid_outer_gains(airframe, designs["pid"])
    attitude = adrc_attitude_gains(airframe, designs["adrc"])
    geometric = geometric_gains(airframe, designs["geometric"])
    return {
        "outer_adrc.json": {
            "comment": "Outer-loop ADRC at 50 Hz, b0 = 1 (control = acceleration, m/s^2), designer's form: omega_c, "
            "omega_o in rad/s, delta in m, r1 = the feedback's acceleration bound (m/s^2). No TD: the navigator's "
            "setpoint velocity and acceleration are the reference rate and feed-forward. use_measured_velocity: the "
            "rate error uses the measured velocity instead of the ESO's z2 (false = the paper's ESO-only form)."
            + source,
            **adrc_outer_specs(airframe, designs["adrc"]),
        },
        "outer_pid.json": {
            "comment": "Outer-loop PID at 50 Hz: poles (s + wc)^2 (s + r wc) (outer_loop.pid_gains_for_bandwidth). "
            "kp 1/s^2, ki 1/s^3, kd 1/s, i_max m/s^2." + source,
            "horizontal": dataclasses.asdict(pid.horizontal),
            "vertical": dataclasses.asdict(pid.vertical),
        },
        "outer_limits.json": {
            "comment": "Desired-acceleration limits shared by the position loops (m/s^2): the airframe's envelope "
            "(uavcore/envelope.py)." + source,
            **dataclasses.asdict(limits),
        },
        "attitude_adrc.json": {
            "comment": "Inner-loop ADRC at 250 Hz. Control is torque (N m), b0 = 1/I. omega_c, omega_o in rad/s; delta "
            "in rad; r1 = feedback angular-acceleration bound (rad/s^2); r0 = TD acceleration bound; h0 = TD filter "
            "factor (s); u_max in N m, a share of the mixer's torque authority about the axis around hover." + source,
            "use_measured_rate": attitude.use_measured_rate,
            "roll": attitude.roll,
            "pitch": attitude.pitch,
            "yaw": attitude.yaw,
        },
        "geometric.json": {
            "comment": "Geometric tracking controller on SE(3) (Lee, Leok, McClamroch 2010; adrc_offboard/geometric.py)"
            ". "
            "Position gains per unit mass: kx in 1/s^2, kv in 1/s (the paper's k_x, k_v are m times these), the "
            "critically damped pair at the design's position bandwidth; no integral action (the paper has none). "
            "attitude: the vehicle's geometric inner loop (MC_ATT_CTRL = 2) has k_R = J w^2, k_Omega = 2 zeta J w, "
            "w in rad/s. max_tilt_deg: a safety cap on the commanded tilt (the paper has none but thrust "
            "saturation)." + source,
            "horizontal": {"kx": geometric.kx_horizontal, "kv": geometric.kv_horizontal},
            "vertical": {"kx": geometric.kx_vertical, "kv": geometric.kv_vertical},
            "attitude": {
                "omega_roll_pitch": geometric.omega_roll_pitch,
                "omega_yaw": geometric.omega_yaw,
                "zeta": geometric.zeta,
            },
            "max_tilt_deg": geometric.max_tilt_deg,
        },
    }
