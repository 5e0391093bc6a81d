"""The route energy model: what a buoy mission draws from the battery, phase by phase, in the forecast wind.

A mission as the ground station uploads it (gcs.domain.planning.mission_items) and the navigator flies it
(sitl_quad.navigator, PX4's): the motors spool up, the vehicle climbs vertically to the mission altitude, then
for each buoy it turns on the spot toward the buoy, flies a straight rest-to-rest leg at the commanded speed
and hovers there for the dwell; the return (RTL) climbs to the return altitude if lower, turns home, flies the
leg and descends (fast, then slowly below the slow-down height) until touchdown is confirmed. The commanded
speed is a GROUND speed (DO_CHANGE_SPEED type 1, PX4's MPC_XY_CRUISE): the reference moves over the ground,
so the wind does not change when the vehicle is where; it changes what the rotors must do.

Kinematics (times). Every motion follows the navigator's limits: a leg of length d is a jerk-limited S-curve
(speed V, acceleration A, jerk J): ramps of V/A + A/J each and a cruise at V, or a lower peak on short legs
(planner.scenario.rest_to_rest_s); a turn of angle dpsi is a trapezoid in yaw (rate r, yaw acceleration
alpha); climbs and descents are vertical S-curves. Each mission item adds ``item_overhead_s`` of hover (the
hand-over ticks and the wait for the vehicle to enter the acceptance radius), the landing adds the touchdown
confirmation.

Power (what the simulator's battery sees, sitl_quad.battery). Each rotor's shaft power is Q Omega = kf Omega^3
and its thrust kl Omega^2, so a rotor's electrical power is proportional to its thrust^1.5; with the four
rotor thrusts T_i written as fractions tau_i of the hover share m g / 4,
    P = P_avionics + P_rotor_hover * (1/4) sum_i tau_i^1.5 + c_turb sigma^2 (1 + |v_air| / v_turb)      (1)
P_rotor_hover is the rotors' electrical power at hover thrust (fitted; the momentum-free prior is
kf (m g / kl)^1.5 / (2 eta) = 147 W for Table 2 and eta = 0.76). The total thrust vector balances
    m a = T + D(v_air, attitude) + m g,   v_air = v_ground - w                                          (2)
with the body-axis drag D_k = -s_D (c_k + q_k |v_k|) v_k of the airframe (s_D fitted, 1 = the airframe's
figures) evaluated in the body axes the thrust direction and the heading define (solved by fixed-point
iteration: the drag tilts the thrust, which turns the drag). So the power depends on the AIR velocity: a head
wind raises it (a larger airspeed), a tail wind lowers it, a cross wind raises it (the vehicle keeps its nose
along the track and meets the cross wind on its side); hovering at a buoy in wind costs the drag of the wind
speed. Accelerations add m a to the thrust. The rotors share the thrust equally except in a yaw acceleration
psi'', where the yaw torque I_z psi'' = L kf sum(+-Omega_i^2) shifts Delta = kl I_z psi'' / (4 L kf) of
thrust between the two pairs: tau_i = (T / 4 +- Delta) / (m g / 4), and the convexity of tau^1.5 makes turns
cost more than the hover they are flown in. The simulator's rotors have no inflow (their power follows
thrust alone), so climbing costs only its extra thrust (drag, acceleration); a real rotor would add
m g v_z / eta, which the model carries as ``climb_work_fraction`` (0 here). The last term is the control
activity in turbulence: sigma^2 is the Dryden variance (sigma_u^2 + sigma_v^2 + sigma_w^2) the forecast's
W20 gives at the flight altitude, growing with the airspeed (c_turb fitted, v_turb held at 10 m/s).

Energy = the integral of (1) over the phases; constant-velocity spans are integrated exactly, the ramps on a
fine grid. ``route_energy`` evaluates a given visiting order exactly (its turns included);
``calibrated_sortie_cost`` builds the planner's ``SortieCost`` (planner.sortie_cost), whose legs cannot know
the previous heading, so each leg carries a turn of the mean turn angle of planned routes (``mean_turn_deg``).

Parameters are data: planner/energy_params.json, written by ``python -m bench.energy_model`` (the fit against
the simulator) and read by ``EnergyModel.load``; it names the airframe, pack and controller it was fitted for,
so a vehicle that differs shows (``EnergyModel.mismatches``). Fitted on 16 simulated ADRC flights, it
predicts 16 held-out ones (other buoy sets, seeds, wind directions) within 0.23 % mean, 0.72 % worst
(planner/README.md, bench/results/energy_model.json).
"""

from __future__ import annotations

import itertools
import json
import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path

import numpy as np

from planner.distances import check_points, euclidean_matrix
from planner.errors import InputError
from planner.motion_profiles import Span, descent_spans, ramp_duration, rest_to_rest_spans, sample_spans
from planner.sortie_cost import WH_PER_J, EnergyBudget, SortieCost
from uavcore.airframe import Airframe

