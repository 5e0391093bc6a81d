"""The rigid body of eq. (1)-(3): numba kernel against a plain numpy reference, hover, free fall, moment steps,
ground contact, reproducibility."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sitl_quad.disturbances import DisturbanceConfig
from sitl_quad.rigid_body import derivative
from sitl_quad.sensors import SensorNoise
from sitl_quad.simulator import Simulator
from sitl_quad.wind import WindConfig
from uavcore.airframe import Airframe, ModelParameterError
from uavcore.rotation import euler_from_quat, quat_from_euler
from uavcore.state import VehicleState

AIRFRAME = Airframe.table2()
NO_DRAG = AIRFRAME.replace(drag_linear_xy=0.0, drag_quadratic_xy=0.0, drag_linear_z=0.0, drag_quadratic_z=0.0)


def reference_derivative(state, omega_cmd, af: Airframe, wind, d_accel, d_angular):
    """The same model written independently with matrices: eq. (1)-(3), drag, motor lag."""
    q = state[6:10] / np.linalg.norm(state[6:10])
    w, x, y, z = q
    rotation = np.array(
        [
            [w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z],
        ]
    )
    omega_sq = state[13:17] ** 2
    u1 = af.kl * omega_sq.sum()
    u2 = af.kl * (omega_sq @ [1, 1, -1, -1])
    u3 = af.kl * (omega_sq @ [1, -1, -1, 1])
    u4 = af.kf * (omega_sq @ [1, -1, 1, -1])
    air_body = rotation.T @ (state[3:6] - wind)
    linear = np.array([af.drag_linear_xy, af.drag_linear_xy, af.drag_linear_z])
    quadratic = np.array([af.drag_quadratic_xy, af.drag_quadratic_xy, af.drag_quadratic_z])
    drag_body = -(linear + quadratic * np.abs(air_body)) * air_body
    accel = rotation @ (np.array([0, 0, -u1]) + drag_body) / af.mass + [0, 0, af.g] + d_accel
    inertia = np.diag([af.ixx, af.iyy, af.izz])
    rates = state[10:13]
    torque = af.arm_length * np.array([u2, u3, u4])
    rates_dot = np.linalg.solve(inertia, torque - np.cross(rates, inertia @ rates)) + d_angular
    omega_quat = np.array([0.0, *rates])
    q_dot = 0.5 * np.array(
        [
            w * omega_quat[0] - x * omega_quat[1] - y * omega_quat[2] - z * omega_quat[3],
            w * omega_quat[1] + x * omega_quat[0] + y * omega_quat[3] - z * omega_quat[2],
            w * omega_quat[2] - x * omega_quat[3] + y * omega_quat[0] + z * omega_quat[1],
            w * omega_quat[3] + x * omega_quat[2] - y * omega_quat[1] + z * omega_quat[0],
        ]
    )
    rotor_dot = (np.clip(omega_cmd, af.rotor_speed_min, af.rotor_speed_max) - state[13:17]) / af.motor_time_constant
    return np.concatenate([state[3:6], accel, q_dot, rates_dot, rotor_dot])


def test_numba_derivative_matches_numpy_reference():
    rng = np.random.default_rng(7)
    params = AIRFRAME.as_array()
    for _ in range(50):
        state = np.concatenate(
            [
                rng.normal(0, 10, 3),
                rng.normal(0, 5, 3),
                quat_from_euler(*rng.uniform(-1.5, 1.5, 3)),
                rng.normal(0, 3, 3),
                rng.uniform(0, 500, 4),
            ]
        )
        omega_cmd = rng.uniform(-50, 600, 4)
        wind, d_accel, d_angular = rng.normal(0, 5, 3), rng.normal(0, 1, 3), rng.normal(0, 1, 3)
        fast = derivative(state, omega_cmd, params, wind, d_accel, d_angular)
        slow = reference_derivative(state, omega_cmd, AIRFRAME, wind, d_accel, d_angular)
        np.testing.assert_allclose(fast, slow, rtol=1e-10, atol=1e-10)


def test_hover_rotor_speed_holds_position():
    assert AIRFRAME.hover_rotor_speed == pytest.approx(math.sqrt(1.3 * 9.81 / (4 * 2.85e-5)))
    sim = Simulator(AIRFRAME, position=(1.0, 2.0, -10.0), yaw=0.3, rotor_speed=AIRFRAME.hover_rotor_speed)
    sim.step(5000)
    state = sim.state
    np.testing.assert_allclose(state.position, [1.0, 2.0, -10.0], atol=1e-9)
    np.testing.assert_allclose(state.velocity, 0.0, atol=1e-9)
    assert euler_from_quat(state.quaternion)[2] == pytest.approx(0.3)
    assert not sim.on_ground


def test_free_fall_accelerates_at_g_with_rotors_off():
    sim = Simulator(NO_DRAG, position=(0.0, 0.0, -100.0))
    sim.step(2000)
    assert sim.state.velocity[2] == pytest.approx(2.0 * 9.81, rel=1e-9)
    assert sim.state.position[2] == pytest.approx(-100.0 + 0.5 * 9.81 * 4.0, rel=1e-9)
    # with drag it starts at g, then the vertical drag grows with speed and the fall is slower
    draggy = Simulator(AIRFRAME, position=(0.0, 0.0, -100.0))
    draggy.step(1)
    assert draggy.state.velocity[2] / draggy.dt == pytest.approx(9.81, rel=1e-3)
    draggy.step(1999)
    assert 0.0 < draggy.state.velocity[2] < 2.0 * 9.81


def test_rotors_follow_commands_with_the_motor_lag_and_limits():
    sim = Simulator(AIRFRAME, position=(0.0, 0.0, -100.0), rotor_speed=300.0)
    sim.set_rotor_commands([400.0, 200.0, 300.0, 900.0])
    sim.step(round(AIRFRAME.motor_time_constant / sim.dt))  # one time constant: 63 % of the way
    expected = np.array([300.0, 300.0, 300.0, 300.0]) + (1 - math.exp(-1)) * np.array([100.0, -100.0, 0.0, 200.0])
    np.testing.assert_allclose(sim.state.rotor_speeds, expected, rtol=1e-6)
    sim.step(1000)
    np.testing.assert_allclose(sim.state.rotor_speeds, [400.0, 200.0, 300.0, AIRFRAME.rotor_speed_max])


@pytest.mark.parametrize(
    ("axis", "pattern", "inertia", "coefficient"),
    [
        (0, (1, 1, -1, -1), AIRFRAME.ixx, AIRFRAME.kl),  # U2: rotors 1, 2 (left) faster -> +roll
        (1, (1, -1, -1, 1), AIRFRAME.iyy, AIRFRAME.kl),  # U3: rotors 1, 4 (front) faster -> +pitch
        (2, (1, -1, 1, -1), AIRFRAME.izz, AIRFRAME.kf),  # U4: rotors 1, 3 (CCW) faster -> +yaw
    ],
)
def test_moment_step_gives_eq1_angular_acceleration(axis, pattern, inertia, coefficient):
    hover = AIRFRAME.hover_rotor_speed
    speeds = np.sqrt(hover**2 + 5000.0 * np.array(pattern))
    u = coefficient * (speeds**2 @ np.array(pattern))
    sim = Simulator(NO_DRAG, position=(0.0, 0.0, -50.0), rotor_speed=speeds)
    sim.step(1)
    expected = AIRFRAME.arm_length * u / inertia  # eq. (1): L U / I (no coupling from rest)
    rates = sim.state.angular_velocity
    assert rates[axis] / sim.dt == pytest.approx(expected, rel=1e-3)
    assert expected > 0
    others = [i for i in range(3) if i != axis]
    assert np.all(np.abs(rates[others]) < 1e-9)


def test_gyroscopic_coupling_of_eq1():
    """Spinning in roll and pitch at once drives yaw by p q (Ix - Iy) / Iz, and so on round the axes."""
    state = np.zeros(17)
    state[6] = 1.0
    state[10:13] = [2.0, 3.0, 5.0]
    state[13:17] = AIRFRAME.hover_rotor_speed
    zeros = np.zeros(3)
    rates_dot = derivative(state, state[13:17], AIRFRAME.as_array(), zeros, zeros, zeros)[10:13]
    a = AIRFRAME
    expected = [3 * 5 * (a.iyy - a.izz) / a.ixx, 5 * 2 * (a.izz - a.ixx) / a.iyy, 2 * 3 * (a.ixx - a.iyy) / a.izz]
    np.testing.assert_allclose(rates_dot, expected, rtol=1e-12)


def test_ground_contact_rest_takeoff_and_landing():
    hover = AIRFRAME.hover_rotor_speed
    sim = Simulator(AIRFRAME, yaw=1.0)
    assert sim.on_ground
    sim.set_rotor_commands(np.full(4, 0.95 * hover))  # below weight: stays down
    sim.step(1000)
    assert sim.on_ground and sim.state.position[2] == 0.0 and np.all(sim.state.velocity == 0.0)
    sim.set_rotor_commands(np.full(4, 1.1 * hover))  # above weight: climbs
    sim.step(1000)
    assert not sim.on_ground and sim.state.position[2] < -0.3
    sim.set_rotor_commands(np.zeros(4))
    lowest = 0.0
    for _ in range(3000):
        sim.step(1)
        lowest = max(lowest, sim.state.position[2])
    assert lowest == 0.0  # never below the ground
    state = sim.state
    assert sim.on_ground
    assert np.all(state.velocity == 0.0) and np.all(state.angular_velocity == 0.0)
    roll, pitch, yaw = euler_from_quat(state.quaternion)
    assert roll == pytest.approx(0.0, abs=1e-12) and pitch == pytest.approx(0.0, abs=1e-12)
    assert yaw == pytest.approx(1.0, abs=1e-9)


def test_landing_levels_a_tilted_body_and_keeps_yaw():
    sim = Simulator(AIRFRAME, position=(0.0, 0.0, -0.5))
    sim.set_state(
        VehicleState(
            position=np.array([0.0, 0.0, -0.5]),
            quaternion=quat_from_euler(0.2, -0.1, -2.0),
            angular_velocity=np.array([0.5, 0.5, 0.0]),
        )
    )
    sim.step(1000)
    assert sim.on_ground
    roll, pitch, yaw = euler_from_quat(sim.state.quaternion)
    assert abs(roll) < 1e-12 and abs(pitch) < 1e-12
    assert yaw == pytest.approx(euler_from_quat(quat_from_euler(0.2, -0.1, -2.0))[2], abs=0.05)


def _noisy_sim(seed: int) -> Simulator:
    return Simulator(
        AIRFRAME,
        wind=WindConfig(6.0, 45.0, 3.0, 0.2, 0.3, turbulence_w20_m_s=8.0),
        disturbance=DisturbanceConfig(sample_time_s=0.01),
        sensor_noise=SensorNoise(),
        seed=seed,
        position=(0.0, 0.0, -5.0),
        rotor_speed=AIRFRAME.hover_rotor_speed,
    )


def test_same_seed_same_flight_and_batching_does_not_matter():
    a, b, c = _noisy_sim(5), _noisy_sim(5), _noisy_sim(6)
    for _ in range(100):
        a.step(4)
        for _ in range(4):
            b.step(1)
        c.step(4)
    np.testing.assert_array_equal(a.state.position, b.state.position)
    np.testing.assert_array_equal(a.measure().position, b.measure().position)
    assert not np.allclose(a.state.position, c.state.position)
    a.reset(position=(0.0, 0.0, -5.0), rotor_speed=AIRFRAME.hover_rotor_speed)
    a.step(400)
    replay = _noisy_sim(5)
    replay.step(400)
    np.testing.assert_array_equal(a.state.position, replay.state.position)


def test_airframe_data_file_and_overrides(tmp_path):
    assert Airframe.table2() == Airframe()
    assert Airframe().thrust_to_weight == pytest.approx(2.23, abs=0.01)
    assert Airframe().hover_thrust == pytest.approx(1.3 * 9.81 / Airframe().max_thrust_n)
    path = tmp_path / "heavy.json"
    path.write_text('{"mass": 2.0, "_note": "comment"}')
    heavy = Airframe.from_file(path)
    assert heavy.mass == 2.0 and heavy.ixx == AIRFRAME.ixx
    with pytest.raises(ModelParameterError, match="unknown"):
        AIRFRAME.replace(wingspan=3.0)
    with pytest.raises(ModelParameterError, match="positive"):
        AIRFRAME.replace(mass=0.0)
    path.write_text("not json")
    with pytest.raises(ModelParameterError):
        Airframe.from_file(path)


def test_bad_simulator_inputs_raise_typed_errors():
    sim = Simulator()
    with pytest.raises(ModelParameterError):
        sim.set_rotor_commands([1.0, 2.0])
    with pytest.raises(ModelParameterError):
        sim.set_rotor_commands([1.0, 2.0, math.nan, 3.0])
    with pytest.raises(ModelParameterError):
        sim.step(-1)
    with pytest.raises(ModelParameterError):
        Simulator(dt=0.0)
    sim.set_rotor_commands([1e6, -5.0, 100.0, 100.0])
    np.testing.assert_array_equal(sim.rotor_commands, [AIRFRAME.rotor_speed_max, 0.0, 100.0, 100.0])


def test_reconfigure_mid_flight_keeps_state_and_time():
    sim = Simulator(AIRFRAME, position=(0.0, 0.0, -20.0), rotor_speed=AIRFRAME.hover_rotor_speed)
    sim.step(500)
    before = sim.state
    sim.reconfigure(wind=WindConfig(5.0, 180.0), airframe=AIRFRAME.replace(mass=2.6))
    assert sim.t == before.t
    np.testing.assert_array_equal(sim.state.position, before.position)
    sim.step(100)
    np.testing.assert_allclose(sim.last_disturbance["wind_ned"], [5.0, 0.0, 0.0], atol=1e-12)
    assert sim.state.velocity[2] > 0.3  # twice the mass on the same rotor speed sinks at about g / 2
    assert sim.state.velocity[0] > 0.0  # pushed north by a wind from the south


def test_disturbance_terms_do_not_lift_a_grounded_body():
    """The paper's variance-15 disturbances would push a resting vehicle around; the ground holds it."""
    sim = Simulator(
        AIRFRAME, disturbance=DisturbanceConfig.paper(), seed=3, rotor_speed=0.9 * AIRFRAME.hover_rotor_speed
    )
    for _ in range(200):
        sim.step(50)
        assert sim.on_ground and sim.state.position[2] == 0.0
        np.testing.assert_array_equal(sim.last_disturbance["d_accel_ned"], 0.0)
    sim.set_rotor_commands(np.full(4, 1.2 * AIRFRAME.hover_rotor_speed))
    sim.step(500)
    assert not sim.on_ground and np.any(sim.last_disturbance["d_accel_ned"] != 0.0)
