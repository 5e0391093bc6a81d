"""What the benchmark measures on one flight's per-tick series (flight.FlightRecorder's columns).

Times t_k are outer-loop ticks; the truth at t_k is compared with the reference POSITION_TARGET published for
t_k, i.e. the same instant; "tracking phase" = mission items from the first buoy leg to the end of the return,
vehicle above 1 m:
- rms_error_m / max_error_m: 3-D position error, truth vs reference;
- cross_track_rms_m / cross_track_max_m: horizontal distance to the planned leg (straight segment between
  consecutive waypoints, takeoff point first) while flying to each buoy;
- along_track_lag_rms_m / along_track_lag_max_m / along_track_lag_mean_m: along-track lag, the reference's position
  minus the vehicle's (horizontal), projected on the direction of the leg being flown (positive = the vehicle
  behind its reference, negative = ahead of it), over the same ticks as cross-track: RMS, the largest (signed)
  value, and the mean (signed: RMS alone does not tell behind from ahead);
- gust_peak_m: largest 3-D error within 10 s of the gust onset; gust_recovery_s: time from the onset until
  the error is back under 0.2 m for good within that window (10 s = not recovered):
  gcs.domain.tracking_metrics.gust_effect,
  the demo's (`buoy-gcs up --demo`) measure too;
- altitude_rms_m: vertical error;
- yaw_turn_rms_deg / yaw_turn_max_deg: yaw error during the on-the-spot turns at the buoys (reference yaw
  rate non-zero, and 1.5 s after), the paper's Figure 11: the heading of the body x axis
  (uavcore.rotation.heading, the recorder's "yaw") against the reference yaw (`turn_yaw_errors_deg`);
- the lateral ESO (ADRC only; `eso_errors`), over the tracking phase, with a_ext the simulator's true external
  acceleration (drag + D terms, `external_accel_ned`, north and east) at the instant the ESO's output z3 is an
  estimate for (the sample after its latest measurement):
  - eso_lateral_error_m_s2: RMS |z3_xy - a_ext,xy|, in m/s^2;
  - eso_disturbance_deviation_m_s2: RMS |a_ext,xy - mean of a_ext,xy over the leg|, the leg being the
    mission item flown (the steady drag of cruising along a leg points along that leg, so one mean over the
    whole route would leave most of it in); eso_lateral_rel_deviation = eso_lateral_error_m_s2 / that:
    the error as a share of what actually varies (gust, turbulence, D terms, speeding up and slowing down),
    not of the steady drag, which an estimate held constant along each leg would already get right;
  - eso_best_lag_s: the time shift (0-0.5 s) at which z3 matches a_ext best (how much of the error is
    observer delay); eso_lateral_error_best_lag_m_s2 and eso_lateral_rel_deviation_best_lag: the error there;
  - eso_disturbance_rms_m_s2: RMS |a_ext,xy| (steady drag included) and eso_lateral_rel_error =
    eso_lateral_error_m_s2 / that, the ratio earlier results reported as "lateral ESO error": kept only
    to compare with them, it counts the steady drag as disturbance and so reads smaller than the error is;
- thrust_step_rms / attitude_step_rms_deg: RMS change of the normalised thrust and of the commanded attitude
  between consecutive ticks (control effort and chatter);
- saturated_fraction: share of tracking-phase ticks in which the mixer had to clip a rotor command.
The step experiment (flight.step_response) is measured by `step_metrics`: overshoot %, 10-90 % rise time and
0.1 m settling time.
"""

from __future__ import annotations

import math

import numpy as np

from bench.control.scenario import OUTER_RATE_HZ, STEP_M, Scenario
from gcs.domain.planning import FIRST_BUOY_SEQ
from gcs.domain.tracking_metrics import GUST_WINDOW_S, gust_effect
from uavcore.rotation import wrap_pi

