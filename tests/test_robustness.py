"""bench/robustness and the physics options it needs: the wandering wind, the sensor delay, the design airframe
apart from the true one; and one tiny campaign's JSON."""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from bench.control.flight import configure_vehicle, make_controller
from bench.control.scenario import short_reference_scenario
from bench.robustness.conditions import BY_NAME, build
from sitl_quad.attitude_loops import attitude_loops
from sitl_quad.config import AttitudeControllerKind, ControlConfig, VehicleConfig
from sitl_quad.sensors import MeasurementDelay, SensorNoise
from sitl_quad.vehicle import Vehicle
from sitl_quad.wind import WANDER_SAMPLE_S, WindConfig, WindModel, mean_and_gust
from uavcore.airframe import Airframe
from uavcore.state import VehicleState

HOME = (59.9, 10.7, 0.0)


def test_wandering_wind_has_the_configured_spread_and_correlation() -> None:
    config = WindConfig(speed_m_s=5.0, wander_std_m_s=3.0, wander_time_constant_s=30.0, wander_horizon_s=100_000.0)
    path = WindModel(config, seed=7).wander
    assert path.shape[1] == 2
    assert np.allclose(path.std(axis=0), 3.0, rtol=0.1)  # ~1700 time constants: a few % of sampling error
    lag = round(30.0 / WANDER_SAMPLE_S)
    for axis in (0, 1):
        x = path[:, axis]
        assert np.corrcoef(x[:-lag], x[lag:])[0, 1] == pytest.approx(math.exp(-1.0), abs=0.05)


def test_wandering_wind_is_deterministic_per_seed_and_leaves_the_turbulence_alone() -> None:
    config = WindConfig(speed_m_s=5.0, turbulence_w20_m_s=5.0, wander_std_m_s=3.0, wander_time_constant_s=30.0)
    a, b, c = WindModel(config, seed=1), WindModel(config, seed=1), WindModel(config, seed=2)
    assert np.array_equal(a.wander, b.wander)
    assert not np.allclose(a.wander, c.wander)
    plain = WindModel(replace(config, wander_std_m_s=0.0), seed=1)
    assert np.array_equal(plain.turbulence, a.turbulence)
    assert np.array_equal(plain.noise(10), a.noise(10))
    # the kernel adds the path (interpolated) to the mean wind
    out, still = np.zeros(3), np.zeros(3)
    t = 12.3 * WANDER_SAMPLE_S
    mean_and_gust(a.params, t, out)
    mean_and_gust(plain.params, t, still)
    k = 12
    expected = 0.7 * a.wander[k] + 0.3 * a.wander[k + 1]
    assert out[:2] - still[:2] == pytest.approx(expected, abs=1e-9)


def test_measurement_delay_returns_the_measurement_n_ticks_old() -> None:
    delay = MeasurementDelay(3)
    states = [VehicleState(t=float(k)) for k in range(8)]
    out = [delay.push(s).t for s in states]
    assert out == [0.0, 0.0, 0.0, 0.0, 1.0, 2.0, 3.0, 4.0]
    assert MeasurementDelay(0).push(states[5]) is states[5]


def _falling_vehicle(delay_s: float) -> Vehicle:
    config = VehicleConfig(sensor_noise=replace(SensorNoise.none(), delay_s=delay_s))
    vehicle = Vehicle(config, HOME, seed=0)
    vehicle.sim.set_state(VehicleState(position=np.array([0.0, 0.0, -100.0]), velocity=np.array([1.0, 2.0, 0.0])))
    return vehicle


def test_sensor_delay_delays_the_vehicles_estimate() -> None:
    now, late = _falling_vehicle(0.0), _falling_vehicle(0.06)  # 3 ticks at 50 Hz
    assert late.measurement_delay.ticks == 3
    fresh, delayed = [], []
    for _ in range(10):
        now.tick()
        late.tick()
        fresh.append(now.estimate.position.copy())
        delayed.append(late.estimate.position.copy())
    for k in range(3, 10):
        assert np.allclose(delayed[k], fresh[k - 3])
    assert not np.allclose(delayed[9], fresh[9])


def test_a_perturbed_airframe_reaches_the_vehicle_while_the_controllers_keep_the_nominal_one() -> None:
    nominal = Airframe.table2()
    for kind in ("adrc", "pid"):
        config, _ = build(BY_NAME["mass+30%"], short_reference_scenario())
        config = configure_vehicle(kind, config)
        assert config.airframe.mass == pytest.approx(1.3 * nominal.mass)
        assert config.controller_airframe == nominal
        vehicle = Vehicle(config, HOME, seed=0, attitude_loops=attitude_loops())
        assert vehicle.sim.airframe.mass == pytest.approx(1.3 * nominal.mass)  # the physics flies the heavy one
        assert vehicle.mixer.airframe == nominal
        assert vehicle.position.airframe == nominal
        controller = make_controller(kind, config)
        assert controller is not None
        output = getattr(controller, "_out", controller)  # the ADRC keeps its thrust model in its output stage
        assert output.mass == nominal.mass
    config = configure_vehicle("adrc", build(BY_NAME["inertia+30%"], short_reference_scenario())[0])
    assert config.airframe.ixx == pytest.approx(1.3 * nominal.ixx)
    designed = Vehicle(config, HOME, seed=0, attitude_loops=attitude_loops()).attitude
    truthful = Vehicle(
        VehicleConfig(airframe=config.airframe, control=ControlConfig(attitude_controller=AttitudeControllerKind.ADRC)),
        HOME,
        seed=0,
        attitude_loops=attitude_loops(),
    ).attitude
    reference = Vehicle(
        VehicleConfig(control=ControlConfig(attitude_controller=AttitudeControllerKind.ADRC)),
        HOME,
        seed=0,
        attitude_loops=attitude_loops(),
    ).attitude
    assert np.array_equal(designed.channel_params, reference.channel_params)  # b0 from the nominal inertia
    assert not np.array_equal(designed.channel_params, truthful.channel_params)


@pytest.mark.slow
def test_a_tiny_campaign_writes_the_json_fields(tmp_path: Path) -> None:
    from bench.robustness.__main__ import main

    out = tmp_path / "robustness.json"
    argv = ["--seeds", "1", "--conditions", "delay_20ms", "--controllers", "adrc,px4", "--workers", "serial"]
    argv += ["--store", str(tmp_path / "flights.jsonl"), "--out", str(out), "--no-figures", "--no-progress"]
    assert main(argv) == 0
    data = json.loads(out.read_text())
    assert data["controllers"] == ["adrc", "px4"] and data["seeds"] == [0] and data["task_errors"] == 0
    entry = data["conditions"]["delay_20ms"]
    assert entry["group"] == "sensors" and set(entry["per_controller"]) == {"adrc", "px4"}
    for stats in entry["per_controller"].values():
        assert stats["n"] == 1 and stats["success_rate"] == 1.0
        for metric in ("rms_error_m", "max_error_m", "gust_peak_m", "along_track_lag_mean_m", "wind_std_m_s"):
            assert stats[metric]["mean"] is not None
    assert "px4" in entry["paired_vs_adrc"]
    flights = [json.loads(line)["result"] for line in (tmp_path / "flights.jsonl").read_text().splitlines()]
    assert {f["mission_state"] for f in flights} == {"complete"}
    lines = (tmp_path / "flights.jsonl").read_text().splitlines()
    assert len(lines) == 2