PARAMS_PATH = Path(__file__).with_name("energy_params.json")
RAMP_STEP_S = 0.05  # integration grid of the non-constant parts of a motion
FEET_M = 0.3048


# ----- parameters
@dataclass(frozen=True)
class VehicleTerms:
    """The physical vehicle the model stands for (the simulator's Table 2 airframe and its power chain)."""

    mass_kg: float = 1.3
    g: float = 9.81
    drag_linear_xy: float = 0.10  # N/(m/s), body x and y
    drag_quadratic_xy: float = 0.017  # N/(m/s)^2
    drag_linear_z: float = 0.20
    drag_quadratic_z: float = 0.05
    yaw_inertia_kg_m2: float = 0.151
    arm_length_m: float = 0.5
    lift_coefficient: float = 2.85e-5  # kl: rotor thrust = kl Omega^2
    drag_torque_coefficient: float = 7.47e-7  # kf: the yaw torque is L kf sum(+-Omega^2) (the paper's eq. 1)
    avionics_w: float = 8.0  # drawn while armed, whatever the rotors do

    @property
    def weight_n(self) -> float:
        return self.mass_kg * self.g

    @classmethod
    def from_airframe(cls, airframe: Airframe, avionics_w: float) -> VehicleTerms:
        """The terms of an airframe (uavcore.airframe: Table 2 and the simulator's drag) and its avionics load."""
        return cls(
            mass_kg=airframe.mass,
            g=airframe.g,
            drag_linear_xy=airframe.drag_linear_xy,
            drag_quadratic_xy=airframe.drag_quadratic_xy,
            drag_linear_z=airframe.drag_linear_z,
            drag_quadratic_z=airframe.drag_quadratic_z,
            yaw_inertia_kg_m2=airframe.izz,
            arm_length_m=airframe.arm_length,
            lift_coefficient=airframe.kl,
            drag_torque_coefficient=airframe.kf,
            avionics_w=avionics_w,
        )


@dataclass(frozen=True)
class NavigatorTerms:
    """How the navigator flies (PX4's mission defaults, mirrored by sitl_quad.navigator.NavigatorConfig)."""

    acceleration_m_s2: float = 3.0  # MPC_ACC_HOR, also the vertical ramps
    jerk_m_s3: float = 4.0  # MPC_JERK_AUTO
    climb_speed_m_s: float = 2.5  # MPC_Z_VEL_MAX_UP
    descent_speed_m_s: float = 1.5  # MPC_Z_VEL_MAX_DN
    land_speed_m_s: float = 0.7  # MPC_LAND_SPEED
    land_slowdown_altitude_m: float = 5.0  # MPC_LAND_ALT2
    land_target_depth_m: float = 0.5  # the landing reference ends this far under the ground
    yaw_rate_deg_s: float = 60.0  # MPC_YAWRAUTO_MAX
    yaw_acceleration_deg_s2: float = 45.0
    rtl_altitude_m: float = 10.0  # RTL_RETURN_ALT
    spool_up_s: float = 1.0  # COM_SPOOLUP_TIME
    touchdown_confirm_s: float = 1.0  # the land detector's confirmation before the disarm
    initial_heading_deg: float = 0.0  # the vehicle stands facing north


@dataclass(frozen=True)
class FittedTerms:
    """What the calibration against flights determines (defaults: the physical priors before any fit)."""

    rotor_hover_w: float = 147.0  # rotors' electrical power at hover thrust, calm air
    drag_scale: float = 1.0  # s_D of eq. (2)
    turbulence_w_per_m2s2: float = 0.0  # c_turb of eq. (1): W per (m/s)^2 of Dryden variance, at hover
    turbulence_speed_m_s: float = 10.0  # v_turb of eq. (1): the turbulence term doubles at this airspeed
    item_overhead_s: float = 0.3  # hover per mission item beyond the reference's own timeline
    landing_overhead_s: float = 0.0  # hover beyond the touchdown confirmation
    climb_work_fraction: float = 0.0  # share of m g v_z / eta a climb adds (0: the simulator's rotors)
    mean_turn_deg: float = 90.0  # SortieCost legs carry one turn of this angle (mean of planned routes)