TRACKING_MIN_ALTITUDE_M = 1.0
TURN_TAIL_S = 1.5
ESO_MAX_LAG_TICKS = 25
STEP_SETTLED_M = 0.1

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
    "eso_lateral_error_m_s2",
    "eso_lateral_rel_deviation",
    "eso_best_lag_s",
    "eso_lateral_error_best_lag_m_s2",
    "eso_lateral_rel_deviation_best_lag",
    "eso_disturbance_deviation_m_s2",
    "eso_disturbance_rms_m_s2",
    "eso_lateral_rel_error",
    "thrust_step_rms",
    "attitude_step_rms_deg",
    "saturated_fraction",
)
ESO_METRICS = tuple(m for m in METRICS if m.startswith("eso_"))
STEP_METRICS = ("overshoot_pct", "rise_time_s", "settling_time_s")
# the issue's, for ADRC; its ESO target of 25 % is held against the error relative to the disturbance's variation
TARGETS = {"rms_error_m": 0.25, "gust_peak_m": 0.6, "eso_lateral_rel_deviation": 0.25}


def _max(values: np.ndarray) -> float:
    """Largest value; NaN for a flight that never reached the phase (e.g. crashed before it)."""
    return float(values.max()) if values.size else math.nan


def _rms(values: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(values)))) if values.size else math.nan


def flight_metrics(s: dict[str, np.ndarray], scenario: Scenario, n_items: int) -> dict:
    """The metrics above for one mission flight; `s` is FlightRecorder.series(), n_items the mission's length."""
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
    cross, lag = [], []
    for leg in range(1, len(waypoints)):
        on_leg = tracking & (seq == FIRST_BUOY_SEQ - 1 + leg)
        a, b = waypoints[leg - 1], waypoints[leg]
        p = truth[on_leg, :2]
        direction = b - a
        u = np.clip(((p - a) @ direction) / float(direction @ direction), 0.0, 1.0)
        cross.append(np.linalg.norm(p - (a + np.outer(u, direction)), axis=1))
        lag.append((ref[on_leg, :2] - p) @ (direction / float(np.linalg.norm(direction))))
    cross_track = np.concatenate(cross) if cross else np.zeros(0)
    out["cross_track_rms_m"] = _rms(cross_track)
    out["cross_track_max_m"] = _max(cross_track)
    along_track = np.concatenate(lag) if lag else np.zeros(0)
    out["along_track_lag_rms_m"] = _rms(along_track)
    out["along_track_lag_max_m"] = _max(along_track)
    out["along_track_lag_mean_m"] = float(along_track.mean()) if along_track.size else math.nan
    # the gust
    t_gust = scenario.wind.gust_start_s
    window = (t_since_takeoff >= t_gust) & (t_since_takeoff <= t_gust + GUST_WINDOW_S)
    gust = gust_effect(t_since_takeoff, error, t_gust)
    out["gust_peak_m"], out["gust_recovery_s"] = gust.peak_m, gust.recovery_s
    out["gust_leg_seq_at_onset"] = int(seq[np.argmax(t_since_takeoff >= t_gust)]) if window.any() else -1
    # yaw at the turns
    yaw_error = turn_yaw_errors_deg(s["yaw"], s["yaw_ref"], s["yaw_rate_ref"], -s["z"] > TRACKING_MIN_ALTITUDE_M, dt)
    out["yaw_turn_rms_deg"] = _rms(yaw_error)
    out["yaw_turn_max_deg"] = _max(yaw_error)
    # control effort and saturation over the tracking phase
    thrust_step = np.diff(s["thrust"])
    q = np.column_stack([s["qw"], s["qx"], s["qy"], s["qz"]])
    dots = np.clip(np.abs(np.sum(q[1:] * q[:-1], axis=1)), 0.0, 1.0)
    attitude_step = np.degrees(2.0 * np.arccos(dots))
    out["thrust_step_rms"] = _rms(thrust_step[tracking])
    out["attitude_step_rms_deg"] = _rms(attitude_step[tracking])
    out["saturated_fraction"] = float(np.mean(s["saturated"][1:][tracking] > 0)) if tracking.any() else math.nan
    # the ESO's z3 against the true external acceleration (NaN for the controllers without one)
    out.update(eso_errors(s, tracking))
    return out


