"""Closed loop as the vehicle composes it: 50 Hz PX4-style position loop, 250 Hz PID attitude loop, mixer,
1 kHz physics. Takeoff, a long hover, a 10 m/s straight leg (calm and windy), a velocity-controlled landing."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest

from sitl_quad.attitude_pid import PidAttitudeController
from sitl_quad.disturbances import DisturbanceConfig
from sitl_quad.position_control import PidPositionController
from sitl_quad.rotors import Mixer
from sitl_quad.sensors import SensorNoise
from sitl_quad.simulator import Simulator
from sitl_quad.wind import WindConfig
from uavcore.airframe import Airframe
from uavcore.rotation import euler_from_quat
from uavcore.state import TrajectorySetpoint

AIRFRAME = Airframe.table2()
ALTITUDE = 5.0


class Pilot:
    """The vehicle's loop in miniature: what sitl_quad's server does each tick, minus MAVLink."""

    def __init__(self, sim: Simulator) -> None:
        self.sim = sim
        self.attitude = PidAttitudeController()
        self.position = PidPositionController(sim.airframe)
        self.mixer = Mixer(sim.airframe)
        self.target = None

    def fly(self, setpoint_at: Callable[[float], TrajectorySetpoint], seconds: float) -> np.ndarray:
        """Fly for `seconds`; returns rows [t, x, y, z, vx, vy, vz, roll, pitch, yaw] every 20 ms."""
        sim, rows = self.sim, []
        for k in range(round(seconds * 250)):
            if k % 5 == 0:
                self.target = self.position.update(setpoint_at(sim.t), sim.measure(), 0.02)
                state = sim.state
                rows.append([sim.t, *state.position, *state.velocity, *euler_from_quat(state.quaternion)])
            torque = self.attitude.update(self.target, sim.measure(), 0.004)
            thrust_n = self.target.thrust * sim.airframe.max_thrust_n
            sim.set_rotor_commands(self.mixer.rotor_commands(thrust_n, torque))
            sim.step(4)
        return np.array(rows)


def hold(position) -> Callable[[float], TrajectorySetpoint]:
    point = np.array(position, dtype=float)
    return lambda t: TrajectorySetpoint(position=point)


def straight_leg(start_time: float, speed: float = 10.0, accel: float = 2.5):
    """Northward leg at ALTITUDE: accelerate at `accel` to `speed`, then cruise (position, velocity, accel)."""
    ramp = speed / accel

    def setpoint(t: float) -> TrajectorySetpoint:
        tau = max(t - start_time, 0.0)
        if tau < ramp:
            x, v, a = 0.5 * accel * tau * tau, accel * tau, accel
        else:
            x, v, a = 0.5 * accel * ramp * ramp + speed * (tau - ramp), speed, 0.0
        return TrajectorySetpoint(
            position=np.array([x, 0.0, -ALTITUDE]),
            velocity=np.array([v, 0.0, 0.0]),
            acceleration=np.array([a, 0.0, 0.0]),
        )

    return setpoint


def test_takeoff_to_5_m_from_the_ground():
    sim = Simulator(AIRFRAME)
    rows = Pilot(sim).fly(hold([0.0, 0.0, -ALTITUDE]), 8.0)
    altitude = -rows[:, 3]
    assert altitude.max() < ALTITUDE + 0.2  # no big overshoot
    reached = rows[np.argmax(altitude > ALTITUDE - 0.1), 0]
    assert 1.0 < reached < 5.0  # climb rate is limited to 3 m/s
    assert np.all(np.abs(altitude[rows[:, 0] > 6.0] - ALTITUDE) < 0.05)
    assert np.abs(rows[:, 1:3]).max() < 1e-6 and not sim.on_ground


def test_sixty_second_hover_does_not_drift():
    """Take off from the ground, then hold for a minute: no NaN, no drift, no yaw creep."""
    sim = Simulator(AIRFRAME, position=(3.0, -2.0, 0.0), yaw=0.7)
    setpoint = TrajectorySetpoint(position=np.array([3.0, -2.0, -ALTITUDE]), yaw=0.7)
    rows = Pilot(sim).fly(lambda t: setpoint, 70.0)
    assert np.all(np.isfinite(rows))
    settled = rows[rows[:, 0] >= 10.0]
    assert np.abs(settled[:, 1:4] - [3.0, -2.0, -ALTITUDE]).max() < 0.03
    assert np.abs(settled[:, 4:7]).max() < 0.01
    assert np.abs(rows[:, 9] - 0.7).max() < 1e-3


def _fly_leg(sim: Simulator) -> tuple[np.ndarray, Callable[[float], TrajectorySetpoint]]:
    pilot = Pilot(sim)
    pilot.fly(hold([0.0, 0.0, -ALTITUDE]), 6.0)
    leg = straight_leg(sim.t)
    rows = pilot.fly(leg, 15.0)
    return rows, leg


def test_ten_metre_per_second_leg_in_still_air():
    rows, leg = _fly_leg(Simulator(AIRFRAME))
    along = np.array([leg(t).position[0] for t in rows[:, 0]]) - rows[:, 1]
    assert np.abs(along).max() < 1.0
    assert np.abs(rows[:, 2]).max() < 0.01  # cross-track
    assert np.abs(rows[:, 3] + ALTITUDE).max() < 0.1
    cruise = rows[rows[:, 0] > rows[0, 0] + 10.0]
    assert np.all(np.abs(cruise[:, 4] - 10.0) < 0.2)
    # drag holds the cruise tilt near the documented 12 degrees (nose down = negative pitch)
    assert math.degrees(np.mean(cruise[:, 8])) == pytest.approx(-12.0, abs=1.5)


def test_ten_metre_per_second_leg_through_crosswind_gust_turbulence_and_noise():
    sim = Simulator(
        AIRFRAME,
        wind=WindConfig(
            6.0,
            270.0,
            gust_amplitude_m_s=4.0,
            gust_rise_time_s=0.1,
            gust_start_s=12.0,
            gust_hold_s=1.0,
            gust_direction_from_deg=270.0,
            turbulence_w20_m_s=6.0,
        ),
        disturbance=DisturbanceConfig(),
        sensor_noise=SensorNoise(),
        seed=21,
    )
    rows, leg = _fly_leg(sim)
    along = np.array([leg(t).position[0] for t in rows[:, 0]]) - rows[:, 1]
    assert np.all(np.isfinite(rows))
    assert np.abs(along).max() < 2.0
    assert np.abs(rows[:, 2]).max() < 1.0
    assert np.abs(rows[:, 3] + ALTITUDE).max() < 0.5


def test_velocity_mode_descent_lands_and_stays_down():
    sim = Simulator(AIRFRAME, position=(0.0, 0.0, -3.0), rotor_speed=AIRFRAME.hover_rotor_speed)
    descend = TrajectorySetpoint(position=np.array([0.0, 0.0, math.nan]), velocity=np.array([0.0, 0.0, 1.0]))
    rows = Pilot(sim).fly(lambda t: descend, 5.0)
    assert sim.on_ground and sim.state.position[2] == 0.0
    falling = rows[(rows[:, 3] < -0.5) & (rows[:, 0] > 1.5)]
    np.testing.assert_allclose(falling[:, 6], 1.0, atol=0.1)
