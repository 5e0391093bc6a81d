"""Outer loops (ADRC and PID) on a point mass at 50 Hz, and once with the ADRC attitude loop on the simulator."""

from __future__ import annotations

import math

import numpy as np
import pytest

from adrc_offboard.adrc import AdrcParameterError
from adrc_offboard.adrc_attitude import AdrcAttitudeController
from adrc_offboard.outer_loop import (
    AccelerationLimits,
    AdrcOuterLoop,
    PidOuterLoop,
    applied_acceleration,
    matched_gains,
    pid_gains_for_bandwidth,
)
from uavcore.state import TrajectorySetpoint, VehicleState

MASS, G = 1.3, 9.81
MAX_THRUST = 2.2 * MASS * G
MAX_TILT = math.radians(35.0)
DT = 0.02


class PointMass:
    """x'' = the acceleration the attitude target asks for (thrust along the body's -z, plus gravity) plus an
    external disturbance acceleration; optionally through a first-order lag standing in for the attitude
    loop. Integrated exactly over 20 sub-steps per controller step."""

    def __init__(self, lag: float = 0.0) -> None:
        self.position = np.zeros(3)
        self.velocity = np.zeros(3)
        self.acceleration = np.zeros(3)
        self.lag = lag

    def state(self) -> VehicleState:
        return VehicleState(position=self.position.copy(), velocity=self.velocity.copy())

    def advance(self, commanded: np.ndarray, disturbance: np.ndarray) -> None:
        h = DT / 20
        for _ in range(20):
            if self.lag:
                self.acceleration = self.acceleration + (commanded - self.acceleration) * h / self.lag
            else:
                self.acceleration = commanded
            total = self.acceleration + disturbance
            self.position = self.position + self.velocity * h + 0.5 * total * h * h
            self.velocity = self.velocity + total * h


# The laws at one matched bandwidth and fixed limits, not the shipped design's numbers (tests/test_design.py):
# what these tests say holds for the control laws themselves.
MATCHED = matched_gains(2.0, 2.5, observer_ratio=4.0, integral_ratio=0.25)
LIMITS = AccelerationLimits(6.0, 4.0, 3.0)


def make(kind: str):
    if kind == "adrc":
        return AdrcOuterLoop(MASS, G, MAX_THRUST, MAX_TILT, gains=MATCHED[0], limits=LIMITS)
    return PidOuterLoop(MASS, G, MAX_THRUST, MAX_TILT, gains=MATCHED[1], limits=LIMITS)


def run(controller, seconds, setpoint_at, disturbance=(0.0, 0.0, 0.0), lag=0.0):
    plant = PointMass(lag)
    d = np.asarray(disturbance, dtype=float)
    trace = []
    for k in range(round(seconds / DT)):
        setpoint = setpoint_at(k * DT)
        target = controller.update(setpoint, plant.state(), DT)
        trace.append((k * DT, plant.position.copy(), target))
        plant.advance(np.array(applied_acceleration(target, MASS, G, MAX_THRUST)), d)
    return trace


def hold(position):
    return lambda t: TrajectorySetpoint(position=np.asarray(position, dtype=float))


@pytest.mark.parametrize("lag", [0.0, 0.08])
def test_adrc_rejects_a_crosswind_and_its_eso_estimates_it(lag: float) -> None:
    # 1.5 m/s^2 east, 1 m/s^2 south: a crosswind's drag on the airframe (z3 has the disturbance's sign)
    controller = make("adrc")
    trace = run(controller, 12.0, hold((0.0, 0.0, -5.0)), disturbance=(-1.0, 1.5, 0.0), lag=lag)
    late = np.array([p for t, p, _ in trace if t > 8.0])
    assert np.max(np.abs(late - [0.0, 0.0, -5.0])) < 2e-3
    peak = max(np.max(np.abs(p[:2])) for _, p, _ in trace)
    assert peak > 0.05  # the wind did push it
    estimates = controller.disturbance_estimates()
    assert estimates["x"] == pytest.approx(-1.0, abs=0.01)
    assert estimates["y"] == pytest.approx(1.5, abs=0.01)
    assert estimates["z"] == pytest.approx(0.0, abs=0.01)


