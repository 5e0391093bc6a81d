"""The compiled inner loop (Simulator.run_pid_attitude_steps) equals stepping measure / PID / mixer / physics
from Python: same state, same random streams, same controller state and mixer counters."""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_sitl_vehicle import HOME, short_mission

from sitl_quad.attitude_pid import PidAttitudeController
from sitl_quad.config import VehicleConfig
from sitl_quad.disturbances import DisturbanceConfig
from sitl_quad.rotors import Mixer
from sitl_quad.sensors import SensorNoise, Sensors
from sitl_quad.simulator import Simulator
from sitl_quad.vehicle import Vehicle
from sitl_quad.wind import WindConfig
from uavcore.airframe import Airframe, ModelParameterError
from uavcore.rotation import quat_from_euler
from uavcore.state import AttitudeTarget

AIRFRAME = Airframe.table2()
ATTITUDE_STEPS, PHYSICS_STEPS, ATTITUDE_DT = 5, 4, 0.004
TOLERANCE = 1e-12
# every random source on; a disturbance sample every 10 physics steps, so samples fall inside attitude steps
WIND = WindConfig(
    speed_m_s=4.0, direction_from_deg=60.0, gust_amplitude_m_s=3.0, gust_start_s=0.3, turbulence_w20_m_s=2.0
)
DISTURBANCE = DisturbanceConfig(0.2, 0.2, 0.2, 0.5, 0.5, 0.5, sample_time_s=0.01)


def step_by_step(
    sim: Simulator,
    controller: PidAttitudeController,
    mixer: Mixer,
    target: AttitudeTarget,
    thrust_n: float,
    apply_torque: bool,
) -> bool:
    """What Vehicle.tick does for an attitude controller it cannot compile."""
    saturated = False
    for _ in range(ATTITUDE_STEPS):
        torque = controller.update(target, sim.measure(), ATTITUDE_DT)
        if not apply_torque:
            torque = np.zeros(3)
        sim.set_rotor_commands(mixer.rotor_commands(thrust_n, torque))
        saturated = saturated or mixer.saturated
        sim.step(PHYSICS_STEPS)
    return saturated


def snapshot(sim: Simulator, controller: PidAttitudeController) -> np.ndarray:
    s = sim.state
    return np.concatenate(
        [
            s.position,
            s.velocity,
            s.quaternion,
            s.angular_velocity,
            s.rotor_speeds,
            sim.rotor_commands,
            *sim.last_disturbance.values(),
            controller.kernel_state,
            sim.measure().position,
        ]
    )  # the next measurement: the noise stream's position


def schedule() -> list[tuple[AttitudeTarget, float, bool]]:
    """(target, thrust N, apply torque) per tick: idle on the ground, lift-off, tilt and yaw steps with body-rate
    feed-forward, then full thrust with a roll step the rotors cannot give (the mixer saturates)."""
    level = np.array([1.0, 0.0, 0.0, 0.0])
    hover = AIRFRAME.mass * AIRFRAME.g
    ticks = [(AttitudeTarget(level, 0.05), 0.05 * AIRFRAME.max_thrust_n, False)] * 10
    ticks += [(AttitudeTarget(level, 0.0), 1.3 * hover, True)] * 15
    ticks += [(AttitudeTarget(quat_from_euler(0.3, -0.2, 2.5), 0.0, np.array([0.2, -0.1, 0.4])), hover, True)] * 15
    ticks += [(AttitudeTarget(quat_from_euler(-1.2, 0.0, -3.0), 0.0), AIRFRAME.max_thrust_n, True)] * 10
    return ticks


def test_compiled_inner_loop_equals_stepping_from_python():
    def make():
        sim = Simulator(AIRFRAME, wind=WIND, disturbance=DISTURBANCE, sensor_noise=SensorNoise(), seed=11)
        return sim, PidAttitudeController(), Mixer(AIRFRAME)

    fused, stepped = make(), make()
    saturated_ticks, ground_ticks = 0, 0
    for target, thrust_n, apply_torque in schedule():
        a = fused[0].run_pid_attitude_steps(
            fused[1], fused[2], target, thrust_n, ATTITUDE_STEPS, PHYSICS_STEPS, ATTITUDE_DT, apply_torque=apply_torque
        )
        b = step_by_step(*stepped, target, thrust_n, apply_torque)
        assert a == b
        saturated_ticks += a
        (sim_a, controller_a, mixer_a), (sim_b, controller_b, mixer_b) = fused, stepped
        np.testing.assert_allclose(snapshot(sim_a, controller_a), snapshot(sim_b, controller_b), rtol=0, atol=TOLERANCE)
        assert sim_a.step_index == sim_b.step_index and sim_a.on_ground == sim_b.on_ground
        assert (mixer_a.calls, mixer_a.saturated_steps, mixer_a.saturated) == (
            mixer_b.calls,
            mixer_b.saturated_steps,
            mixer_b.saturated,
        )
        ground_ticks += sim_a.on_ground
    # the schedule did reach the cases it is for
    assert 0 < ground_ticks < len(schedule()) and saturated_ticks > 0
    assert fused[2].calls == ATTITUDE_STEPS * len(schedule()) and fused[2].saturated_steps > 0


