"""Wind, gust, Dryden turbulence and the paper's Gaussian disturbance terms, alone and acting on the body."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sitl_quad.disturbances import DisturbanceConfig, GaussianDisturbance
from sitl_quad.simulator import Simulator
from sitl_quad.wind import FEET, WindConfig, WindModel
from uavcore.airframe import Airframe, ModelParameterError

AIRFRAME = Airframe.table2()


def low_altitude_intensities(w20: float, altitude_m: float) -> tuple[float, float]:
    """MIL-F-8785C low-altitude sigma_u (= sigma_v) and sigma_w, written out again for the test."""
    h_ft = altitude_m / FEET
    sigma_w = 0.1 * w20
    return sigma_w / (0.177 + 0.000823 * h_ft) ** 0.4, sigma_w


@pytest.mark.parametrize("dt", [0.001, 0.02])
def test_dryden_standard_deviation_matches_intensity_at_any_step(dt):
    # 10 ft and 30 m/s: the w filter's time constant L_w / V is 0.1 s, so a 20 ms step is a fifth of it
    # (a naive Euler discretisation would be visibly off there)
    w20, altitude, airspeed = 10.0, 10 * FEET, 30.0
    model = WindModel(WindConfig(turbulence_w20_m_s=w20), seed=11)
    # 2000 s: over 2500 correlation times of the slowest (u, v) components
    series = model.series(round(2000.0 / dt), dt, altitude, airspeed)
    sigma_uv, sigma_w = low_altitude_intensities(w20, altitude)
    std = series.std(axis=0)
    assert std[0] == pytest.approx(sigma_uv, rel=0.05)  # u along north without mean wind
    assert std[1] == pytest.approx(sigma_uv, rel=0.05)
    assert std[2] == pytest.approx(sigma_w, rel=0.05)
    assert np.all(np.abs(series.mean(axis=0)) < 0.2 * np.array([sigma_uv, sigma_uv, sigma_w]))


def test_dryden_correlation_time_follows_length_scale_over_airspeed():
    """The u component is first-order Gauss-Markov: lag-one correlation exp(-V dt / L_u)."""
    altitude, airspeed, dt = 20.0, 15.0, 0.05
    series = WindModel(WindConfig(turbulence_w20_m_s=10.0), seed=3).series(200_000, dt, altitude, airspeed)
    u = series[:, 0] - series[:, 0].mean()
    correlation = np.dot(u[:-1], u[1:]) / np.dot(u, u)
    h_ft = altitude / FEET
    length_u = h_ft / (0.177 + 0.000823 * h_ft) ** 1.2 * FEET
    assert correlation == pytest.approx(math.exp(-airspeed * dt / length_u), abs=0.01)


def test_one_minus_cosine_gust_shape():
    amplitude, rise, start, hold = 6.0, 0.4, 1.0, 0.5
    model = WindModel(
        WindConfig(
            gust_amplitude_m_s=amplitude,
            gust_rise_time_s=rise,
            gust_start_s=start,
            gust_hold_s=hold,
            gust_direction_from_deg=90.0,
        )
    )  # from the east, blows west
    times = [
        0.0,
        0.99,
        start + rise / 2,
        start + rise,
        start + rise + hold / 2,
        start + 2 * rise + hold - rise / 2,
        start + 2 * rise + hold + 0.01,
        5.0,
    ]
    east = [model.velocity(t, 5.0, 0.0)[1] for t in times]
    expected = [0.0, 0.0, -amplitude / 2, -amplitude, -amplitude, -amplitude / 2, 0.0, 0.0]
    np.testing.assert_allclose(east, expected, atol=1e-9)
    quarter = WindModel(WindConfig(gust_amplitude_m_s=amplitude, gust_rise_time_s=rise, gust_start_s=start))
    value = quarter.velocity(start + rise / 4, 5.0, 0.0)
    assert value[0] == pytest.approx(-amplitude / 2 * (1 - math.cos(math.pi / 4)))  # from north, blows south
    assert quarter.velocity(100.0, 5.0, 0.0)[0] == pytest.approx(-amplitude)  # default: the gust stays


def test_constant_wind_direction_is_where_it_comes_from():
    np.testing.assert_allclose(WindModel(WindConfig(8.0, 270.0)).velocity(0.0, 5.0, 0.0), [0.0, 8.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(WindModel(WindConfig(8.0, 0.0)).velocity(0.0, 5.0, 0.0), [-8.0, 0.0, 0.0], atol=1e-12)


def test_wind_seed_reproducibility():
    config = WindConfig(5.0, 30.0, turbulence_w20_m_s=8.0)
    a = WindModel(config, seed=4).series(1000, 0.01, 5.0, 10.0)
    b = WindModel(config, seed=4).series(1000, 0.01, 5.0, 10.0)
    c = WindModel(config, seed=5).series(1000, 0.01, 5.0, 10.0)
    np.testing.assert_array_equal(a, b)
    assert not np.allclose(a, c)


def test_wind_pushes_a_hovering_body_downwind_and_is_reported():
    sim = Simulator(
        AIRFRAME, wind=WindConfig(10.0, 270.0), position=(0.0, 0.0, -20.0), rotor_speed=AIRFRAME.hover_rotor_speed
    )
    sim.step(100)
    report = sim.last_disturbance
    np.testing.assert_allclose(report["wind_ned"], [0.0, 10.0, 0.0], atol=1e-12)
    velocity = sim.state.velocity
    assert velocity[1] > 0.05 and abs(velocity[0]) < 1e-6
    # drag on air-relative velocity (-v_east + 10 m/s): linear + quadratic, over the mass
    air = 10.0 - velocity[1]
    expected = (AIRFRAME.drag_linear_xy + AIRFRAME.drag_quadratic_xy * air) * air / AIRFRAME.mass
    assert report["external_accel_ned"][1] == pytest.approx(expected, rel=1e-3)


def test_external_acceleration_explains_the_motion_not_due_to_thrust_and_gravity():
    sim = Simulator(
        AIRFRAME,
        wind=WindConfig(7.0, 120.0, turbulence_w20_m_s=6.0),
        disturbance=DisturbanceConfig(sample_time_s=0.2),
        seed=9,
        position=(0.0, 0.0, -30.0),
        rotor_speed=AIRFRAME.hover_rotor_speed,
    )
    for _ in range(50):
        sim.step(37)
        before = sim.state
        external = sim.last_disturbance["external_accel_ned"]
        sim.step(1)
        after = sim.state
        measured = (after.velocity - before.velocity) / sim.dt
        w, x, y, z = before.quaternion
        body_z = np.array([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)])
        thrust = AIRFRAME.kl * np.sum(before.rotor_speeds**2) / AIRFRAME.mass
        unexplained = measured - (-thrust * body_z + [0.0, 0.0, AIRFRAME.g])
        np.testing.assert_allclose(unexplained, external, atol=0.02)


def test_gaussian_disturbance_is_zero_order_held_with_configured_variance():
    config = DisturbanceConfig(1.0, 4.0, 9.0, 0.25, 0.01, 15.0, sample_time_s=0.5)
    disturbance = GaussianDisturbance(config, seed=2)
    first = disturbance.value(0.0)
    np.testing.assert_array_equal(disturbance.value(0.49), first)
    assert not np.allclose(disturbance.value(0.5), first)
    samples = disturbance.draw(40_000)
    np.testing.assert_allclose(samples.var(axis=0), [1.0, 4.0, 9.0, 0.25, 0.01, 15.0], rtol=0.03)
    assert DisturbanceConfig.paper().variance_z == 15.0 and DisturbanceConfig.paper().sample_time_s == 0.5
    with pytest.raises(ModelParameterError):
        DisturbanceConfig(variance_x=-1.0)


def test_disturbance_terms_act_as_accelerations_on_the_body():
    config = DisturbanceConfig(1.0, 1.0, 1.0, 1.0, 1.0, 1.0, sample_time_s=0.05)
    drag_free = AIRFRAME.replace(drag_linear_xy=0, drag_quadratic_xy=0, drag_linear_z=0, drag_quadratic_z=0)
    sim = Simulator(
        drag_free, disturbance=config, seed=1, position=(0.0, 0.0, -100.0), rotor_speed=AIRFRAME.hover_rotor_speed
    )
    sim.step(1)
    report = sim.last_disturbance
    assert np.all(report["d_accel_ned"] != 0.0)
    np.testing.assert_allclose(sim.state.velocity / sim.dt, report["d_accel_ned"], rtol=1e-3)
    np.testing.assert_allclose(sim.state.angular_velocity / sim.dt, report["d_angular"], rtol=1e-2)
    held = report["d_accel_ned"]
    sim.step(49)  # steps 0..49 share the first sample (0.05 s at 1 kHz)
    np.testing.assert_array_equal(sim.last_disturbance["d_accel_ned"], held)
    sim.step(1)
    assert not np.allclose(sim.last_disturbance["d_accel_ned"], held)