@dataclass(frozen=True)
class EnergyModel:
    """The model's parameters; ``fitted_for`` records what they were fitted on (airframe, pack, controller)."""

    vehicle: VehicleTerms = field(default_factory=VehicleTerms)
    navigator: NavigatorTerms = field(default_factory=NavigatorTerms)
    fitted: FittedTerms = field(default_factory=FittedTerms)
    fitted_for: dict = field(default_factory=dict)

    @classmethod
    def load(cls, path: str | Path = PARAMS_PATH) -> EnergyModel:
        """The parameters in a JSON file (default: the committed calibration)."""
        return cls.from_dict(json.loads(Path(path).read_text()))

    @classmethod
    def from_dict(cls, data: dict) -> EnergyModel:
        """From the JSON layout ``to_dict`` writes; unknown or missing terms raise InputError."""
        try:
            return cls(
                vehicle=_terms(VehicleTerms, data["vehicle"]),
                navigator=_terms(NavigatorTerms, data["navigator"]),
                fitted=_terms(FittedTerms, data["fitted"]),
                fitted_for=dict(data.get("fitted_for", {})),
            )
        except (KeyError, TypeError) as error:
            raise InputError(f"energy parameters need vehicle, navigator and fitted sections: {error}") from None

    def to_dict(self) -> dict:
        return {
            "vehicle": asdict(self.vehicle),
            "navigator": asdict(self.navigator),
            "fitted": asdict(self.fitted),
            "fitted_for": self.fitted_for,
        }

    def with_fitted(self, **changes: float) -> EnergyModel:
        return replace(self, fitted=replace(self.fitted, **changes))

    def mismatches(self, vehicle: VehicleTerms) -> list[str]:
        """Which physical terms of ``vehicle`` differ from those the parameters were fitted for."""
        mine = asdict(self.vehicle)
        return [
            f"{name}: fitted for {mine[name]:g}, given {value:g}"
            for name, value in asdict(vehicle).items()
            if not math.isclose(mine[name], value, rel_tol=1e-9)
        ]


def _terms(cls, values: dict):
    names = {f.name for f in fields(cls)}
    unknown = sorted(set(values) - names)
    if unknown:
        raise InputError(f"unknown {cls.__name__} term(s): {', '.join(unknown)}")
    return cls(**{k: float(v) for k, v in values.items()})


@dataclass(frozen=True)
class RouteFlight:
    """How a mission is flown (the ground station's flight parameters)."""

    altitude_m: float = 5.0
    speed_m_s: float = 10.0  # commanded ground speed along each leg
    dwell_s: float = 1.0  # hover at each buoy

    def __post_init__(self) -> None:
        if not (self.altitude_m > 0 and self.speed_m_s > 0 and self.dwell_s >= 0):
            raise InputError(f"flight needs altitude > 0, speed > 0 and dwell >= 0; got {self}")


@dataclass(frozen=True)
class WindForecast:
    """The forecast air: a mean wind (compass degrees it comes FROM) and Dryden turbulence of intensity W20 (the
    wind speed at 20 ft; None = the mean wind speed, the usual reading of a forecast)."""

    speed_m_s: float = 0.0
    from_deg: float = 0.0
    turbulence_w20_m_s: float | None = None

    def __post_init__(self) -> None:
        w20 = self.turbulence_w20_m_s
        if not (self.speed_m_s >= 0 and math.isfinite(self.from_deg) and (w20 is None or w20 >= 0)):
            raise InputError(f"wind needs speed >= 0, a finite direction and W20 >= 0; got {self}")

    @property
    def velocity_en(self) -> np.ndarray:
        """The air's velocity [east, north] m/s (it blows TOWARD from_deg + 180)."""
        angle = math.radians(self.from_deg)
        return -self.speed_m_s * np.array([math.sin(angle), math.cos(angle)])

    def variance_m2_s2(self, altitude_m: float) -> float:
        """sigma_u^2 + sigma_v^2 + sigma_w^2 of MIL-F-8785C's low-altitude Dryden model at altitude_m (h in feet
        clamped to 10..1000 ft): sigma_w = 0.1 W20, sigma_u = sigma_v = sigma_w / (0.177 + 0.000823 h)^0.4."""
        w20 = self.speed_m_s if self.turbulence_w20_m_s is None else self.turbulence_w20_m_s
        h_ft = min(max(altitude_m / FEET_M, 10.0), 1000.0)
        sigma_w = 0.1 * w20
        sigma_u = sigma_w / (0.177 + 0.000823 * h_ft) ** 0.4
        return 2.0 * sigma_u**2 + sigma_w**2