def turn_yaw_errors_deg(
    heading: np.ndarray, yaw_ref: np.ndarray, yaw_rate_ref: np.ndarray, airborne: np.ndarray, dt: float
) -> np.ndarray:
    """|heading - reference yaw| in degrees at the ticks of the turns (reference yaw rate non-zero, and
    TURN_TAIL_S after) while airborne. Per-tick series as the recorder's: heading[k] (the truth's, at the end of
    tick k) meets the reference of tick k + 1, computed for that instant."""
    turning = np.abs(yaw_rate_ref[1:]) > 1e-3
    tail = round(TURN_TAIL_S / dt)
    turns = np.convolve(turning.astype(float), np.ones(tail + 1), mode="full")[: turning.size] > 0
    yaw_error = np.degrees(np.abs(wrap_pi(heading[:-1] - yaw_ref[1:])))
    return yaw_error[turns & airborne[:-1]]


def eso_errors(s: dict[str, np.ndarray], tracking: np.ndarray) -> dict:
    """The ESO metrics of the module docstring (all NaN without an ESO or a tracking phase long enough).

    Timing: z3 read after tick k has just stepped the ESO with the measurement taken at t_(k-1) (the state
    stamped t_k); the discrete ESO's output after that step is its estimate for the next sample, t_k, whose
    true external acceleration is the one reported at the end of tick k-1: z3[k] is compared with
    ext[k - 1 - lag], lag 0 being the ESO's own claim. Every lag is scored on the same ticks k, and the
    relative figures divide by the same disturbance statistics (those of the lag-0 instants)."""
    z3 = np.column_stack([s["z3_x"], s["z3_y"]])
    ext = np.column_stack([s["ext_x"], s["ext_y"]])
    mask = np.concatenate([[False], tracking]) & (s["offboard"] > 0)  # tracking is indexed from tick 1
    mask[: 1 + ESO_MAX_LAG_TICKS] = False  # every lag needs its truth sample
    k = np.flatnonzero(mask & np.all(np.isfinite(z3), axis=1))
    if k.size < 2:
        return dict.fromkeys(ESO_METRICS, math.nan)
    errors = [_rms(np.linalg.norm(z3[k] - ext[k - 1 - lag], axis=1)) for lag in range(ESO_MAX_LAG_TICKS + 1)]
    best = int(np.argmin(errors))
    truth = ext[k - 1]
    leg = s["seq"][k - 1]  # the mission item being flown when that truth was sampled
    deviation = truth.copy()
    for item in np.unique(leg):
        deviation[leg == item] -= truth[leg == item].mean(axis=0)
    deviation_rms = _rms(np.linalg.norm(deviation, axis=1))
    total_rms = _rms(np.linalg.norm(truth, axis=1))
    return {
        "eso_lateral_error_m_s2": errors[0],
        "eso_lateral_rel_deviation": _ratio(errors[0], deviation_rms),
        "eso_best_lag_s": best / OUTER_RATE_HZ,
        "eso_lateral_error_best_lag_m_s2": errors[best],
        "eso_lateral_rel_deviation_best_lag": _ratio(errors[best], deviation_rms),
        "eso_disturbance_deviation_m_s2": deviation_rms,
        "eso_disturbance_rms_m_s2": total_rms,
        "eso_lateral_rel_error": _ratio(errors[0], total_rms),
    }


def _ratio(error: float, scale: float) -> float:
    """error / scale; NaN for a disturbance that does not vary (nothing to be a share of; 1e-9 m/s^2 is
    rounding left by subtracting a constant's mean)."""
    return error / scale if scale > 1e-9 else math.nan


def step_metrics(t: np.ndarray, east: np.ndarray) -> dict:
    """Overshoot (% of STEP_M), 10-90 % rise time and settling time (last instant outside STEP_M +- 0.1 m) of
    the east position `east` at times `t` after the step."""
    outside = np.flatnonzero(np.abs(east - STEP_M) > STEP_SETTLED_M)
    return {
        "overshoot_pct": float(max(east.max() - STEP_M, 0.0) / STEP_M * 100.0),
        "rise_time_s": float(t[np.argmax(east >= 0.9 * STEP_M)] - t[np.argmax(east >= 0.1 * STEP_M)]),
        "settling_time_s": float(t[outside[-1]]) if outside.size else 0.0,
    }