def test_pid_with_its_integrator_also_rejects_a_crosswind() -> None:
    controller = make("pid")
    trace = run(controller, 20.0, hold((0.0, 0.0, -5.0)), disturbance=(-1.0, 1.5, 0.0))
    late = np.array([p for t, p, _ in trace if t > 16.0])
    assert np.max(np.abs(late - [0.0, 0.0, -5.0])) < 5e-3
    assert controller.disturbance_estimates() == {}
    assert controller.telemetry()["integral_y"] == pytest.approx(-1.5, abs=0.01)


def test_adrc_settles_faster_than_the_matched_pid_after_a_gust() -> None:
    # same bandwidth (MATCHED), same disturbance: the ESO cancels it, the integrator has to wind
    errors = {}
    for kind in ("adrc", "pid"):
        trace = run(make(kind), 10.0, hold((0.0, 0.0, 0.0)), disturbance=(0.0, 2.0, 0.0))
        errors[kind] = np.array([abs(p[1]) for _, p, _ in trace])
    assert errors["adrc"].max() < errors["pid"].max()
    assert errors["adrc"][-50:].max() < 0.1 * errors["pid"][-50:].max()


@pytest.mark.parametrize(("kind", "max_overshoot"), [("adrc", 0.02), ("pid", 0.25)])
def test_position_step_overshoot(kind: str, max_overshoot: float) -> None:
    # ADRC: the NLSEF's fhan approaches along its time-optimal curve. PID: the integrator's zero in a
    # one-degree-of-freedom PID gives about 19% for poles (s + wc)^2 (s + wc / 4) (its linear design value).
    step = np.array([0.5, 0.0, -0.5])
    trace = run(make(kind), 10.0, hold(step))
    positions = np.array([p for _, p, _ in trace])
    overshoot = max(positions[:, 0].max() / step[0] - 1.0, positions[:, 2].min() / step[2] - 1.0)
    assert overshoot < max_overshoot
    assert np.allclose(positions[-1], step, atol=5e-3)


@pytest.mark.parametrize("kind", ["adrc", "pid"])
def test_tilt_and_thrust_limits_hold_on_a_huge_step(kind: str) -> None:
    trace = run(make(kind), 4.0, hold((200.0, -150.0, -60.0)))
    for _, _, target in trace:
        _, x, y, _ = target.quaternion
        tilt = math.acos(max(-1.0, min(1.0, 1.0 - 2.0 * (x * x + y * y))))
        assert tilt <= MAX_TILT + 1e-9
        assert 0.0 <= target.thrust <= 1.0
        ax, ay, _ = applied_acceleration(target, MASS, G, MAX_THRUST)
        assert math.hypot(ax, ay) <= LIMITS.max_horizontal + 1e-9
    # it is really pushing at the limit: the horizontal acceleration is saturated at the start
    ax, ay, _ = applied_acceleration(trace[5][2], MASS, G, MAX_THRUST)
    assert math.hypot(ax, ay) == pytest.approx(LIMITS.max_horizontal, rel=1e-6)


def test_adrc_follows_a_moving_setpoint_with_feed_forward() -> None:
    # the navigator's reference: 10 m/s north after a 2 m/s^2 ramp; feed-forward keeps the error small
    def leg(t: float) -> TrajectorySetpoint:
        ramp = 5.0
        if t < ramp:
            x, v, a = t * t, 2.0 * t, 2.0
        else:
            x, v, a = 25.0 + 10.0 * (t - ramp), 10.0, 0.0
        return TrajectorySetpoint(
            position=np.array([x, 0.0, 0.0]), velocity=np.array([v, 0.0, 0.0]), acceleration=np.array([a, 0.0, 0.0])
        )

    trace = run(make("adrc"), 12.0, leg, lag=0.05)
    errors = [np.linalg.norm(p - leg(t).position) for t, p, _ in trace]
    assert max(errors) < 0.1


