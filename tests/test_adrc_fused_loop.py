"""The vehicle's compiled ADRC inner loop (sitl_quad.attitude_loops: one numba call per outer tick) flies bit for
bit what stepping AdrcAttitudeController.update, the mixer and the physics from Python flies: same torques, same
body, same random streams, same observer states; the vehicle takes the compiled path when MC_ATT_CTRL=1."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from test_sitl_fused_loop import (
    AIRFRAME,
    ATTITUDE_DT,
    ATTITUDE_STEPS,
    DISTURBANCE,
    PHYSICS_STEPS,
    WIND,
    schedule,
    step_by_step,
)
from test_sitl_fused_loop import snapshot as pid_loop_snapshot
from test_sitl_vehicle import HOME, short_mission

from adrc_offboard.adrc import AdrcChannel
from adrc_offboard.adrc_attitude import AdrcAttitudeController, attitude_errors
from adrc_offboard.design import adrc_attitude_gains, load_design
from sitl_quad.attitude_loops import CompiledAdrcAttitudeLoop, adrc_inner_loop, attitude_loops
from sitl_quad.config import AttitudeControllerKind, ControlConfig, VehicleConfig
from sitl_quad.flight_loop import CompiledAttitudeLoop
from sitl_quad.rotors import Mixer
from sitl_quad.sensors import SensorNoise
from sitl_quad.simulator import Simulator
from sitl_quad.vehicle import Vehicle
from uavcore.airframe import ModelParameterError
from uavcore.rotation import quat_from_euler
from uavcore.state import AttitudeTarget, VehicleState

RATE_HZ = 1.0 / ATTITUDE_DT


def snapshot(sim: Simulator, controller: AdrcAttitudeController) -> np.ndarray:
    """test_sitl_fused_loop's snapshot (body, commands, disturbances, next noise) with the ADRC's state."""
    state = np.concatenate([controller.channel_states.ravel(), controller.loop_state])
    return pid_loop_snapshot(sim, SimpleNamespace(kernel_state=state))


def test_compiled_adrc_loop_equals_stepping_update_from_python_bit_for_bit():
    def make():
        sim = Simulator(AIRFRAME, wind=WIND, disturbance=DISTURBANCE, sensor_noise=SensorNoise(), seed=11)
        return sim, CompiledAdrcAttitudeLoop.for_airframe(AIRFRAME, rate_hz=RATE_HZ), Mixer(AIRFRAME)

    fused, stepped = make(), make()
    saturated_ticks, ground_ticks = 0, 0
    for target, thrust_n, apply_torque in schedule():  # idle, lift-off, steps with yaw feed-forward, saturation
        sim_a, controller_a, mixer_a = fused
        a = sim_a.run_attitude_steps(
            controller_a.inner_loop,
            controller_a.kernel_arguments(target),
            mixer_a,
            thrust_n,
            ATTITUDE_STEPS,
            PHYSICS_STEPS,
            ATTITUDE_DT,
            apply_torque,
        )
        b = step_by_step(*stepped, target, thrust_n, apply_torque)
        assert a == b
        saturated_ticks += a
        sim_b, controller_b, mixer_b = stepped
        np.testing.assert_array_equal(snapshot(sim_a, controller_a), snapshot(sim_b, controller_b))
        assert sim_a.step_index == sim_b.step_index and sim_a.on_ground == sim_b.on_ground
        assert (mixer_a.calls, mixer_a.saturated_steps) == (mixer_b.calls, mixer_b.saturated_steps)
        ground_ticks += sim_a.on_ground
    assert 0 < ground_ticks < len(schedule()) and saturated_ticks > 0
    assert np.all(fused[1].channel_states[:, 0] == 1.0)  # every channel started


def _vehicle(attitude_loops_given) -> Vehicle:
    config = VehicleConfig(wind=WIND, disturbance=DISTURBANCE, control=ControlConfig(AttitudeControllerKind.ADRC))
    vehicle = Vehicle(config, home=HOME, seed=5, attitude_loops=attitude_loops_given)
    vehicle.set_mission(short_mission())
    return vehicle


def test_vehicle_flies_the_same_with_the_compiled_adrc_loop_and_step_by_step():
    def python_adrc(config: VehicleConfig, rate_hz: float) -> AdrcAttitudeController:
        gains = adrc_attitude_gains(config.airframe, load_design("adrc"))  # the vehicle's, as attitude_loops has them
        return AdrcAttitudeController.for_airframe(config.airframe, gains=gains, rate_hz=rate_hz)  # stepped

    fused = _vehicle(attitude_loops())
    stepped = _vehicle({AttitudeControllerKind.ADRC: python_adrc})
    assert isinstance(fused.attitude, CompiledAttitudeLoop) and not isinstance(stepped.attitude, CompiledAttitudeLoop)
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
                np.testing.assert_array_equal(getattr(x, name), getattr(y, name))
    assert sources == {"off", "idle", "builtin"}
    assert -fused.sim.state.position[2] > 2.0  # it did fly
    np.testing.assert_array_equal(fused.attitude.channel_states, stepped.attitude.channel_states)
    assert fused.attitude.disturbance_estimates() == stepped.attitude.disturbance_estimates()
    assert (fused.mixer.calls, fused.mixer.saturated_steps) == (stepped.mixer.calls, stepped.mixer.saturated_steps)


def test_compiled_adrc_loop_refuses_non_finite_thrust_and_malformed_targets():
    sim, mixer = Simulator(AIRFRAME, position=(0.0, 0.0, -10.0)), Mixer(AIRFRAME)
    controller = CompiledAdrcAttitudeLoop.for_airframe(AIRFRAME, rate_hz=RATE_HZ)
    level = AttitudeTarget(np.array([1.0, 0.0, 0.0, 0.0]), 0.5)
    with pytest.raises(ModelParameterError, match="finite"):
        law = controller.kernel_arguments(level)
        sim.run_attitude_steps(adrc_inner_loop, law, mixer, math.nan, ATTITUDE_STEPS, PHYSICS_STEPS, ATTITUDE_DT)
    assert sim.step_index == 0 and mixer.calls == 0  # stopped before the first rotor command
    with pytest.raises(ValueError, match="body rates of 3"):
        controller.kernel_arguments(AttitudeTarget(level.quaternion, 0.5, np.zeros(2)))


def test_the_attitude_kernel_runs_the_channel_kernels_the_outer_loop_runs():
    """adrc_attitude_torque against three AdrcChannel objects stepped from Python with the same errors, angles and
    actuator model (the module's docstring): equal torques and observer states. With a stale numba cache of
    adrc_attitude.py (edits to adrc.py's kernels do not invalidate it) this fails: delete __pycache__/*.nbi."""
    controller = AdrcAttitudeController.for_airframe(AIRFRAME, rate_hz=RATE_HZ)
    channels = [AdrcChannel(channel.parameters, channel.h) for channel in controller.channels]
    lag = 1.0 - math.exp(-ATTITUDE_DT / AIRFRAME.motor_time_constant)
    theta, actuator = np.zeros(3), np.zeros(3)
    rng = np.random.default_rng(3)
    for step in range(200):
        target = AttitudeTarget(quat_from_euler(*rng.normal(0.0, 0.3, 3)), 0.5, rng.normal(0.0, 0.2, 3))
        q = quat_from_euler(*rng.normal(0.0, 0.3, 3))
        rates = rng.normal(0.0, 0.5, 3)
        state = VehicleState(t=step * ATTITUDE_DT, quaternion=q, angular_velocity=rates)
        torque = controller.update(target, state, ATTITUDE_DT)
        errors = attitude_errors(q, target.quaternion)
        for i, channel in enumerate(channels):
            reference_rate = target.body_rates[2] if i == 2 else 0.0
            u = channel.control(theta[i] + errors[i], theta[i], reference_rate, 0.0, rates[i])
            actuator[i] += (u - actuator[i]) * lag
            channel.observe_applied(actuator[i])
            theta[i] += rates[i] * ATTITUDE_DT
            assert torque[i] == u
    for channel, ours in zip(channels, controller.channels, strict=True):
        assert channel.state() == ours.state()
