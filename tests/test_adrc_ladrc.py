"""Linear ADRC: Gao's bandwidth parameterisation with the current discrete (ZOH) observer."""

from __future__ import annotations

import math

import numpy as np
import pytest

from adrc_offboard.adrc import AdrcParameterError, bandwidth_parameters
from adrc_offboard.gains import channel_parameters, make_channel
from adrc_offboard.ladrc import LinearAdrcChannel, LinearAdrcParameters


def zoh_step(y: float, rate: float, acceleration: float, h: float) -> tuple[float, float]:
    return y + rate * h + 0.5 * acceleration * h * h, rate + acceleration * h


def implemented_observer_matrix(channel: LinearAdrcChannel) -> np.ndarray:
    """The prediction-error map the code really applies, read off column by column: with y = 0 and u = 0
    the predicted estimate is the prediction error."""
    channel.control(0.0, 0.0)  # start it
    columns = []
    for basis in np.eye(3):
        channel.z1, channel.z2, channel.z3 = basis
        channel.control(0.0, 0.0)
        channel.observe_applied(0.0)
        columns.append([channel.z1, channel.z2, channel.z3])
    return np.array(columns).T


@pytest.mark.parametrize(("omega_o", "h"), [(10.0, 0.02), (60.0, 0.004), (150.0, 0.02)])
def test_discrete_observer_poles_sit_at_exp_minus_omega_o_h(omega_o: float, h: float) -> None:
    channel = LinearAdrcChannel(LinearAdrcParameters(b0=3.0, omega_o=omega_o, omega_c=0.2 * omega_o), h)
    poles = np.linalg.eigvals(implemented_observer_matrix(channel))
    # a triple pole: numerically split by ~cbrt(eps), so compare loosely per pole and tightly on average
    assert np.allclose(np.abs(poles), math.exp(-omega_o * h), atol=1e-4)
    assert np.mean(poles).real == pytest.approx(math.exp(-omega_o * h), abs=1e-9)


def test_exact_discretisation_is_stable_where_the_euler_observer_is_refused() -> None:
    # omega_o h = 3: Han's Euler ESO is unstable (refused); the ZOH observer is fine and rejects a disturbance
    h, b0, d = 0.02, 2.0, -1.5
    with pytest.raises(AdrcParameterError):
        bandwidth_parameters(omega_c=10.0, omega_o=150.0, b0=b0, delta=0.01, r1=100.0).validate(h)
    channel = LinearAdrcChannel(LinearAdrcParameters(b0=b0, omega_o=150.0, omega_c=10.0), h)
    y = rate = 0.0
    for k in range(int(4.0 / h)):
        u = channel.update(0.5, y)
        y, rate = zoh_step(y, rate, b0 * u + (d if k * h >= 2.0 else 0.0), h)
    assert y == pytest.approx(0.5, abs=1e-6)
    assert channel.disturbance == pytest.approx(d, abs=1e-6)


def test_zoh_observer_is_exact_under_a_varying_input() -> None:
    # unlike the Euler ESO (first-order error in h), the ZOH model matches a held input exactly
    h, b0, d = 0.01, 2.0, -3.0
    channel = LinearAdrcChannel(LinearAdrcParameters(b0=b0, omega_o=20.0, omega_c=1.0), h)
    channel.control(0.0, 0.0)
    y = rate = 0.0
    for k in range(int(3.0 / h)):
        u = 0.5 * math.sin(3.0 * k * h)
        if k:
            channel.control(0.0, y)
        channel.observe_applied(u)
        y, rate = zoh_step(y, rate, d + b0 * u, h)
    assert channel.disturbance == pytest.approx(d, abs=1e-6)


def test_closed_loop_step_follows_the_designed_double_pole() -> None:
    # with the observer well ahead (omega_o = 10 omega_c), a step settles like (s + omega_c)^2: no overshoot
    h, omega_c = 0.002, 4.0
    channel = LinearAdrcChannel(LinearAdrcParameters(b0=1.0, omega_o=40.0, omega_c=omega_c), h)
    y = rate = 0.0
    trace = []
    for _ in range(int(3.0 / h)):
        u = channel.update(1.0, y)
        y, rate = zoh_step(y, rate, u, h)
        trace.append(y)
    trace = np.array(trace)
    t = np.arange(1, len(trace) + 1) * h
    ideal = 1.0 - (1.0 + omega_c * t) * np.exp(-omega_c * t)
    assert trace.max() < 1.01
    assert np.max(np.abs(trace - ideal)) < 0.05


def test_linear_channel_from_a_spec_and_refusals() -> None:
    p = channel_parameters({"kind": "linear", "omega_o": 20, "omega_c": 5, "u_max": 3}, 1.0)
    assert isinstance(make_channel(p, 0.01), LinearAdrcChannel)
    with pytest.raises(AdrcParameterError):
        LinearAdrcParameters(b0=1.0, omega_o=-1.0, omega_c=1.0).validate(0.01)
    with pytest.raises(AdrcParameterError, match="closed loop"):
        LinearAdrcParameters(b0=1.0, omega_o=50.0, omega_c=200.0).validate(0.01)
    with pytest.raises(AdrcParameterError, match="unknown keys"):
        channel_parameters({"kind": "linear", "omega_o": 20, "omega_c": 5, "delta": 0.1}, 1.0)