def test_matched_gains_place_the_same_poles() -> None:
    omega_c = 2.0
    adrc, pid = matched_gains(omega_c, 2.5, observer_ratio=4.0, integral_ratio=0.25)
    # PID: s^3 + kd s^2 + kp s + ki = (s + wc)^2 (s + wc/4)
    k = pid.horizontal
    assert np.allclose(np.sort(np.roots([1.0, k.kd, k.kp, k.ki]).real), [-omega_c, -omega_c, -0.5])
    # ADRC: NLSEF linear zone kp = 1/h1^2 = wc^2, kd = 2c/h1 = 2 wc; ESO linear zone at -4 wc
    h = adrc.horizontal
    assert (1.0 / h.h1**2, 2.0 * h.c / h.h1) == pytest.approx((omega_c**2, 2 * omega_c))
    observer = h.make_observer(DT)
    l1, l2, l3 = observer.linear_zone_gains()
    assert np.allclose(np.roots([1.0, l1, l2, l3]).real, -4.0 * omega_c, rtol=1e-3)


def test_refuses_bad_construction() -> None:
    with pytest.raises(AdrcParameterError):
        AdrcOuterLoop(MASS, G, 0.5 * MASS * G)  # cannot lift itself
    with pytest.raises(AdrcParameterError):
        PidOuterLoop(MASS, G, MAX_THRUST, max_tilt_rad=2.0)
    with pytest.raises(AdrcParameterError):
        AccelerationLimits(max_horizontal=-1.0)
    with pytest.raises(AdrcParameterError):
        pid_gains_for_bandwidth(0.0)


def test_closed_loop_on_the_simulator_hover_and_a_10_m_s_leg() -> None:
    # AdrcOuterLoop (50 Hz) + AdrcAttitudeController (250 Hz) + the Mixer on the SITL physics (1 kHz)
    from sitl_quad.rotors import Mixer
    from sitl_quad.simulator import Simulator
    from uavcore.airframe import Airframe

    airframe = Airframe.table2()
    hover_speed = math.sqrt(airframe.mass * airframe.g / (4 * airframe.kl))
    sim = Simulator(airframe, position=(0.0, 0.0, -5.0), rotor_speed=hover_speed)
    mixer = Mixer(airframe)
    attitude = AdrcAttitudeController.for_airframe(airframe)
    outer = AdrcOuterLoop(airframe.mass, airframe.g, airframe.max_thrust_n)

    def reference(t: float) -> TrajectorySetpoint:
        # hover 4 s, then north: 2 m/s^2 up to 10 m/s
        tt = max(0.0, t - 4.0)
        if tt < 5.0:
            x, v, a = tt * tt, 2.0 * tt, (2.0 if t > 4.0 else 0.0)
        else:
            x, v, a = 25.0 + 10.0 * (tt - 5.0), 10.0, 0.0
        return TrajectorySetpoint(
            position=np.array([x, 0.0, -5.0]), velocity=np.array([v, 0.0, 0.0]), acceleration=np.array([a, 0.0, 0.0])
        )

    errors, drag_estimates = [], []
    for k in range(round(16.0 / DT)):
        t = k * DT
        setpoint = reference(t)
        target = outer.update(setpoint, sim.measure(), DT)
        for _ in range(5):
            torque = attitude.update(target, sim.measure(), 0.004)
            sim.set_rotor_commands(mixer.rotor_commands(target.thrust * airframe.max_thrust_n, torque))
            sim.step(4)
        errors.append((t, np.linalg.norm(sim.state.position - reference(t + DT).position)))
        drag_estimates.append((t, outer.disturbance_estimates()["x"], sim.last_disturbance["external_accel_ned"][0]))
    errors = np.array(errors)
    assert errors[errors[:, 0] < 4.0, 1].max() < 0.01  # hover
    assert errors[:, 1].max() < 0.2  # the whole leg, accelerating included (0.10 m measured)
    assert errors[errors[:, 0] > 13.0, 1].max() < 0.01  # cruising at 10 m/s
    _, estimate, truth = drag_estimates[-1]
    assert truth < -1.0  # drag at 10 m/s pulls south
    assert estimate == pytest.approx(truth, abs=0.02)  # the ESO's z3 is the drag acceleration