# ----- power, eq. (1) and (2)
def electrical_power_w(
    model: EnergyModel,
    air_velocity: np.ndarray,
    acceleration: np.ndarray,
    heading_en: np.ndarray,
    yaw_acceleration: np.ndarray | float = 0.0,
    turbulence_variance: np.ndarray | float = 0.0,
) -> np.ndarray:
    """Electrical power (W) at each of N instants: air_velocity and acceleration (N, 3) [east, north, up] m/s and
    m/s^2 (the vehicle's velocity relative to the air, its acceleration over the ground), heading_en (N, 2) unit
    vectors of the nose, yaw_acceleration (N,) rad/s^2; turbulence_variance the Dryden sigma^2 (m/s)^2."""
    v, f = model.vehicle, model.fitted
    air = np.atleast_2d(np.asarray(air_velocity, dtype=float))
    need = v.mass_kg * np.atleast_2d(np.asarray(acceleration, dtype=float)) + np.array([0.0, 0.0, v.weight_n])
    nose = np.zeros_like(air)
    nose[:, :2] = np.atleast_2d(heading_en)
    drag = _body_drag(model, air, nose, np.broadcast_to(np.array([0.0, 0.0, 1.0]), air.shape))  # level first
    for _ in range(4):  # the drag tilts the thrust, the tilt turns the drag: converges in a few rounds
        thrust = need - drag
        z_body = thrust / np.linalg.norm(thrust, axis=1, keepdims=True)
        drag = _body_drag(model, air, nose, z_body)
    thrust_n = np.linalg.norm(need - drag, axis=1)
    shift = (
        v.lift_coefficient
        * v.yaw_inertia_kg_m2
        * np.asarray(yaw_acceleration, dtype=float)
        / (4.0 * v.arm_length_m * v.drag_torque_coefficient)
    )
    share = v.weight_n / 4.0
    pair_a = np.clip((thrust_n / 4.0 + shift) / share, 0.0, None)
    pair_b = np.clip((thrust_n / 4.0 - shift) / share, 0.0, None)
    rotors = f.rotor_hover_w * 0.5 * (pair_a**1.5 + pair_b**1.5)
    airspeed = np.linalg.norm(air, axis=1)
    turbulence = f.turbulence_w_per_m2s2 * turbulence_variance * (1.0 + airspeed / f.turbulence_speed_m_s)
    climb = f.climb_work_fraction * v.weight_n * np.clip(air[:, 2], 0.0, None) * f.rotor_hover_w / _hover_shaft_w(v)
    return v.avionics_w + rotors + turbulence + climb


def _hover_shaft_w(v: VehicleTerms) -> float:
    """Shaft power of the ideal momentum-free rotors at hover: kf (m g / kl)^1.5 / 2 (so P_rotor_hover / this is
    1 / eta, the electrical watts per shaft watt)."""
    return v.drag_torque_coefficient * (v.weight_n / v.lift_coefficient) ** 1.5 / 2.0


def _body_drag(model: EnergyModel, air: np.ndarray, nose: np.ndarray, z_body: np.ndarray) -> np.ndarray:
    """World-frame drag of the air velocity in the body axes: z along the thrust, x the nose's heading made
    perpendicular to it (sitl_quad.rigid_body's per-axis linear + quadratic drag)."""
    v, scale = model.vehicle, model.fitted.drag_scale
    x_body = nose - np.sum(nose * z_body, axis=1, keepdims=True) * z_body
    x_body /= np.linalg.norm(x_body, axis=1, keepdims=True)
    y_body = np.cross(z_body, x_body)
    drag = np.zeros_like(air)
    for axis, linear, quadratic in (
        (x_body, v.drag_linear_xy, v.drag_quadratic_xy),
        (y_body, v.drag_linear_xy, v.drag_quadratic_xy),
        (z_body, v.drag_linear_z, v.drag_quadratic_z),
    ):
        along = np.sum(air * axis, axis=1, keepdims=True)
        drag -= scale * (linear + quadratic * np.abs(along)) * along * axis
    return drag


# ----- phases: each a block of samples; a route's blocks share one evaluation of eq. (1)
@dataclass(frozen=True)
class Phase:
    """One part of a mission: its kind, the mission item it belongs to, its duration and energy."""

    name: str  # spool-up, climb, turn, leg, dwell, overhead, descent, touchdown
    item: int  # 0 the take-off, k the k-th buoy, -1 the return and landing
    time_s: float
    energy_wh: float


@dataclass(frozen=True)
class _Block:
    """A phase before evaluation: its samples' durations and what the power depends on at each."""

    name: str
    item: int
    dt: np.ndarray  # (N,) s
    air: np.ndarray  # (N, 3) velocity relative to the air [east, north, up]
    accel: np.ndarray  # (N, 3) acceleration over the ground
    nose: np.ndarray  # (N, 2) heading unit vectors
    yaw_accel: np.ndarray  # (N,) rad/s^2
    variance: float  # turbulence sigma^2


@dataclass(frozen=True)
class RouteEnergy:
    """A mission's predicted duration and energy, start command to disarm, and its phases."""

    phases: list[Phase]

    @property
    def time_s(self) -> float:
        return float(sum(p.time_s for p in self.phases))

    @property
    def energy_wh(self) -> float:
        return float(sum(p.energy_wh for p in self.phases))

    def by_item(self) -> dict[int, tuple[float, float]]:
        """(time s, energy Wh) per mission item: 0 take-off, 1..n the buoys (turn, leg, dwell), -1 the return."""
        out: dict[int, tuple[float, float]] = {}
        for p in self.phases:
            t, e = out.get(p.item, (0.0, 0.0))
            out[p.item] = (t + p.time_s, e + p.energy_wh)
        return out

    def by_name(self) -> dict[str, float]:
        """Energy (Wh) per kind of phase."""
        out: dict[str, float] = {}
        for p in self.phases:
            out[p.name] = out.get(p.name, 0.0) + p.energy_wh
        return out