class StepByStepPid:
    """The same PID law seen only through the AttitudeController protocol: Vehicle.tick steps it from Python."""

    def __init__(self, pid: PidAttitudeController) -> None:
        self.pid = pid

    def reset(self) -> None:
        self.pid.reset()

    def update(self, target, state, dt):
        return self.pid.update(target, state, dt)


def test_vehicle_flies_the_same_with_the_compiled_loop_and_step_by_step():
    config = VehicleConfig(wind=WIND)

    def make() -> Vehicle:
        vehicle = Vehicle(config, home=HOME, seed=5)
        vehicle.set_mission(short_mission())
        return vehicle

    fused, stepped = make(), make()
    stepped.attitude = StepByStepPid(stepped.attitude)
    sources = set()
    for tick in range(300):  # 6 s: 0.2 s disarmed, 1 s spool-up at idle, then the climb toward the waypoint
        if tick == 10:
            for vehicle in (fused, stepped):
                assert vehicle.arm() == 0 and vehicle.start_mission() == 0
        a, b = fused.tick(), stepped.tick()
        assert a.source == b.source
        sources.add(a.source)
        for x, y in [(a.truth, b.truth), (a.estimate, b.estimate)]:
            for name in ("position", "velocity", "quaternion", "angular_velocity", "rotor_speeds"):
                np.testing.assert_allclose(getattr(x, name), getattr(y, name), rtol=0, atol=TOLERANCE)
        assert fused.saturated_ticks == stepped.saturated_ticks
    assert sources == {"off", "idle", "builtin"}
    assert -fused.sim.state.position[2] > 2.0  # it did fly
    np.testing.assert_allclose(fused.attitude.kernel_state, stepped.attitude.pid.kernel_state, rtol=0, atol=TOLERANCE)
    assert (fused.mixer.calls, fused.mixer.saturated_steps) == (stepped.mixer.calls, stepped.mixer.saturated_steps)


def test_sensor_noise_is_the_seeds_normals_in_order_however_drawn():
    noise = SensorNoise(position_std_m=0.1, velocity_std_m_s=0.2, attitude_std_rad=0.01, gyro_std_rad_s=0.05)
    std = np.repeat([0.1, 0.2, 0.01, 0.05], 3)
    expected = np.random.default_rng(4).standard_normal((7, 12)) * std  # 12 normals per measurement
    sensors = Sensors(noise, seed=4)
    drawn = np.vstack([sensors.noise(1), sensors.noise(5), sensors.noise(1)])
    np.testing.assert_array_equal(drawn, expected)
    assert not np.any(Sensors(SensorNoise.none(), seed=4).noise(3))


def test_non_finite_thrust_bad_step_counts_and_malformed_targets_are_refused():
    sim, controller, mixer = Simulator(AIRFRAME, position=(0.0, 0.0, -10.0)), PidAttitudeController(), Mixer(AIRFRAME)
    level = AttitudeTarget(np.array([1.0, 0.0, 0.0, 0.0]), 0.5)
    with pytest.raises(ModelParameterError, match="finite"):
        sim.run_pid_attitude_steps(controller, mixer, level, math.nan, ATTITUDE_STEPS, PHYSICS_STEPS, ATTITUDE_DT)
    assert sim.step_index == 0 and mixer.calls == 0  # stopped before the first rotor command
    for steps, physics, dt in [(-1, 4, 0.004), (5, 0, 0.004), (5, 4, 0.0), (2.5, 4, 0.004)]:
        with pytest.raises(ModelParameterError):
            sim.run_pid_attitude_steps(controller, mixer, level, 10.0, steps, physics, dt)
    with pytest.raises(ModelParameterError, match="body rates"):
        sim.run_pid_attitude_steps(
            controller,
            mixer,
            AttitudeTarget(level.quaternion, 0.5, np.zeros(2)),
            10.0,
            ATTITUDE_STEPS,
            PHYSICS_STEPS,
            ATTITUDE_DT,
        )
    with pytest.raises(ModelParameterError, match="quaternion"):
        controller.update(AttitudeTarget(np.ones(3), 0.5), sim.state, ATTITUDE_DT)
