"""One robustness flight: a condition, a controller, a seed; the metrics of bench.control.metrics plus success
and the wind the vehicle met. `fly_condition` is the campaign's task (bench.campaign.run_tasks)."""

from __future__ import annotations

import math
import time
from functools import cache

import numpy as np

from bench.control.flight import FlightRecorder, configure_vehicle, make_controller
from bench.control.metrics import flight_metrics
from bench.control.scenario import OUTER_RATE_HZ, Scenario, build_scenario, short_scenario
from bench.robustness.conditions import BY_NAME, build
from sitl_quad.attitude_loops import attitude_loops
from sitl_quad.lockstep_harness import HarnessError, LockstepHarness
from sitl_quad.vehicle import TickRecord, Vehicle
from uavcore.airframe import ModelParameterError

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


@cache
def base_scenario() -> Scenario:
    """The nominal short flight (bench.control.scenario.short_scenario), built once per process."""
    return short_scenario(build_scenario())


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
    base = base_scenario()
    config, scenario = build(BY_NAME[condition], base)
    config = configure_vehicle(kind, config)  # the family's inner loop, designed for config.controller_airframe
    vehicle = Vehicle(config, scenario.home, seed=seed, outer_rate_hz=OUTER_RATE_HZ, attitude_loops=attitude_loops())
    harness = LockstepHarness(vehicle, make_controller(kind, config), outer_rate_hz=OUTER_RATE_HZ)
    recorder = FlightRecorder(harness)
    winds: list[np.ndarray] = []
    texts: list[str] = []  # the vehicle's STATUSTEXTs: why a flight that did not complete ended

    def on_tick(record: TickRecord) -> None:
        recorder(record)
        texts.extend(e.text for e in harness.last_events if e.kind == "text" and e.text)
        if -record.truth.position[2] > AIRBORNE_M:
            winds.append(record.disturbance["wind_ned"])

    completed, failure = True, ""
    try:
        harness.fly_mission(scenario.items, idle_ticks=60, timeout_s=TIMEOUT_S, on_tick=on_tick)
    except (HarnessError, ModelParameterError) as exc:
        completed, failure = False, f"{type(exc).__name__}: {exc}"[:200]
    state = vehicle.navigator.mission_state
    if completed and state != "complete":  # ended without the harness's error: say how (a crash, a failsafe)
        failure = f"mission {state}, vehicle {'armed' if vehicle.armed else 'disarmed'}" + (
            f": {texts[-1]}" if texts else ""
        )
    completed = completed and state == "complete"
    metrics = flight_metrics(recorder.series(), scenario, len(scenario.items)) if recorder.rows else {}
    out: dict = {k: _finite_or_none(metrics.get(k, math.nan)) for k in KEPT}
    max_error = metrics.get("max_error_m", math.nan)
    out.update(
        condition=condition,
        controller=kind,
        seed=seed,
        completed=completed,
        success=bool(completed and math.isfinite(max_error) and max_error < SUCCESS_MAX_ERROR_M),
        failure=failure,
        mission_state=state,
        wall_s=time.perf_counter() - started,
    )
    out.update({k: _finite_or_none(v) for k, v in wind_stats(np.asarray(winds).reshape(-1, 3)).items()})
    return out


def _finite_or_none(value: float) -> float | None:
    """JSON has no NaN: a metric the flight never reached is None."""
    return float(value) if value is not None and math.isfinite(value) else None