def _evaluate(model: EnergyModel, parts: Sequence[Phase | _Block]) -> list[Phase]:
    """Eq. (1) over every block's samples in one call; phases already evaluated pass through."""
    blocks = [p for p in parts if isinstance(p, _Block) and p.dt.size]
    energy_j = {}
    if blocks:
        power = electrical_power_w(
            model,
            np.concatenate([b.air for b in blocks]),
            np.concatenate([b.accel for b in blocks]),
            np.concatenate([b.nose for b in blocks]),
            np.concatenate([b.yaw_accel for b in blocks]),
            np.concatenate([np.full(b.dt.size, b.variance) for b in blocks]),
        )
        dt = np.concatenate([b.dt for b in blocks])
        starts = np.cumsum([0] + [b.dt.size for b in blocks[:-1]])
        energy_j = {id(b): e for b, e in zip(blocks, np.add.reduceat(power * dt, starts), strict=True)}
    return [
        p
        if isinstance(p, Phase)
        else Phase(p.name, p.item, float(p.dt.sum()), float(energy_j.get(id(p), 0.0)) * WH_PER_J)
        for p in parts
    ]


class _Air:
    """The forecast as the phases need it: the wind vector (3,), the turbulence variance at one altitude."""

    def __init__(self, wind: WindForecast, altitude_m: float) -> None:
        self.velocity = np.array([*wind.velocity_en, 0.0])
        self.variance = wind.variance_m2_s2(altitude_m)


STILL_AIR = WindForecast()


def _motion(name: str, item: int, spans: list[Span], direction: np.ndarray, nose_en: np.ndarray, air: _Air) -> _Block:
    """A straight motion along the unit vector `direction` (3,) [east, north, up], the nose on nose_en."""
    dt, speed, accel = sample_spans(spans, RAMP_STEP_S)
    n = dt.size
    return _Block(
        name,
        item,
        dt,
        speed[:, None] * direction - air.velocity,
        accel[:, None] * direction,
        np.broadcast_to(nose_en, (n, 2)),
        np.zeros(n),
        air.variance,
    )


def _hover(name: str, item: int, seconds: float, nose_en: np.ndarray, air: _Air) -> _Block:
    seconds = max(seconds, 0.0)
    dt = np.array([seconds]) if seconds > 0.0 else np.zeros(0)
    n = dt.size
    return _Block(
        name, item, dt, np.broadcast_to(-air.velocity, (n, 3)), np.zeros((n, 3)), np.broadcast_to(nose_en, (n, 2)),
        np.zeros(n), air.variance,
    )  # fmt: skip


def _turn(model: EnergyModel, item: int, heading_from: float, heading_to: float, air: _Air) -> _Block:
    """A turn on the spot from one compass heading (rad) to another, the short way: a trapezoid in yaw."""
    nav = model.navigator
    angle = (heading_to - heading_from + math.pi) % (2.0 * math.pi) - math.pi
    rate, accel = math.radians(nav.yaw_rate_deg_s), math.radians(nav.yaw_acceleration_deg_s2)
    dt, yaw_rate, yaw_accel = sample_spans(rest_to_rest_spans(abs(angle), rate, accel, math.inf), RAMP_STEP_S)
    turned = np.cumsum(yaw_rate * dt) - 0.5 * yaw_rate * dt  # angle turned at each sample's midpoint
    heading = heading_from + math.copysign(1.0, angle) * turned
    n = dt.size
    nose = np.column_stack([np.sin(heading), np.cos(heading)])
    return _Block(
        "turn", item, dt, np.broadcast_to(-air.velocity, (n, 3)), np.zeros((n, 3)), nose, yaw_accel, air.variance
    )


def _bearing(start: np.ndarray, end: np.ndarray) -> float:
    """Compass bearing (rad) from one [east, north] point to another."""
    east, north = end - start
    return math.atan2(east, north)


def turn_angles_deg(route_en, initial_heading_deg: float = 0.0) -> list[float]:
    """|Heading change| (deg) before each leg of a mission over route_en (depot first; the return leg included)."""
    route = np.asarray(route_en, dtype=float).reshape(-1, 2)
    closed = np.vstack([route, route[:1]])
    headings = [math.radians(initial_heading_deg), *(_bearing(a, b) for a, b in itertools.pairwise(closed))]
    return [abs(math.degrees((b - a + math.pi) % (2.0 * math.pi) - math.pi)) for a, b in itertools.pairwise(headings)]


def _nose(heading: float) -> np.ndarray:
    return np.array([math.sin(heading), math.cos(heading)])


UP, DOWN = np.array([0.0, 0.0, 1.0]), np.array([0.0, 0.0, -1.0])


