"""bench.control's operating points: the gains read from bench/tune_control.py's JSON and the results' rows."""

from __future__ import annotations

import json

import pytest

from adrc_offboard.outer_loop import pid_gains_for_bandwidth
from bench.control import RESULTS
from bench.control.__main__ import OperatingPoint, tuned_gains

TUNING = RESULTS / "control_tuning.json"


def assert_flies(point: OperatingPoint, picks: dict) -> None:
    """The point's gains are the tuning's picks: ADRC bandwidth (h1 = 1/omega_c) and observer (beta1 = 3 omega_o),
    PID from pid_gains_for_bandwidth, horizontal axis."""
    adrc, pid = picks["adrc"], picks["pid"]
    assert point.adrc.horizontal.h1 == pytest.approx(1.0 / adrc["omega_c"])
    assert point.adrc.horizontal.beta1 == pytest.approx(3.0 * adrc["second"] * adrc["omega_c"])
    assert point.pid.horizontal == pid_gains_for_bandwidth(pid["omega_c"], pid["second"])
    for kind in ("adrc", "pid"):
        assert point.described[kind]["omega_c_horizontal"] == picks[kind]["omega_c"]
        assert point.described[kind]["tuning_flight_rms_error_m"] == picks[kind]["rms_error_m"]


def test_the_shared_point_flies_both_controllers_at_the_tuned_shared_bandwidth() -> None:
    data = json.loads(TUNING.read_text())
    point = tuned_gains(TUNING, "shared")
    assert [point.row(k) for k in ("adrc", "pid", "px4")] == ["adrc", "pid", "px4"]  # the keys of earlier results
    assert_flies(point, data["chosen"])
    assert data["chosen"]["adrc"]["omega_c"] == data["chosen"]["pid"]["omega_c"] == data["shared_omega_c"]


def test_the_own_point_flies_each_controller_at_its_own_best_tuning() -> None:
    data = json.loads(TUNING.read_text())
    point = tuned_gains(TUNING, "own")
    assert [point.row(k) for k in ("adrc", "pid", "px4")] == ["adrc@own", "pid@own", "px4"]
    assert_flies(point, data["own_best"])
