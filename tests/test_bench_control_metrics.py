"""The control benchmark's ESO metrics (bench.control.metrics.eso_errors) on synthetic per-tick series."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bench.control.metrics import ESO_MAX_LAG_TICKS, ESO_METRICS, eso_errors
from bench.control.scenario import OUTER_RATE_HZ

TICKS = 2000
LEGS = 4  # mission items 0..3, TICKS / LEGS ticks each


def series(ext_xy: np.ndarray, z3_xy: np.ndarray) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """The recorder's columns eso_errors reads, and a tracking phase covering every tick after the first 100."""
    s = {
        "ext_x": ext_xy[:, 0],
        "ext_y": ext_xy[:, 1],
        "z3_x": z3_xy[:, 0],
        "z3_y": z3_xy[:, 1],
        "offboard": np.ones(TICKS),
        "seq": np.repeat(np.arange(LEGS), TICKS // LEGS).astype(float),
    }
    tracking = np.arange(1, TICKS) >= 100  # indexed from tick 1, as flight_metrics builds it
    return s, tracking


def varying_disturbance(seed: int = 0) -> np.ndarray:
    """A gust-like smooth north/east acceleration (m/s^2) with zero mean."""
    t = np.arange(TICKS) / OUTER_RATE_HZ
    rng = np.random.default_rng(seed)
    phases = rng.uniform(0.0, 2.0 * math.pi, 4)
    return 0.5 * np.column_stack(
        [
            np.sin(0.7 * t + phases[0]) + np.sin(2.3 * t + phases[1]),
            np.sin(1.1 * t + phases[2]) + np.sin(3.1 * t + phases[3]),
        ]
    )


def estimate_of(ext: np.ndarray, lag_ticks: int) -> np.ndarray:
    """z3 as eso_errors aligns it: z3[k] estimates ext[k - 1]; a lagged estimate is ext[k - 1 - lag_ticks]."""
    z3 = np.full_like(ext, np.nan)
    z3[1 + lag_ticks :] = ext[: TICKS - 1 - lag_ticks]
    return z3


def test_a_constant_disturbance_estimated_perfectly_has_no_error() -> None:
    ext = np.tile([1.5, -0.8], (TICKS, 1))
    out = eso_errors(*series(ext, estimate_of(ext, 0)))
    assert out["eso_lateral_error_m_s2"] == pytest.approx(0.0, abs=1e-12)
    assert out["eso_lateral_error_best_lag_m_s2"] == pytest.approx(0.0, abs=1e-12)
    assert out["eso_best_lag_s"] == 0.0
    assert out["eso_disturbance_deviation_m_s2"] == pytest.approx(0.0, abs=1e-12)
    assert math.isnan(out["eso_lateral_rel_deviation"])  # nothing varies: no share to speak of
    assert out["eso_lateral_rel_error"] == pytest.approx(0.0, abs=1e-12)


def test_a_perfect_estimate_of_a_varying_disturbance_has_no_error() -> None:
    ext = varying_disturbance()
    out = eso_errors(*series(ext, estimate_of(ext, 0)))
    assert out["eso_lateral_error_m_s2"] == pytest.approx(0.0, abs=1e-12)
    assert out["eso_lateral_rel_deviation"] == pytest.approx(0.0, abs=1e-12)
    assert out["eso_best_lag_s"] == 0.0


@pytest.mark.parametrize("lag_ticks", [3, 10, ESO_MAX_LAG_TICKS])
def test_a_purely_lagging_estimate_is_found_at_its_lag(lag_ticks: int) -> None:
    ext = varying_disturbance()
    out = eso_errors(*series(ext, estimate_of(ext, lag_ticks)))
    assert out["eso_best_lag_s"] == pytest.approx(lag_ticks / OUTER_RATE_HZ)
    assert out["eso_lateral_error_best_lag_m_s2"] == pytest.approx(0.0, abs=1e-12)
    assert out["eso_lateral_rel_deviation_best_lag"] == pytest.approx(0.0, abs=1e-12)
    # at lag 0 the delay shows as error, reported in m/s^2 and relative to the disturbance's variation
    assert out["eso_lateral_error_m_s2"] > 0.05
    ratio = out["eso_lateral_error_m_s2"] / out["eso_disturbance_deviation_m_s2"]
    assert out["eso_lateral_rel_deviation"] == pytest.approx(ratio)


def test_steady_drag_along_each_leg_does_not_change_the_relative_error() -> None:
    gust = varying_disturbance()
    s, tracking = series(gust, estimate_of(gust, 6))
    calm = eso_errors(s, tracking)
    # a different steady drag on each leg (cruise drag points along the leg), itself estimated without error
    drag = np.array([[-2.0, 0.5], [1.0, -2.5], [2.2, 1.0], [-0.5, 2.0]])[s["seq"].astype(int)]
    dragged = eso_errors(*series(gust + drag, estimate_of(gust, 6) + estimate_of(drag, 0)))
    for name in ("eso_lateral_error_m_s2", "eso_disturbance_deviation_m_s2", "eso_lateral_rel_deviation"):
        assert dragged[name] == pytest.approx(calm[name], rel=1e-9), name
    # the old ratio counts the drag as disturbance and shrinks with it
    assert dragged["eso_lateral_rel_error"] < 0.5 * calm["eso_lateral_rel_error"]


def test_a_controller_without_an_eso_has_none_of_the_metrics() -> None:
    ext = varying_disturbance()
    out = eso_errors(*series(ext, np.full_like(ext, np.nan)))
    assert set(out) == set(ESO_METRICS)
    assert all(math.isnan(v) for v in out.values())