def _takeoff(model: EnergyModel, flight: RouteFlight, wind: WindForecast) -> list[Phase | _Block]:
    """Spool-up on the ground (the rotors ramp to hover thrust: tau^1.5 averages 0.4 over a linear ramp), the
    vertical climb to the mission altitude, the item's hand-over."""
    nav, air = model.navigator, _Air(wind, flight.altitude_m)
    nose = _nose(math.radians(nav.initial_heading_deg))
    spool_w = model.vehicle.avionics_w + 0.4 * model.fitted.rotor_hover_w
    climb = rest_to_rest_spans(flight.altitude_m, nav.climb_speed_m_s, nav.acceleration_m_s2, nav.jerk_m_s3)
    return [
        Phase("spool-up", 0, nav.spool_up_s, spool_w * nav.spool_up_s * WH_PER_J),
        _motion("climb", 0, climb, UP, nose, air),
        _hover("overhead", 0, model.fitted.item_overhead_s, nose, air),
    ]


def _leg(model: EnergyModel, item: int, start: np.ndarray, end: np.ndarray, speed: float, air: _Air) -> _Block:
    """The straight leg from start to end (a rest-to-rest S-curve), the nose along it."""
    nav = model.navigator
    length = float(np.hypot(*(end - start)))
    direction = np.array([*((end - start) / max(length, 1e-9)), 0.0])
    spans = rest_to_rest_spans(length, speed, nav.acceleration_m_s2, nav.jerk_m_s3)
    return _motion("leg", item, spans, direction, _nose(_bearing(start, end)), air)


def _return_climb(model: EnergyModel, flight: RouteFlight, heading: float, wind: WindForecast) -> list[_Block]:
    """RTL's climb to the return altitude, when the mission flies lower."""
    nav = model.navigator
    rise = nav.rtl_altitude_m - flight.altitude_m
    if rise <= 0.0:
        return []
    spans = rest_to_rest_spans(rise, nav.climb_speed_m_s, nav.acceleration_m_s2, nav.jerk_m_s3)
    return [_motion("climb", -1, spans, UP, _nose(heading), _Air(wind, flight.altitude_m))]


def _landing(model: EnergyModel, height: float, heading: float, wind: WindForecast) -> list[_Block]:
    """The descent from `height` to touchdown and the land detector's confirmation (at hover power: the
    controller keeps about the weight on the rotors until the disarm)."""
    nav = model.navigator
    spans = descent_spans(
        height,
        nav.land_target_depth_m,
        nav.descent_speed_m_s,
        min(nav.land_speed_m_s, nav.descent_speed_m_s),
        nav.land_slowdown_altitude_m,
        nav.acceleration_m_s2,
        nav.jerk_m_s3,
    )
    hold = nav.touchdown_confirm_s + model.fitted.landing_overhead_s
    return [
        _motion("descent", -1, spans, DOWN, _nose(heading), _Air(wind, height)),
        _hover("touchdown", -1, hold, _nose(heading), _Air(STILL_AIR, 0.0)),
    ]


def _return_altitude(model: EnergyModel, flight: RouteFlight) -> float:
    return max(flight.altitude_m, model.navigator.rtl_altitude_m)


def route_energy(route_en, flight: RouteFlight, wind: WindForecast, model: EnergyModel | None = None) -> RouteEnergy:
    """Energy of a mission over `route_en`: the depot (home, the take-off point) then the buoys in visiting order,
    [east, north] metres; the return home (RTL) and the landing close it. A route of the depot alone is a
    take-off and a landing."""
    model = model or EnergyModel.load()
    return RouteEnergy(_evaluate(model, _route_parts(route_en, flight, wind, model)))


def route_timeline(route_en, flight: RouteFlight, model: EnergyModel | None = None) -> list[Phase]:
    """The phases of a mission over `route_en` (as route_energy) with their durations only (energy 0): the same
    motions, not integrated for power, so it is cheap. Its sum is route_energy's time_s (durations do not depend on
    the wind: the commanded speeds are ground speeds)."""
    model = model or EnergyModel.load()
    parts = _route_parts(route_en, flight, STILL_AIR, model)
    return [p if isinstance(p, Phase) else Phase(p.name, p.item, float(p.dt.sum()), 0.0) for p in parts]


def _route_parts(route_en, flight: RouteFlight, wind: WindForecast, model: EnergyModel) -> list[Phase | _Block]:
    """The phases of a mission over route_en, before evaluation (route_energy, route_timeline)."""
    route = np.asarray(route_en, dtype=float).reshape(-1, 2)
    if len(route) < 1 or not np.all(np.isfinite(route)):
        raise InputError("a route needs the depot and finite [east, north] coordinates")
    air = _Air(wind, flight.altitude_m)
    parts = _takeoff(model, flight, wind)
    heading = math.radians(model.navigator.initial_heading_deg)
    for k in range(1, len(route)):
        bearing = _bearing(route[k - 1], route[k])
        nose = _nose(bearing)
        parts += [
            _turn(model, k, heading, bearing, air),
            _leg(model, k, route[k - 1], route[k], flight.speed_m_s, air),
            _hover("dwell", k, flight.dwell_s, nose, air),
            _hover("overhead", k, model.fitted.item_overhead_s, nose, air),
        ]
        heading = bearing
    if len(route) == 1:
        return [*parts, *_landing(model, flight.altitude_m, heading, wind)]
    parts += _return_climb(model, flight, heading, wind)
    home_air = _Air(wind, _return_altitude(model, flight))
    bearing = _bearing(route[-1], route[0])
    parts += [
        _turn(model, -1, heading, bearing, home_air),
        _leg(model, -1, route[-1], route[0], flight.speed_m_s, home_air),
    ]
    return [*parts, *_landing(model, _return_altitude(model, flight), bearing, wind)]


