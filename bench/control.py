"""ADRC against PID on the paper's buoy-inspection mission: a paired Monte Carlo over seeds, flown in lockstep.

    .venv/bin/python -m bench.control                 # 30 seeds, 2 workers: table + bench/results/control.json
    .venv/bin/python -m bench.control --seeds 5 --paper-seeds 0 --no-figures   # a quick look

Scenario (the paper's Section VI, made concrete; every number below is in control.json's "scenario"):
- Mission: `planner.scenario.reference_scenario()` (13 buoys, depot at home), optimal order
  (`plan_tour(method="exact")` through gcs.planning.make_plan), flown as the GCS would upload it
  (gcs.planning.mission_items: takeoff, DO_CHANGE_SPEED 10 m/s, one NAV_WAYPOINT per buoy at 5 m with a
  1 s inspection dwell and a 2 m acceptance radius, RTL), in-process lockstep (sitl_quad.lockstep_harness).
- Wind: 5 m/s mean crosswind perpendicular to the route's longest leg (blowing from its right-hand side).
- Gust: 1-cosine, 4 m/s along the crosswind, rise 1 s, starting when the navigator's reference is halfway
  along the longest leg (computed from the reference's own timeline, see `gust_start_time`). Like every
  wind time it counts on the flight's disturbance clock, which starts at the mission start command (the
  climb follows the vehicle's 1 s motor spool-up, so the gust meets the reference about 1 s before its
  midpoint: still mid-cruise on a 41 s leg; each flight's item at the onset is in per_seed). It holds
  10 s and falls back (gust_hold_s = 10): the onset is the step-like "sudden wind change" of the paper's
  Figure 6, and falling back keeps the rest of the mission at the 5 m/s mean.
- Turbulence: Dryden, MIL-F-8785C low-altitude form, W20 chosen so that sigma_u = sigma_v = 1.0 m/s at the
  5 m flight altitude (`dryden_w20_for_sigma`: W20 = 5.15 m/s, sigma_w = 0.52 m/s). W20 ~ 5 m/s is also
  consistent with the 5 m/s mean wind.
- Disturbance terms D (eq. 1-2): sitl_quad.disturbances' realistic default (variance 0.05 on every channel,
  held 0.5 s). The paper's variance 15 is a 0.4 g random push held half a second; `--paper-seeds N` flies
  N extra seeds with it and reports them apart.
- Sensor noise: sitl_quad.sensors defaults (2 cm, 5 cm/s, 0.3 deg, 0.01 rad/s).
- Seeds 0..N-1; a seed fixes wind, turbulence, D terms and sensor noise, so every controller meets the same
  air (paired design).

Controllers:
- "adrc": ADRC outer loop (adrc_offboard.outer_loop.AdrcOuterLoop) + ADRC inner loop (MC_ATT_CTRL = 1,
  gains/attitude_adrc.json): the paper's cascade dual ADRC.
- "pid": PID outer loop (PidOuterLoop) + the vehicle's PID attitude loop (MC_ATT_CTRL = 0).
  Both outer loops fly the gains bench/tune_control.py chose (results/control_tuning.json: one shared
  bandwidth, each controller's free parameter tuned with the same budget, rebuilt by
  outer_loop.matched_gains); --shipped-gains flies adrc_offboard/gains/outer_*.json instead.
- "px4": the vehicle's built-in PX4-default PID cascade, no offboard controller ("PX4 defaults").

Metrics per flight (times t_k are outer-loop ticks; the truth at t_k is compared with the reference
POSITION_TARGET published for t_k, i.e. the same instant; "tracking phase" = mission items from the first
buoy leg to the end of the return, vehicle above 1 m):
- rms_error_m / max_error_m: 3-D position error, truth vs reference;
- cross_track_rms_m / cross_track_max_m: horizontal distance to the planned leg (straight segment between
  consecutive waypoints, takeoff point first) while flying to each buoy;
- gust_peak_m: largest 3-D error within 10 s of the gust onset; gust_recovery_s: time from the onset until
  the error is back under 0.2 m for good within that window (10 s = not recovered);
- altitude_rms_m: vertical error;
- yaw_turn_rms_deg / yaw_turn_max_deg: yaw error during the on-the-spot turns at the buoys (reference yaw
  rate non-zero, and 1.5 s after), the paper's Figure 11;
- eso_lateral_rel_error (ADRC only): RMS over the tracking phase of |z3_xy - a_ext,xy| / RMS |a_ext,xy|,
  where a_ext is the simulator's true external acceleration (drag + D terms, `external_accel_ned`) at the
  instant the ESO's output is an estimate for (the sample after its latest measurement);
  eso_lateral_rel_error_best_lag is the same at the best time shift (0-0.5 s), a diagnostic of how much
  is observer lag;
- thrust_step_rms / attitude_step_rms_deg: RMS change of the normalised thrust and of the commanded attitude
  between consecutive ticks (control effort and chatter);
- saturated_fraction: share of tracking-phase ticks in which the mixer had to clip a rotor command.
Plus a separate step experiment: a 5 m lateral (east) position step at a 5 m hover in still air (sensor noise
and D terms on): overshoot %, 10-90 % rise time and 0.1 m settling time.

Statistics: mean and 95 % confidence interval (Student t over seeds) per controller; paired t-test and
Wilcoxon signed-rank test (exact distribution without ties, normal approximation with ties) on the per-seed
differences ADRC - PID and ADRC - PX4 defaults. scipy is not a dependency: both are implemented below.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from dataclasses import asdict, dataclass, field
from multiprocessing import Pool
from pathlib import Path

import numpy as np

from adrc_offboard.outer_loop import AdrcOuterGains, AdrcOuterLoop, PidOuterGains, PidOuterLoop, matched_gains
from gcs.planning import FIRST_BUOY_SEQ, FlightParams, make_plan, mission_items
from planner.scenario import ALTITUDE_M, CRUISE_SPEED_M_S, reference_scenario
from sitl_quad.config import AttitudeControllerKind, ControlConfig, VehicleConfig
from sitl_quad.disturbances import DisturbanceConfig
from sitl_quad.lockstep_harness import HarnessError, LockstepHarness
from sitl_quad.navigator import Navigator, NavigatorConfig
from sitl_quad.vehicle import Vehicle
from sitl_quad.wind import FEET, WindConfig
from uavcore.mission import MavCmd, MavFrame, MissionItem
from uavcore.rotation import euler_from_quat, quat_from_euler
from uavcore.state import TrajectorySetpoint, VehicleState

RESULTS = Path(__file__).resolve().parent / "results"
CONTROLLERS = ("adrc", "pid", "px4")
LABELS = {
    "adrc": "ADRC outer + ADRC inner (cascade dual ADRC)",
    "pid": "PID outer + PID inner, same bandwidth",
    "px4": "PX4 defaults (built-in PID cascade)",
}
OUTER_RATE_HZ = 50.0
DWELL_S = 1.0
ACCEPTANCE_RADIUS_M = 2.0
CROSSWIND_M_S = 5.0
GUST_M_S = 4.0
GUST_RISE_S = 1.0
GUST_HOLD_S = 10.0
GUST_WINDOW_S = 10.0
RECOVERED_M = 0.2
TURBULENCE_SIGMA_M_S = 1.0
TRACKING_MIN_ALTITUDE_M = 1.0
TURN_TAIL_S = 1.5
ESO_MAX_LAG_TICKS = 25
STEP_M = 5.0
STEP_HOVER_S = 12.0
STEP_WINDOW_S = 10.0
STEP_SETTLED_M = 0.1
TARGETS = {"rms_error_m": 0.25, "gust_peak_m": 0.6, "eso_lateral_rel_error": 0.25}


# ----------------------------------------------------------------------------------------------- scenario
def dryden_w20_for_sigma(sigma_m_s: float, altitude_m: float) -> float:
    """W20 whose MIL-F-8785C low-altitude horizontal intensity at altitude_m is sigma_m_s:
    sigma_u = sigma_v = 0.1 W20 / (0.177 + 0.000823 h)^0.4, h in feet (clamped to 10..1000 ft as in sitl_quad.wind)."""
    h_ft = min(max(altitude_m / FEET, 10.0), 1000.0)
    return sigma_m_s * (0.177 + 0.000823 * h_ft) ** 0.4 / 0.1


@dataclass
class Scenario:
    home: tuple[float, float, float]
    items: list[MissionItem]
    waypoints_ne: list[list[float]]  # takeoff point, then the buoys in visiting order: [north, east] m
    route_length_m: float
    longest_leg: int  # index into waypoints_ne of the longest leg's end (1 = first buoy)
    crosswind_from_deg: float
    gust_start_s: float
    wind: WindConfig
    disturbance: DisturbanceConfig = field(default_factory=DisturbanceConfig)

    def config(self, kind: str, paper_disturbance: bool = False) -> VehicleConfig:
        inner = AttitudeControllerKind.ADRC if kind == "adrc" else AttitudeControllerKind.PID
        disturbance = DisturbanceConfig.paper() if paper_disturbance else self.disturbance
        return VehicleConfig(wind=self.wind, disturbance=disturbance, control=ControlConfig(attitude_controller=inner))


def build_scenario() -> Scenario:
    reference = reference_scenario()
    plan = make_plan(
        reference.depot_lat_lon,
        [tuple(p) for p in reference.buoys_lat_lon.tolist()],
        [f"buoy-{i}" for i in range(len(reference.buoys_lat_lon))],
        method="exact",
    )
    items = mission_items(
        plan, FlightParams(ALTITUDE_M, CRUISE_SPEED_M_S, DWELL_S, ACCEPTANCE_RADIUS_M), reference.depot_lat_lon
    )
    vehicle = Vehicle(VehicleConfig(), reference.home)
    waypoints = [[0.0, 0.0]]
    for it in items[FIRST_BUOY_SEQ : FIRST_BUOY_SEQ + len(plan.order)]:
        north, east, _ = vehicle.frame.to_ned(it.lat, it.lon, vehicle.frame.alt0)
        waypoints.append([float(north), float(east)])
    legs = np.diff(np.asarray(waypoints), axis=0)
    longest = int(np.argmax(np.hypot(legs[:, 0], legs[:, 1]))) + 1
    bearing = math.degrees(math.atan2(legs[longest - 1, 1], legs[longest - 1, 0]))
    crosswind_from = (bearing + 90.0) % 360.0  # from the leg's right-hand side
    gust_start = gust_start_time(items, reference.home, longest)
    wind = WindConfig(
        speed_m_s=CROSSWIND_M_S,
        direction_from_deg=crosswind_from,
        gust_amplitude_m_s=GUST_M_S,
        gust_rise_time_s=GUST_RISE_S,
        gust_start_s=gust_start,
        gust_hold_s=GUST_HOLD_S,
        gust_direction_from_deg=crosswind_from,
        turbulence_w20_m_s=round(dryden_w20_for_sigma(TURBULENCE_SIGMA_M_S, ALTITUDE_M), 3),
    )
    return Scenario(reference.home, items, waypoints, float(plan.length_m), longest, crosswind_from, gust_start, wind)


def gust_start_time(items: list[MissionItem], home, leg: int) -> float:
    """Seconds from takeoff at which the navigator's reference is halfway along leg `leg` (its own timeline,
    flown by a vehicle that tracks it perfectly), rounded to 0.1 s."""
    vehicle = Vehicle(VehicleConfig(), home)
    navigator = Navigator(vehicle.frame, NavigatorConfig())
    navigator.set_mission(items)
    state = VehicleState()
    navigator.start_mission(0.0, state)
    dt, t = 1.0 / OUTER_RATE_HZ, 0.0
    seq, start, end = FIRST_BUOY_SEQ - 1 + leg, None, None
    while t < 3600.0:
        sp = navigator.update(t, state)
        moving = float(np.hypot(*sp.velocity[:2])) > 0.5
        if navigator.current_seq == seq and moving:
            start = t if start is None else start
            end = t
        elif start is not None and navigator.current_seq != seq:
            break
        state = VehicleState(
            t=t, position=sp.position, velocity=sp.velocity, quaternion=np.asarray(quat_from_euler(0.0, 0.0, sp.yaw))
        )
        t += dt
    if start is None or end is None:
        raise RuntimeError(f"the reference never flew leg {leg}")
    return round(0.5 * (start + end), 1)


# ----------------------------------------------------------------------------------------------- flights
def make_controller(
    kind: str, config: VehicleConfig, adrc_gains: AdrcOuterGains | None = None, pid_gains: PidOuterGains | None = None
):
    af = config.airframe
    if kind == "adrc":
        return AdrcOuterLoop(af.mass, af.g, af.max_thrust_n, gains=adrc_gains, rate_hz=OUTER_RATE_HZ)
    if kind == "pid":
        return PidOuterLoop(af.mass, af.g, af.max_thrust_n, gains=pid_gains, rate_hz=OUTER_RATE_HZ)
    return None


class FlightRecorder:
    """Per-tick series of one flight (called by the harness after each vehicle tick, before the exchange)."""

    def __init__(self, harness: LockstepHarness) -> None:
        self.harness = harness
        self.rows: list[list[float]] = []
        self._saturated = harness.vehicle.saturated_ticks

    COLUMNS = (
        "t",
        "x",
        "y",
        "z",
        "yaw",
        "x_ref",
        "y_ref",
        "z_ref",
        "yaw_ref",
        "yaw_rate_ref",
        "seq",
        "thrust",
        "qw",
        "qx",
        "qy",
        "qz",
        "ext_x",
        "ext_y",
        "ext_z",
        "saturated",
        "offboard",
        "z1_x",
        "z1_y",
        "z1_z",
        "z2_x",
        "z2_y",
        "z2_z",
        "z3_x",
        "z3_y",
        "z3_z",
        "vx",
        "vy",
        "vz",
    )

    def __call__(self, record) -> None:
        vehicle = self.harness.vehicle
        truth, sp, target = record.truth, record.setpoint, record.target
        ext = record.disturbance.get("external_accel_ned", np.zeros(3))
        saturated = vehicle.saturated_ticks - self._saturated
        self._saturated = vehicle.saturated_ticks
        controller = self.harness.controller
        eso = controller.telemetry() if isinstance(controller, AdrcOuterLoop) else {}
        self.rows.append(
            [
                record.t,
                *truth.position,
                euler_from_quat(truth.quaternion)[2],
                *sp.position,
                sp.yaw,
                sp.yaw_rate,
                vehicle.navigator.current_seq,
                target.thrust,
                *target.quaternion,
                *ext,
                saturated,
                float(record.source == "offboard"),
                *(eso.get(f"{name}_{axis}", math.nan) for name in ("z1", "z2", "z3") for axis in "xyz"),
                *truth.velocity,
            ]
        )

    def series(self) -> dict[str, np.ndarray]:
        data = np.asarray(self.rows, dtype=float)
        return {name: data[:, i] for i, name in enumerate(self.COLUMNS)}


def fly(
    kind: str,
    seed: int,
    scenario: Scenario,
    paper_disturbance: bool = False,
    adrc_gains: AdrcOuterGains | None = None,
    pid_gains: PidOuterGains | None = None,
    items: list[MissionItem] | None = None,
) -> tuple[dict, dict[str, np.ndarray]]:
    """One mission; returns (metrics, per-tick series)."""
    config = scenario.config(kind, paper_disturbance)
    vehicle = Vehicle(config, scenario.home, seed=seed, outer_rate_hz=OUTER_RATE_HZ)
    harness = LockstepHarness(
        vehicle, make_controller(kind, config, adrc_gains, pid_gains), outer_rate_hz=OUTER_RATE_HZ
    )
    recorder = FlightRecorder(harness)
    completed = True
    try:
        harness.fly_mission(items or scenario.items, idle_ticks=60, on_tick=recorder)
    except HarnessError:
        completed = False
    completed = completed and vehicle.navigator.mission_state == "complete"
    series = recorder.series()
    metrics = flight_metrics(series, scenario, len(items or scenario.items))
    metrics["completed"] = completed
    return metrics, series


def _wrap(angle: np.ndarray) -> np.ndarray:
    return (angle + np.pi) % (2 * np.pi) - np.pi


def _max(values: np.ndarray) -> float:
    """Largest value; NaN for a flight that never reached the phase (e.g. crashed before it)."""
    return float(values.max()) if values.size else math.nan


def _rms(values: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(values)))) if values.size else math.nan


def flight_metrics(s: dict[str, np.ndarray], scenario: Scenario, n_items: int) -> dict:
    dt = 1.0 / OUTER_RATE_HZ
    # the truth at the start of tick k (= end of tick k-1) against the reference computed for that instant
    truth = np.column_stack([s["x"], s["y"], s["z"]])[:-1]
    ref = np.column_stack([s["x_ref"], s["y_ref"], s["z_ref"]])[1:]
    seq = s["seq"][1:]
    t_since_takeoff = s["t"][1:] - s["t"][0]  # tick 0 starts at takeoff: its end is t[0] = takeoff + dt
    error = np.linalg.norm(truth - ref, axis=1)
    tracking = (seq >= FIRST_BUOY_SEQ) & (seq <= n_items - 1) & (-truth[:, 2] > TRACKING_MIN_ALTITUDE_M)
    out: dict = {"flight_s": float(s["t"][-1] - s["t"][0] + dt)}
    out["rms_error_m"] = _rms(error[tracking])
    out["max_error_m"] = _max(error[tracking])
    out["altitude_rms_m"] = _rms((truth[:, 2] - ref[:, 2])[tracking])
    # cross-track against the planned legs
    waypoints = np.asarray(scenario.waypoints_ne)
    cross = []
    for leg in range(1, len(waypoints)):
        on_leg = tracking & (seq == FIRST_BUOY_SEQ - 1 + leg)
        a, b = waypoints[leg - 1], waypoints[leg]
        p = truth[on_leg, :2]
        direction = b - a
        u = np.clip(((p - a) @ direction) / float(direction @ direction), 0.0, 1.0)
        cross.append(np.linalg.norm(p - (a + np.outer(u, direction)), axis=1))
    cross_track = np.concatenate(cross) if cross else np.zeros(0)
    out["cross_track_rms_m"] = _rms(cross_track)
    out["cross_track_max_m"] = _max(cross_track)
    # the gust
    t_gust = scenario.wind.gust_start_s
    window = (t_since_takeoff >= t_gust) & (t_since_takeoff <= t_gust + GUST_WINDOW_S)
    out["gust_peak_m"] = _max(error[window])
    above = np.flatnonzero(window & (error > RECOVERED_M))
    out["gust_recovery_s"] = (
        math.nan
        if not window.any()
        else 0.0
        if above.size == 0
        else float(min(t_since_takeoff[above[-1]] + dt - t_gust, GUST_WINDOW_S))
    )
    out["gust_leg_seq_at_onset"] = int(seq[np.argmax(t_since_takeoff >= t_gust)]) if window.any() else -1
    # yaw at the turns
    turning = np.abs(s["yaw_rate_ref"][1:]) > 1e-3
    tail = round(TURN_TAIL_S / dt)
    turns = np.convolve(turning.astype(float), np.ones(tail + 1), mode="full")[: turning.size] > 0
    yaw_error = np.degrees(np.abs(_wrap(s["yaw"][:-1] - s["yaw_ref"][1:])))
    airborne = -truth[:, 2] > TRACKING_MIN_ALTITUDE_M
    out["yaw_turn_rms_deg"] = _rms(yaw_error[turns & airborne])
    out["yaw_turn_max_deg"] = _max(yaw_error[turns & airborne])
    # control effort and saturation over the tracking phase
    thrust_step = np.diff(s["thrust"])
    q = np.column_stack([s["qw"], s["qx"], s["qy"], s["qz"]])
    dots = np.clip(np.abs(np.sum(q[1:] * q[:-1], axis=1)), 0.0, 1.0)
    attitude_step = np.degrees(2.0 * np.arccos(dots))
    out["thrust_step_rms"] = _rms(thrust_step[tracking])
    out["attitude_step_rms_deg"] = _rms(attitude_step[tracking])
    out["saturated_fraction"] = float(np.mean(s["saturated"][1:][tracking] > 0)) if tracking.any() else math.nan
    # the ESO's z3 against the true external acceleration
    if np.all(np.isnan(s["z3_x"])):
        out["eso_lateral_rel_error"] = out["eso_lateral_rel_error_best_lag"] = math.nan
    else:
        out.update(eso_errors(s, tracking))
    return out


def eso_errors(s: dict[str, np.ndarray], tracking: np.ndarray) -> dict:
    """z3 read after tick k has just stepped the ESO with the measurement taken at t_(k-1) (the state stamped
    t_k); the discrete ESO's output after that step is its estimate for the next sample, t_k, whose true
    external acceleration is the one reported at the end of tick k-1: compare z3[k] with ext[k - 1 - lag]
    (lag 0 is the ESO's own claim; the best lag shows how much of the error is observer delay)."""
    z3 = np.column_stack([s["z3_x"], s["z3_y"]])
    ext = np.column_stack([s["ext_x"], s["ext_y"]])
    mask = np.concatenate([[False], tracking]) & (s["offboard"] > 0)  # tracking is indexed from tick 1
    if mask.sum() <= 1 + ESO_MAX_LAG_TICKS:
        return {
            "eso_lateral_rel_error": math.nan,
            "eso_lateral_rel_error_best_lag": math.nan,
            "eso_best_lag_s": math.nan,
        }
    results = []
    for lag in range(ESO_MAX_LAG_TICKS + 1):
        shift = 1 + lag
        k = np.flatnonzero(mask[shift:]) + shift
        diff = z3[k] - ext[k - shift]
        results.append(_rms(np.linalg.norm(diff, axis=1)) / _rms(np.linalg.norm(ext[k - shift], axis=1)))
    return {
        "eso_lateral_rel_error": results[0],
        "eso_lateral_rel_error_best_lag": min(results),
        "eso_best_lag_s": results.index(min(results)) / OUTER_RATE_HZ,
    }


# ------------------------------------------------------------------------------------- step experiment
class StepReference:
    """Stands in for the vehicle's navigator during the step experiment: a fixed position (a step from the
    hover point) with what the vehicle reads of a navigator in an active mission."""

    activity = "mission"
    is_landing = False
    mission_state = "active"

    def __init__(self, position: np.ndarray, yaw: float, current_seq: int) -> None:
        self.position, self.yaw, self.current_seq = position, yaw, current_seq

    def update(self, t: float, state: VehicleState) -> TrajectorySetpoint:
        return TrajectorySetpoint(position=self.position.copy(), yaw=self.yaw)

    def pop_events(self) -> list:
        return []


def hover_mission(home) -> list[MissionItem]:
    lat, lon = round(home[0] * 1e7), round(home[1] * 1e7)
    return [
        MissionItem(
            seq=0,
            frame=MavFrame.GLOBAL_RELATIVE_ALT_INT,
            command=MavCmd.NAV_TAKEOFF,
            current=1,
            x=lat,
            y=lon,
            z=ALTITUDE_M,
        ),
        MissionItem(
            seq=1,
            frame=MavFrame.GLOBAL_RELATIVE_ALT_INT,
            command=MavCmd.NAV_LOITER_TIME,
            param1=3600.0,
            param2=0.0,
            param3=0.0,
            x=lat,
            y=lon,
            z=ALTITUDE_M,
        ),
    ]


def step_response(
    kind: str,
    seed: int,
    scenario: Scenario,
    adrc_gains: AdrcOuterGains | None = None,
    pid_gains: PidOuterGains | None = None,
) -> tuple[dict, np.ndarray]:
    """Hover at 5 m in still air, then a 5 m step east; returns metrics and [t, east] after the step."""
    config = scenario.config(kind)
    config.wind = WindConfig()
    vehicle = Vehicle(config, scenario.home, seed=seed, outer_rate_hz=OUTER_RATE_HZ)
    harness = LockstepHarness(
        vehicle, make_controller(kind, config, adrc_gains, pid_gains), outer_rate_hz=OUTER_RATE_HZ
    )
    harness.upload_mission(hover_mission(scenario.home))
    harness.arm()
    for _ in range(60):
        harness.step()
    harness.start_mission()
    for _ in range(round(STEP_HOVER_S * OUTER_RATE_HZ)):
        harness.step()
    start = vehicle.setpoint.position.copy()
    vehicle.navigator = StepReference(start + np.array([0.0, STEP_M, 0.0]), 0.0, vehicle.navigator.current_seq)
    east = []
    for _ in range(round(STEP_WINDOW_S * OUTER_RATE_HZ)):
        record = harness.step()
        east.append(record.truth.position[1] - start[1])
    east = np.asarray(east)
    t = (np.arange(east.size) + 1) / OUTER_RATE_HZ
    outside = np.flatnonzero(np.abs(east - STEP_M) > STEP_SETTLED_M)
    metrics = {
        "overshoot_pct": float(max(east.max() - STEP_M, 0.0) / STEP_M * 100.0),
        "rise_time_s": float(t[np.argmax(east >= 0.9 * STEP_M)] - t[np.argmax(east >= 0.1 * STEP_M)]),
        "settling_time_s": float(t[outside[-1]]) if outside.size else 0.0,
    }
    return metrics, np.column_stack([t, east])


# ----------------------------------------------------------------------------------------------- statistics
def _betacf(a: float, b: float, x: float) -> float:
    """Continued fraction of the regularised incomplete beta function (modified Lentz)."""
    tiny = 1e-300
    c, d = 1.0, 1.0 - (a + b) * x / (a + 1.0)
    d = 1.0 / (d if abs(d) > tiny else tiny)
    h = d
    for m in range(1, 300):
        m2 = 2 * m
        for num in (
            m * (b - m) * x / ((a + m2 - 1) * (a + m2)),
            -(a + m) * (a + b + m) * x / ((a + m2) * (a + m2 + 1)),
        ):
            d = 1.0 + num * d
            d = 1.0 / (d if abs(d) > tiny else tiny)
            c = 1.0 + num / c
            c = c if abs(c) > tiny else tiny
            h *= d * c
        if abs(d * c - 1.0) < 1e-15:
            break
    return h


def incomplete_beta(a: float, b: float, x: float) -> float:
    """I_x(a, b)."""
    if x <= 0.0:
        return 0.0
    if x >= 1.0:
        return 1.0
    log_front = math.lgamma(a + b) - math.lgamma(a) - math.lgamma(b) + a * math.log(x) + b * math.log1p(-x)
    if x < (a + 1.0) / (a + b + 2.0):
        return math.exp(log_front) * _betacf(a, b, x) / a
    return 1.0 - math.exp(log_front) * _betacf(b, a, 1.0 - x) / b


def t_two_sided_p(t: float, df: float) -> float:
    return incomplete_beta(df / 2.0, 0.5, df / (df + t * t))


def t_quantile(p: float, df: float) -> float:
    """Upper quantile: P(T <= q) = p, for p > 0.5 (bisection on the CDF)."""
    lo, hi = 0.0, 100.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if 1.0 - 0.5 * t_two_sided_p(mid, df) < p:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def mean_ci(values: np.ndarray) -> dict:
    values = values[np.isfinite(values)]
    n = values.size
    if n == 0:
        return {"mean": None, "ci95": None, "n": 0}
    mean = float(values.mean())
    if n < 2:
        return {"mean": mean, "ci95": None, "n": int(n)}
    half = t_quantile(0.975, n - 1) * float(values.std(ddof=1)) / math.sqrt(n)
    return {"mean": mean, "ci95": [mean - half, mean + half], "n": int(n)}


def paired_t_test(a: np.ndarray, b: np.ndarray) -> float:
    d = a - b
    n = d.size
    sd = float(d.std(ddof=1))
    if sd == 0.0:
        return 1.0 if float(d.mean()) == 0.0 else 0.0
    return t_two_sided_p(float(d.mean()) / (sd / math.sqrt(n)), n - 1)


def wilcoxon_signed_rank(a: np.ndarray, b: np.ndarray) -> float:
    """Two-sided p of the Wilcoxon signed-rank test (zero differences dropped)."""
    d = a - b
    d = d[d != 0.0]
    n = d.size
    if n == 0:
        return 1.0
    magnitude = np.abs(d)
    order = np.argsort(magnitude, kind="stable")
    ranks = np.empty(n)
    sorted_mag = magnitude[order]
    i = 0
    while i < n:  # average ranks over ties
        j = i
        while j + 1 < n and sorted_mag[j + 1] == sorted_mag[i]:
            j += 1
        ranks[order[i : j + 1]] = 0.5 * (i + j) + 1.0
        i = j + 1
    w_plus = float(ranks[d > 0].sum())
    ties = np.unique(magnitude).size < n
    if not ties and n <= 60:
        # exact null distribution of W+: counts of subsets of {1..n} by sum
        total = n * (n + 1) // 2
        counts = np.zeros(total + 1)
        counts[0] = 1.0
        for r in range(1, n + 1):
            counts[r:] = counts[r:] + counts[:-r].copy()
        probs = counts / counts.sum()
        w = round(w_plus)
        return float(min(1.0, 2.0 * min(probs[: w + 1].sum(), probs[w:].sum())))
    mean = n * (n + 1) / 4.0
    _, tie_counts = np.unique(magnitude, return_counts=True)
    var = n * (n + 1) * (2 * n + 1) / 24.0 - float(np.sum(tie_counts**3 - tie_counts)) / 48.0
    z = (abs(w_plus - mean) - 0.5) / math.sqrt(var)
    return float(math.erfc(max(z, 0.0) / math.sqrt(2.0)))


# ----------------------------------------------------------------------------------------------- running
def _flight_job(job: tuple) -> tuple:
    kind, seed, paper, keep = job
    metrics, series = fly(kind, seed, SCENARIO, paper_disturbance=paper, adrc_gains=GAINS[0], pid_gains=GAINS[1])
    return kind, seed, paper, metrics, (series if keep else None)


def _step_job(job: tuple) -> tuple:
    kind, seed = job
    metrics, trace = step_response(kind, seed, SCENARIO, *GAINS)
    return kind, seed, metrics, (trace if seed == 0 else None)


SCENARIO: Scenario  # set in main() before the pool forks
GAINS: tuple[AdrcOuterGains | None, PidOuterGains | None] = (None, None)  # None: the shipped gains files


def tuned_gains(path: Path) -> tuple[tuple[AdrcOuterGains, PidOuterGains], dict]:
    """The outer-loop gains bench/tune_control.py chose (its JSON), rebuilt with outer_loop.matched_gains."""
    data = json.loads(path.read_text())
    grid, chosen = data["grid"], data["chosen"]
    omega_c = float(data["shared_omega_c"])
    adrc, _ = matched_gains(
        omega_c,
        grid["vertical_ratio"] * omega_c,
        observer_ratio=chosen["adrc"]["second"],
        delta=grid["adrc_delta"],
        r1=tuple(grid["adrc_r1"]),
    )
    _, pid = matched_gains(omega_c, grid["vertical_ratio"] * omega_c, integral_ratio=chosen["pid"]["second"])
    described = {
        "source": str(path.relative_to(RESULTS.parent.parent)),
        "omega_c_horizontal": omega_c,
        "omega_c_vertical": grid["vertical_ratio"] * omega_c,
        "adrc_observer_ratio": chosen["adrc"]["second"],
        "pid_integral_ratio": chosen["pid"]["second"],
        "adrc_delta": grid["adrc_delta"],
        "adrc_r1": grid["adrc_r1"],
        "pid": asdict(pid),
    }
    return (adrc, pid), described


METRICS = (
    "rms_error_m",
    "max_error_m",
    "cross_track_rms_m",
    "cross_track_max_m",
    "gust_peak_m",
    "gust_recovery_s",
    "altitude_rms_m",
    "yaw_turn_rms_deg",
    "yaw_turn_max_deg",
    "eso_lateral_rel_error",
    "eso_lateral_rel_error_best_lag",
    "thrust_step_rms",
    "attitude_step_rms_deg",
    "saturated_fraction",
)
STEP_METRICS = ("overshoot_pct", "rise_time_s", "settling_time_s")


def summarise(per_seed: dict[str, list[dict]], metrics: tuple[str, ...]) -> dict:
    out: dict = {"per_controller": {}, "paired": {}}
    for kind, rows in per_seed.items():
        out["per_controller"][kind] = {m: mean_ci(np.array([r[m] for r in rows], dtype=float)) for m in metrics}
    for other in ("pid", "px4"):
        if "adrc" not in per_seed or other not in per_seed:
            continue
        tests = {}
        for m in metrics:
            a = np.array([r[m] for r in per_seed["adrc"]], dtype=float)
            b = np.array([r[m] for r in per_seed[other]], dtype=float)
            ok = np.isfinite(a) & np.isfinite(b)
            if ok.sum() < 3:
                continue
            tests[m] = {
                "mean_difference": float(np.mean(a[ok] - b[ok])),
                "paired_t_p": paired_t_test(a[ok], b[ok]),
                "wilcoxon_p": wilcoxon_signed_rank(a[ok], b[ok]),
                "n": int(ok.sum()),
            }
        out["paired"][f"adrc_vs_{other}"] = tests
    return out


def print_table(title: str, summary: dict, metrics: tuple[str, ...]) -> None:
    kinds = list(summary["per_controller"])
    print(f"\n{title}")
    header = f"{'metric':30}" + "".join(f"{k:>26}" for k in kinds) + f"{'p (t / W) adrc-pid':>24}"
    print(header)
    print("-" * len(header))
    for m in metrics:
        cells = []
        for k in kinds:
            c = summary["per_controller"][k][m]
            if c["mean"] is None:
                cells.append(f"{'-':>26}")
            elif c["ci95"] is None:
                cells.append(f"{c['mean']:>26.4g}")
            else:
                cells.append(f"{c['mean']:>10.4g} [{c['ci95'][0]:.3g}, {c['ci95'][1]:.3g}]".rjust(26))
        test = summary["paired"].get("adrc_vs_pid", {}).get(m)
        p = f"{test['paired_t_p']:.2g} / {test['wilcoxon_p']:.2g}" if test else "-"
        print(f"{m:30}" + "".join(cells) + f"{p:>24}")


# ----------------------------------------------------------------------------------------------- figures
def draw_figures(scenario: Scenario, series: dict[str, dict], steps: dict[str, np.ndarray], out_dir: Path) -> list[str]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    colours = {"adrc": "tab:green", "pid": "tab:red", "px4": "tab:purple"}
    paths = []
    t_gust = scenario.wind.gust_start_s

    def since_takeoff(s):
        return s["t"][1:] - s["t"][0]

    # Figure 6: x, y, z, yaw around the gust
    fig, axes = plt.subplots(4, 1, figsize=(9, 10), sharex=True)
    for kind, s in series.items():
        t = since_takeoff(s)
        w = (t >= t_gust - 2) & (t <= t_gust + 8)
        for ax, (name, ref, scale) in zip(
            axes,
            (("x", "x_ref", 1), ("y", "y_ref", 1), ("z", "z_ref", -1), ("yaw", "yaw_ref", 180 / math.pi)),
            strict=True,
        ):
            if name in ("x", "y"):  # at 10 m/s the positions are straight lines: show the error instead
                ax.plot(t[w], (s[name][:-1] - s[ref][1:])[w], color=colours[kind], label=LABELS[kind])
                continue
            ax.plot(t[w], s[name][:-1][w] * scale, color=colours[kind], label=LABELS[kind])
            if kind == "adrc":
                ax.plot(t[w], s[ref][1:][w] * scale, "b:", label="reference")
    for ax, label in zip(
        axes, ("north error x - x_ref (m)", "east error y - y_ref (m)", "altitude (m)", "yaw (deg)"), strict=True
    ):
        ax.set_ylabel(label)
        ax.axvspan(t_gust, t_gust + GUST_RISE_S, color="0.9")
    axes[0].legend(fontsize=7)
    axes[-1].set_xlabel(f"time since takeoff (s); gust onset {t_gust:g} s (shaded: rise)")
    fig.suptitle("Tracking around the gust (seed 0; paper Fig. 6)")
    paths.append(_save(fig, out_dir / "control_gust_tracking.png"))

    # Figure 7: ESO outputs (ADRC) in the gust window against the true disturbance
    if "adrc" in series:
        s = series["adrc"]
        # tick k ends at t[k] = t[0] + k dt on a clock that starts dt before t[0] (the mission start);
        # z at tick k is the ESO's estimate for t_k, the start of tick k (see eso_errors)
        t = s["t"] - s["t"][0]
        w = (t >= t_gust - 2) & (t <= t_gust + 8)
        fig, axes = plt.subplots(3, 2, figsize=(11, 8), sharex=True)
        ext_t = s["t"] - s["t"][0] + 1.0 / OUTER_RATE_HZ  # reported at the end of its tick
        we = (ext_t >= t_gust - 2) & (ext_t <= t_gust + 8)
        for col, axis in enumerate(("x", "y")):
            # z at tick k describes t_k = the truth recorded at the end of tick k-1
            truth_pos = np.concatenate([[np.nan], s[axis][:-1]])
            truth_vel = np.concatenate([[np.nan], s[f"v{axis}"][:-1]])
            axes[0, col].plot(t[w], (s[f"z1_{axis}"] - truth_pos)[w], label="z1 - true position")
            axes[1, col].plot(t[w], truth_vel[w], "k:", label="true velocity")
            axes[1, col].plot(t[w], s[f"z2_{axis}"][w], "g", label="z2 (velocity estimate)")
            axes[2, col].plot(ext_t[we], s[f"ext_{axis}"][we], color="0.6", label="true external acceleration")
            axes[2, col].plot(t[w], s[f"z3_{axis}"][w], "r", label="z3 (total disturbance estimate)")
            axes[0, col].set_title(f"{'north' if axis == 'x' else 'east'} channel")
            for ax in axes[:, col]:
                ax.axvspan(t_gust, t_gust + GUST_RISE_S, color="0.9")
                ax.legend(fontsize=7)
        axes[0, 0].set_ylabel("m")
        axes[1, 0].set_ylabel("m/s")
        axes[2, 0].set_ylabel("m/s^2")
        for ax in axes[-1]:
            ax.set_xlabel("time since takeoff (s)")
        fig.suptitle("ADRC extended state observer around the gust (seed 0; paper Fig. 7)")
        paths.append(_save(fig, out_dir / "control_eso.png"))

    # Figure 10: flown tracks over the planned route, with a zoom on a turn
    waypoints = np.asarray([*scenario.waypoints_ne, [0.0, 0.0]])
    fig, (ax, zoom) = plt.subplots(1, 2, figsize=(13, 6))
    corner = waypoints[min(7, len(waypoints) - 2)]  # the paper zooms on its 7th, 9th and 12th buoys
    for a in (ax, zoom):
        a.plot(waypoints[:, 1], waypoints[:, 0], "b-", lw=1, label="planned route")
        a.plot(waypoints[1:-1, 1], waypoints[1:-1, 0], "o", mfc="none", color="tab:red", label="buoys")
        for kind, s in series.items():
            a.plot(s["y"], s["x"], color=colours[kind], lw=0.8, label=LABELS[kind])
    for i, (n, e) in enumerate(waypoints[1:-1], start=1):
        ax.annotate(str(i), (e, n), fontsize=7)
    ax.set_aspect("equal")
    ax.set_xlabel("east (m)")
    ax.set_ylabel("north (m)")
    ax.legend(fontsize=7)
    zoom.set_xlim(corner[1] - 6, corner[1] + 6)
    zoom.set_ylim(corner[0] - 6, corner[0] + 6)
    zoom.set_aspect("equal")
    zoom.set_title("zoom: 7th buoy")
    zoom.set_xlabel("east (m)")
    fig.suptitle("Flown tracks over the planned route (seed 0; paper Fig. 10)")
    paths.append(_save(fig, out_dir / "control_tracks.png"))

    # Figure 11: yaw desired vs actual at the 7th, 9th and 12th buoys
    fig, axes = plt.subplots(1, 3, figsize=(13, 4))
    for ax, buoy in zip(axes, (7, 9, 12), strict=True):
        for kind, s in series.items():
            seq = s["seq"][1:]
            t = since_takeoff(s)
            at = np.flatnonzero((seq == FIRST_BUOY_SEQ + buoy) & (np.abs(s["yaw_rate_ref"][1:]) > 1e-3))
            if at.size == 0:
                continue
            w = (t >= t[at[0]] - 1) & (t <= t[at[-1]] + 3)
            ax.plot(t[w], np.degrees(np.unwrap(s["yaw"][:-1][w])), color=colours[kind], label=LABELS[kind])
            if kind == "adrc":
                ax.plot(t[w], np.degrees(np.unwrap(s["yaw_ref"][1:][w])), "b:", label="desired")
        ax.set_title(f"turn at buoy {buoy} (toward buoy {buoy + 1})")
        ax.set_xlabel("time since takeoff (s)")
    axes[0].set_ylabel("yaw (deg)")
    axes[0].legend(fontsize=7)
    fig.suptitle("Yaw at the turns (seed 0; paper Fig. 11)")
    paths.append(_save(fig, out_dir / "control_yaw_turns.png"))

    # step responses
    if steps:
        fig, ax = plt.subplots(figsize=(8, 4))
        for kind, trace in steps.items():
            ax.plot(trace[:, 0], trace[:, 1], color=colours[kind], label=LABELS[kind])
        ax.axhline(STEP_M, color="b", ls=":")
        ax.set_xlabel("time since the step (s)")
        ax.set_ylabel("east (m)")
        ax.legend(fontsize=7)
        ax.set_title(f"{STEP_M:g} m lateral position step at hover (seed 0)")
        paths.append(_save(fig, out_dir / "control_step.png"))
    return paths


def _save(fig, path: Path) -> str:
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    import matplotlib.pyplot as plt

    plt.close(fig)
    return str(path.relative_to(RESULTS.parent.parent))


# ----------------------------------------------------------------------------------------------- main
def main(argv: list[str] | None = None) -> int:
    global SCENARIO, GAINS
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--seeds", type=int, default=30)
    p.add_argument("--paper-seeds", type=int, default=5, help="extra seeds with the paper's variance-15 D terms")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--no-figures", dest="figures", action="store_false")
    p.add_argument("--out", type=Path, default=RESULTS / "control.json")
    p.add_argument(
        "--tuning",
        type=Path,
        default=RESULTS / "control_tuning.json",
        help="outer-loop gains chosen by bench/tune_control.py (default); see --shipped-gains",
    )
    p.add_argument("--shipped-gains", action="store_true", help="fly adrc_offboard/gains/outer_*.json instead")
    args = p.parse_args(argv)
    if args.seeds < 3 or args.workers < 1 or args.paper_seeds < 0:
        print("control.py: error: need --seeds >= 3, --workers >= 1, --paper-seeds >= 0", file=sys.stderr)
        return 2
    started = time.perf_counter()
    SCENARIO = build_scenario()
    gains_used = {
        "adrc_outer": "adrc_offboard/gains/outer_adrc.json",
        "pid_outer": "adrc_offboard/gains/outer_pid.json",
    }
    if not args.shipped_gains:
        if not args.tuning.exists():
            print(
                f"control.py: error: {args.tuning} not found: run bench/tune_control.py or use --shipped-gains",
                file=sys.stderr,
            )
            return 2
        GAINS, gains_used = tuned_gains(args.tuning)
    print(
        f"route {SCENARIO.route_length_m:.0f} m, longest leg {SCENARIO.longest_leg}, crosswind from "
        f"{SCENARIO.crosswind_from_deg:.0f} deg, gust at {SCENARIO.gust_start_s:g} s after takeoff, "
        f"W20 {SCENARIO.wind.turbulence_w20_m_s} m/s",
        flush=True,
    )
    jobs = [(k, seed, False, seed == 0) for seed in range(args.seeds) for k in CONTROLLERS]
    jobs += [(k, seed, True, False) for seed in range(args.paper_seeds) for k in CONTROLLERS]
    step_jobs = [(k, seed) for seed in range(args.seeds) for k in CONTROLLERS]
    per_seed: dict[str, list] = {k: [None] * args.seeds for k in CONTROLLERS}
    paper: dict[str, list] = {k: [None] * args.paper_seeds for k in CONTROLLERS}
    steps: dict[str, list] = {k: [None] * args.seeds for k in CONTROLLERS}
    series, traces = {}, {}
    with Pool(args.workers) if args.workers > 1 else _InlinePool() as pool:
        for done, (kind, seed, is_paper, metrics, s) in enumerate(pool.imap_unordered(_flight_job, jobs), 1):
            (paper if is_paper else per_seed)[kind][seed] = metrics
            if s is not None:
                series[kind] = s
            print(
                f"  [{done}/{len(jobs)}] {kind} seed {seed}{' (paper D)' if is_paper else ''}: "
                f"rms {metrics['rms_error_m']:.3f} m, gust peak {metrics['gust_peak_m']:.3f} m, "
                f"completed {metrics['completed']} ({time.perf_counter() - started:.0f} s)",
                flush=True,
            )
        for kind, seed, metrics, trace in pool.imap_unordered(_step_job, step_jobs):
            steps[kind][seed] = metrics
            if trace is not None:
                traces[kind] = trace
    elapsed = time.perf_counter() - started
    summary = summarise(per_seed, METRICS)
    step_summary = summarise(steps, STEP_METRICS)
    print_table(
        f"Reference mission, {args.seeds} paired seeds (mean [95% CI]; paired p: t-test / Wilcoxon)", summary, METRICS
    )
    print_table("5 m lateral step at hover", step_summary, STEP_METRICS)
    paper_summary = None
    if args.paper_seeds >= 3:
        paper_summary = summarise(paper, METRICS)
        print_table(f"Paper's variance-15 disturbance, {args.paper_seeds} seeds", paper_summary, METRICS)
    adrc = summary["per_controller"]["adrc"]
    targets = {
        m: {"target_max": v, "adrc_mean": adrc[m]["mean"], "met": adrc[m]["mean"] is not None and adrc[m]["mean"] <= v}
        for m, v in TARGETS.items()
    }
    print(
        "\nADRC targets: "
        + ", ".join(
            f"{m} {t['adrc_mean']:.3g} <= {t['target_max']} {'met' if t['met'] else 'MISSED'}"
            for m, t in targets.items()
        )
    )
    figures = draw_figures(SCENARIO, series, traces, args.out.parent) if args.figures else []
    result = {
        "command": "python -m bench.control " + " ".join(argv if argv is not None else sys.argv[1:]),
        "elapsed_s": elapsed,
        "workers": args.workers,
        "cpu_count": os.cpu_count(),
        "scenario": {
            **{k: v for k, v in asdict(SCENARIO).items() if k not in ("items", "wind", "disturbance")},
            "wind": asdict(SCENARIO.wind),
            "disturbance": asdict(SCENARIO.disturbance),
            "turbulence_sigma_uv_m_s": TURBULENCE_SIGMA_M_S,
            "dwell_s": DWELL_S,
            "acceptance_radius_m": ACCEPTANCE_RADIUS_M,
            "gust_window_s": GUST_WINDOW_S,
            "recovered_below_m": RECOVERED_M,
        },
        "controllers": LABELS,
        "gains": {
            **gains_used,
            "adrc_inner": "adrc_offboard/gains/attitude_adrc.json",
            "pid_inner": "the vehicle's PidAttitudeGains (PX4 defaults)",
        },
        "seeds": args.seeds,
        "mission": summary,
        "completed": {k: sum(bool(r["completed"]) for r in rows) for k, rows in per_seed.items()},
        "step": step_summary,
        "paper_disturbance": paper_summary,
        "paper_disturbance_completed": {k: sum(bool(r["completed"]) for r in rows) for k, rows in paper.items()}
        if args.paper_seeds
        else None,
        "targets": targets,
        "per_seed": per_seed,
        "figures": figures,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(_finite_or_null(result), indent=1, default=float))
    print(f"\nwrote {args.out} ({elapsed:.0f} s){''.join(chr(10) + '  ' + f for f in figures)}")
    return 0


def _finite_or_null(value):
    """NaN (a metric a crashed flight never reached) as JSON null, so the file stays strict JSON."""
    if isinstance(value, dict):
        return {k: _finite_or_null(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_finite_or_null(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


class _InlinePool:
    """Pool stand-in for --workers 1."""

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        return None

    @staticmethod
    def imap_unordered(fn, jobs):
        return map(fn, jobs)


if __name__ == "__main__":
    sys.exit(main())
