"""One robustness flight: a condition, a controller, a seed; the metrics of bench.control.metrics plus success
and the wind the vehicle met. `fly_condition` is the campaign's task (bench.campaign.run_tasks)."""

from __future__ import annotations

import math
import time

import numpy as np

from bench.control.flight import fly
from bench.control.scenario import short_reference_scenario
from bench.robustness.conditions import BY_NAME, build
from sitl_quad.lockstep_harness import LockstepHarness
from sitl_quad.vehicle import TickRecord

SUCCESS_MAX_ERROR_M = 10.0  # success: the mission completed and the 3-D tracking error never exceeded this
# the nominal short mission lasts about 100 s: one not over after three times that has failed (and a failed flight
# would otherwise fly on to the harness's 900 s, ten times a good one's cost)
TIMEOUT_S = 300.0
AIRBORNE_M = 1.0
KEPT = (
    "rms_error_m",
    "max_error_m",
    "cross_track_rms_m",
    "cross_track_max_m",
    "along_track_lag_rms_m",
    "along_track_lag_max_m",
    "along_track_lag_mean_m",
    "gust_peak_m",
    "gust_recovery_s",
    "altitude_rms_m",
    "saturated_fraction",
    "thrust_step_rms",
    "flight_s",
)


def wind_stats(wind_ned: np.ndarray) -> dict:
    """The wind the vehicle met (per tick, while airborne): horizontal speed mean, standard deviation and peak, and
    the spread of the horizontal wind vector (sqrt of the trace of its covariance: what a wandering mean adds)."""
    if wind_ned.shape[0] < 2:
        return dict.fromkeys(("wind_mean_m_s", "wind_std_m_s", "wind_peak_m_s", "wind_vector_spread_m_s"), math.nan)
    horizontal = wind_ned[:, :2]
    speed = np.linalg.norm(horizontal, axis=1)
    return {
        "wind_mean_m_s": float(speed.mean()),
        "wind_std_m_s": float(speed.std(ddof=1)),
        "wind_peak_m_s": float(speed.max()),
        "wind_vector_spread_m_s": float(math.sqrt(np.trace(np.cov(horizontal.T)))),
    }


def fly_condition(condition: str, kind: str, seed: int) -> dict:
    """Fly the short mission under `condition` with controller `kind` on `seed`; a JSON-able dict of results."""
    started = time.perf_counter()
    config, scenario = build(BY_NAME[condition], short_reference_scenario())
    winds: list[np.ndarray] = []

    def wind_met(record: TickRecord, _harness: LockstepHarness) -> None:
        if -record.truth.position[2] > AIRBORNE_M:
            winds.append(record.disturbance["wind_ned"])

    metrics, _ = fly(kind, seed, scenario, config=config, timeout_s=TIMEOUT_S, observe=wind_met)
    out: dict = {k: _finite_or_none(metrics.get(k, math.nan)) for k in KEPT}
    max_error = metrics.get("max_error_m", math.nan)
    out.update(
        condition=condition,
        controller=kind,
        seed=seed,
        completed=metrics["completed"],
        success=bool(metrics["completed"] and math.isfinite(max_error) and max_error < SUCCESS_MAX_ERROR_M),
        failure=metrics["failure"],
        mission_state=metrics["mission_state"],
        wall_s=time.perf_counter() - started,
    )
    out.update({k: _finite_or_none(v) for k, v in wind_stats(np.asarray(winds).reshape(-1, 3)).items()})
    return out


def _finite_or_none(value: float) -> float | None:
    """JSON has no NaN: a metric the flight never reached is None."""
    return float(value) if value is not None and math.isfinite(value) else None