# ----- the planner's SortieCost
LEG_TABLE_BEARINGS = 360  # the legs' bearing table: 1 degree apart
EXACT_LEGS_MAX = 2 * LEG_TABLE_BEARINGS  # fewer legs than the table would evaluate are each evaluated exactly


def leg_durations_s(length_m, speed: float, navigator: NavigatorTerms) -> np.ndarray:
    """Duration of straight rest-to-rest legs of these lengths (any shape) at `speed`: the navigator's S-curve
    (uavcore.motion_profiles.rest_to_rest_spans, what sitl_quad.trajectory flies). A leg at least as long as its
    two speed ramps (the knee, V x ramp) takes d / V + one ramp's duration (two ramps at the mean speed V / 2, the
    cruise between); a shorter one peaks lower and is evaluated span by span. The one leg-time function of the
    planners: the sortie cost (calibrated_sortie_cost) and the fleet's (planner.fleet_time) both take it."""
    length = np.asarray(length_m, dtype=float)
    ramp = ramp_duration(speed, navigator.acceleration_m_s2, navigator.jerk_m_s3)
    out = np.where(length > 0.0, length / speed + ramp, 0.0)
    short = np.argwhere((length > 0.0) & (length < speed * ramp))
    for index in map(tuple, short):
        spans = rest_to_rest_spans(float(length[index]), speed, navigator.acceleration_m_s2, navigator.jerk_m_s3)
        out[index] = sum(span[0] for span in spans)
    return out


def _legs(model: EnergyModel, starts: np.ndarray, ends: np.ndarray, speed: float, air: _Air):
    """(time s, energy Wh) of every straight leg starts[i] -> ends[j] (as _leg): arrays (len(starts), len(ends));
    the times are leg_durations_s'.

    A leg long enough to reach the cruise speed (2 ramps: the knee) costs its two ramps plus the cruise in
    between, whose power depends on the bearing only: so beyond the knee its energy is exactly linear in its
    length, E(d, b) = E(knee, b) + P(b) (d - knee) / V. Many legs are therefore evaluated on a table of bearings
    (two lengths each, interpolated between bearings 1 degree apart: the power is smooth in the bearing) and
    only the legs shorter than the knee one by one; few legs are all evaluated one by one. A 500-buoy cost takes
    seconds, not the minutes of 250 000 evaluations."""
    nav = model.navigator
    delta = ends[None, :, :] - starts[:, None, :]
    length = np.hypot(delta[..., 0], delta[..., 1])
    knee = speed * ramp_duration(speed, nav.acceleration_m_s2, nav.jerk_m_s3)
    one_by_one = np.argwhere((length < knee) | (length.size <= EXACT_LEGS_MAX))
    energy_wh = np.zeros(length.shape)
    if len(one_by_one):
        legs = _evaluate(model, [_leg(model, 0, starts[i], ends[j], speed, air) for i, j in one_by_one])
        energy_wh[tuple(one_by_one.T)] = [leg.energy_wh for leg in legs]
    tabled = length >= knee if length.size > EXACT_LEGS_MAX else np.zeros(length.shape, dtype=bool)
    if tabled.any():
        bearings = np.linspace(-math.pi, math.pi, LEG_TABLE_BEARINGS, endpoint=False)
        units = np.column_stack([np.sin(bearings), np.cos(bearings)])
        lengths = (knee, knee + 100.0)
        table = _evaluate(model, [_leg(model, 0, np.zeros(2), u * d, speed, air) for d in lengths for u in units])
        at_knee = np.array([leg.energy_wh for leg in table[:LEG_TABLE_BEARINGS]])
        per_m = (np.array([leg.energy_wh for leg in table[LEG_TABLE_BEARINGS:]]) - at_knee) / 100.0
        bearing = np.arctan2(delta[..., 0], delta[..., 1])[tabled]
        period = 2.0 * math.pi
        extra = length[tabled] - knee
        energy_wh[tabled] = np.interp(bearing, bearings, at_knee, period=period) + extra * np.interp(
            bearing, bearings, per_m, period=period
        )
    return leg_durations_s(length, speed, nav), energy_wh


def calibrated_sortie_cost(
    points,
    budget: EnergyBudget,
    flight: RouteFlight | None = None,
    wind: WindForecast | None = None,
    model: EnergyModel | None = None,
) -> SortieCost:
    """The SortieCost of planar points ((n, 2) [east, north] metres, node 0 the depot = home) under this model.

    Leg i -> j (j a buoy): a turn of ``mean_turn_deg``, the leg at the mission altitude, the item's hand-over.
    Leg i -> 0, the return: the climb to the return altitude if lower, a mean turn, the leg at the return
    altitude. Dwell: the hover at a buoy in the wind. Fixed per sortie: spool-up, climb, the take-off's
    hand-over, descent and touchdown. A sortie's sum is ``route_energy`` of its order but for the turn angles."""
    model = model or EnergyModel.load()
    flight = flight or RouteFlight()
    wind = wind or WindForecast()
    if not 0.0 <= budget.reserve < 1.0 or not budget.capacity_wh > 0:
        raise InputError(f"battery capacity must be > 0 and reserve in [0, 1); got {budget}")
    pts = check_points(points)
    n = len(pts)
    air, home_air = _Air(wind, flight.altitude_m), _Air(wind, _return_altitude(model, flight))
    blocks = _sortie_blocks(model, flight, wind)
    energy = {name: sum(p.energy_wh for p in _evaluate(model, parts)) for name, parts in blocks.items()}
    times = sortie_times(flight, model)
    # every leg i -> j: out to a buoy at the mission altitude, or home (j = 0) at the return altitude
    leg_time, leg_energy = np.zeros((n, n)), np.zeros((n, n))
    for targets, leg_air, extra in ((slice(1, None), air, "per_buoy"), (slice(0, 1), home_air, "home")):
        time_s, energy_wh = _legs(model, pts, pts[targets], flight.speed_m_s, leg_air)
        leg_time[:, targets] = time_s + (times.per_buoy_s if extra == "per_buoy" else times.return_s)
        leg_energy[:, targets] = energy_wh + energy[extra]
    np.fill_diagonal(leg_time, 0.0)
    np.fill_diagonal(leg_energy, 0.0)
    dwell_time, dwell_energy = np.full(n, times.dwell_s), np.full(n, energy["dwell"])
    dwell_time[0] = dwell_energy[0] = 0.0
    return SortieCost(
        leg_time_s=leg_time,
        leg_energy_wh=leg_energy,
        leg_distance_m=euclidean_matrix(pts),
        dwell_time_s=dwell_time,
        dwell_energy_wh=dwell_energy,
        sortie_time_s=times.fixed_s,
        sortie_energy_wh=float(energy["fixed"]),
        budget_wh=budget.usable_wh,
    )


@dataclass(frozen=True)
class SortieTimes:
    """A sortie's duration as the planners add it up (legs apart: leg_durations_s): what each buoy adds besides its
    leg (a turn of ``mean_turn_deg`` before the leg, the item's hand-over after it), the dwell, what the return adds
    besides its leg (the climb to the return altitude if lower, a mean turn) and the fixed rest (spool-up, climb to
    the mission altitude, the take-off's hand-over, the descent from the return altitude and the touchdown)."""

    per_buoy_s: float
    dwell_s: float
    return_s: float
    fixed_s: float

    def time_s(self, legs_s: float, buoys: int) -> float:
        """A sortie over `buoys` buoys whose legs (the return included) take legs_s."""
        return self.fixed_s + self.return_s + legs_s + buoys * (self.per_buoy_s + self.dwell_s)


def _sortie_blocks(model: EnergyModel, flight: RouteFlight, wind: WindForecast) -> dict[str, list[Phase | _Block]]:
    """The parts of a sortie that are not its legs (SortieTimes' terms), as unevaluated phases."""
    air, home_air = _Air(wind, flight.altitude_m), _Air(wind, _return_altitude(model, flight))
    north = np.array([0.0, 1.0])
    mean_turn = math.radians(model.fitted.mean_turn_deg)
    return {
        "per_buoy": [
            _turn(model, 0, 0.0, mean_turn, air),
            _hover("overhead", 0, model.fitted.item_overhead_s, north, air),
        ],
        "home": [_turn(model, 0, 0.0, mean_turn, home_air), *_return_climb(model, flight, 0.0, wind)],
        "dwell": [_hover("dwell", 0, flight.dwell_s, north, air)],
        "fixed": [*_takeoff(model, flight, wind), *_landing(model, _return_altitude(model, flight), 0.0, wind)],
    }


def _duration_s(parts: Sequence[Phase | _Block]) -> float:
    return float(sum(p.time_s if isinstance(p, Phase) else p.dt.sum() for p in parts))


def sortie_times(flight: RouteFlight, model: EnergyModel | None = None) -> SortieTimes:
    """The calibrated model's SortieTimes for a flight (its altitude sets the climb and the return's climb)."""
    model = model or EnergyModel.load()
    blocks = _sortie_blocks(model, flight, STILL_AIR)
    return SortieTimes(*(_duration_s(blocks[name]) for name in ("per_buoy", "dwell", "home", "fixed")))
