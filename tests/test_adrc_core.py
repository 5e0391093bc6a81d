"""The nonlinear ADRC core (paper eq. 9-13): fhan, fal, TD, ESO, NLSEF, the composed channel, the validator."""

from __future__ import annotations

import math

import numpy as np
import pytest

from adrc_offboard.adrc import (
    AdrcChannel,
    AdrcChannelParameters,
    AdrcParameterError,
    ExtendedStateObserver,
    TrackingDifferentiator,
    bandwidth_parameters,
    fal,
    fhan,
    fsg,
)
from adrc_offboard.adrc_attitude import AdrcAttitudeGains
from adrc_offboard.gains import channel_parameters, make_channel
from adrc_offboard.outer_loop import AdrcOuterGains


def double_integrator_step(y: float, rate: float, acceleration: float, h: float) -> tuple[float, float]:
    """Exact zero-order-hold step of y'' = acceleration."""
    return y + rate * h + 0.5 * acceleration * h * h, rate + acceleration * h


@pytest.mark.parametrize("r0", [4.0, 100.0])
def test_td_reaches_a_unit_step_in_the_time_optimal_time_without_overshoot(r0: float) -> None:
    # bang-bang with acceleration r0 covers a distance 1 in 2 sqrt(1 / r0)
    h = 0.004
    td = TrackingDifferentiator(r0, h, h)
    outputs = np.array([td.update(1.0)[0] for _ in range(int(3.0 / math.sqrt(r0) / h))])
    settled_at = h * (1 + int(np.argmax(np.abs(outputs - 1.0) < 1e-3)))
    assert abs(outputs[-1] - 1.0) < 1e-6
    assert outputs.max() <= 1.0 + 1e-9
    assert np.all(np.diff(outputs) >= -1e-12)  # monotone approach
    assert settled_at == pytest.approx(2.0 / math.sqrt(r0), rel=0.1)


def test_td_filter_factor_above_the_step_smooths_a_noisy_reference() -> None:
    # Han: h0 = h is time-optimal but follows noise bang-bang; a larger h0 low-passes v2
    h = 0.004
    noise = np.random.default_rng(0).normal(0.0, 0.005, 2000)
    spreads = {}
    for h0 in (h, 10 * h):
        td = TrackingDifferentiator(150.0, h0, h)
        spreads[h0] = np.std([td.update(0.2 + n)[1] for n in noise][500:])
    assert spreads[10 * h] < 0.2 * spreads[h]


def test_fhan_is_a_pd_near_the_origin_and_bounded_by_r_far_away() -> None:
    r, h = 10.0, 0.5
    for x1, x2 in [(0.1, 0.0), (-0.2, 0.1), (0.05, -0.3)]:
        assert fhan(x1, x2, r, h) == pytest.approx(-(x1 + 2 * h * x2) / h**2)
    for x1, x2 in [(100.0, 0.0), (-50.0, 3.0), (0.0, 40.0)]:
        value = fhan(x1, x2, r, h)
        assert abs(value) == pytest.approx(r)
        assert math.copysign(1.0, value) == -math.copysign(1.0, x1 + x2)


@pytest.mark.parametrize(("alpha", "delta"), [(0.5, 0.01), (0.25, 0.01), (0.25, 0.3), (1.0, 0.1)])
def test_fal_is_continuous_at_delta_and_odd(alpha: float, delta: float) -> None:
    for edge in (delta, -delta):
        inside, at, outside = (
            fal(edge * (1 - 1e-9), alpha, delta),
            fal(edge, alpha, delta),
            fal(edge * (1 + 1e-9), alpha, delta),
        )
        assert at == pytest.approx(math.copysign(delta**alpha, edge), rel=1e-12)
        assert inside == pytest.approx(at, rel=1e-6)
        assert outside == pytest.approx(at, rel=1e-6)
    assert fal(0.3 * delta, alpha, delta) == pytest.approx(0.3 * delta * delta ** (alpha - 1))  # linear zone
    assert fal(5 * delta, alpha, delta) == pytest.approx((5 * delta) ** alpha)
    assert fal(-2 * delta, alpha, delta) == -fal(2 * delta, alpha, delta)


def test_fal_and_fsg_equal_the_printed_formulas() -> None:
    # eq. (13) and fsg of eq. (10) literally, with sign(0) = 0; the module computes them with comparisons
    def sgn(x: float) -> float:
        return (x > 0) - (x < 0)

    def fal_printed(e: float, alpha: float, delta: float) -> float:
        s = 0.5 * (sgn(e + delta) - sgn(e - delta))
        return e * s / delta ** (1 - alpha) + abs(e) ** alpha * sgn(e) * (1 - s)

    rng = np.random.default_rng(3)
    for _ in range(2000):
        delta, alpha = rng.uniform(1e-4, 1.0), rng.uniform(0.05, 1.0)
        for e in (rng.uniform(-3 * delta, 3 * delta), delta, -delta, 0.0):
            assert fal(e, alpha, delta) == pytest.approx(fal_printed(e, alpha, delta), rel=1e-12, abs=1e-15)
            assert fsg(e, delta) == 0.5 * (sgn(e + delta) - sgn(e - delta))


def run_observer(observer: ExtendedStateObserver, disturbance, h: float, seconds: float, excitation=None):
    """Drive the plant y'' = d(t) + b0 u(t) (u held over each step) and feed the ESO; returns times, z3."""
    y = rate = 0.0
    observer.reset(0.0, 0.0)
    times, estimates = [], []
    for k in range(int(seconds / h)):
        t = k * h
        u = 0.5 if excitation is None else excitation(t)  # an input the observer knows about
        observer.update(y, u)
        y, rate = double_integrator_step(y, rate, disturbance(t) + observer.b0 * u, h)
        times.append(t + h)
        estimates.append(observer.z3)
    return np.array(times), np.array(estimates)


def observer_for(omega_o: float, h: float, delta: float = 0.01, b0: float = 2.0) -> ExtendedStateObserver:
    p = bandwidth_parameters(omega_c=1.0, omega_o=omega_o, b0=b0, delta=delta, r1=10.0)
    return p.make_observer(h)


def test_eso_converges_to_a_constant_disturbance() -> None:
    times, z3 = run_observer(observer_for(20.0, 0.01), lambda t: -3.0, 0.01, 3.0)
    assert z3[-1] == pytest.approx(-3.0, abs=1e-6)
    assert np.all(np.abs(z3[times > 1.5] + 3.0) < 1e-3)


def test_eso_error_under_a_varying_input_is_first_order_in_the_step() -> None:
    # Han's Euler ESO models the input's effect on y one step late (no h^2/2 term): with a varying u the
    # estimate carries an O(h) error. The exactly discretised observer in ladrc.py does not.
    def worst_error(h: float) -> float:
        times, z3 = run_observer(observer_for(20.0, h), lambda t: -3.0, h, 3.0, lambda t: 0.5 * math.sin(3 * t))
        return float(np.max(np.abs(z3[times > 1.5] + 3.0)))

    coarse, fine = worst_error(0.01), worst_error(0.0025)
    assert coarse < 0.02
    assert fine == pytest.approx(coarse / 4, rel=0.1)


def test_eso_tracks_a_ramp_disturbance_with_the_predicted_lag() -> None:
    # for a ramp d = s t the linearised error settles at z3 - d = -3 s / omega_o (triple pole at -omega_o)
    omega_o, slope, h = 20.0, 2.0, 0.005
    times, z3 = run_observer(observer_for(omega_o, h), lambda t: 1.0 + slope * t, h, 4.0)
    expected = 1.0 + slope * times - 3.0 * slope / omega_o
    late = times > 2.0
    # up to one sample of the ramp: the disturbance is held over each step
    assert np.max(np.abs(z3[late] - expected[late])) < 1.5 * slope * h


def test_closed_loop_rejects_a_step_disturbance_and_estimates_it() -> None:
    h, b0, d = 0.01, 4.0, 2.5
    p = bandwidth_parameters(omega_c=5.0, omega_o=20.0, b0=b0, delta=0.01, r1=20.0, u_min=-5, u_max=5)
    channel = AdrcChannel(p, h)
    y = rate = 0.0
    trace = []
    for k in range(int(6.0 / h)):
        t = k * h
        u = channel.update(1.0, y)
        y, rate = double_integrator_step(y, rate, b0 * u + (d if t >= 3.0 else 0.0), h)
        trace.append((t, y, channel.disturbance))
    trace = np.array(trace)
    before = trace[(trace[:, 0] > 2.0) & (trace[:, 0] < 3.0)]
    after = trace[trace[:, 0] > 5.0]
    assert np.all(np.abs(before[:, 1] - 1.0) < 1e-3)
    assert np.max(np.abs(trace[trace[:, 0] > 3.0, 1] - 1.0)) > 0.005  # the step did push the output
    assert np.all(np.abs(after[:, 1] - 1.0) < 1e-3)
    assert after[-1, 2] == pytest.approx(d, abs=0.01)


def test_saturated_channel_feeds_the_observer_the_applied_control() -> None:
    # the plant can only get +-1 although the channel would ask for more; the ESO must not wind up
    h, b0 = 0.01, 1.0
    p = bandwidth_parameters(omega_c=4.0, omega_o=16.0, b0=b0, delta=0.01, r1=50.0)
    channel = AdrcChannel(p, h)
    y = rate = 0.0
    for _ in range(int(8.0 / h)):
        wanted = channel.control(3.0, y)
        applied = max(-1.0, min(1.0, wanted))
        channel.observe_applied(applied)
        y, rate = double_integrator_step(y, rate, b0 * applied, h)
        assert abs(channel.disturbance) < 0.05  # no disturbance: the saturation is not mistaken for one
    assert y == pytest.approx(3.0, abs=0.01)


def test_validator_refuses_an_euler_observer_beyond_omega_o_h_2_and_the_refused_set_diverges() -> None:
    h = 0.004
    fast = bandwidth_parameters(omega_c=10.0, omega_o=2.2 / h, b0=1.0, delta=0.01, r1=50.0)
    with pytest.raises(AdrcParameterError, match="ESO unstable"):
        fast.validate(h)
    with pytest.raises(ValueError):  # AdrcParameterError is a ValueError
        AdrcChannel(fast, h)
    # the refusal is not over-cautious: that observer really blows up, the one just inside does not
    for omega_o, diverges in ((2.2 / h, True), (1.8 / h, False)):
        observer = bandwidth_parameters(10.0, omega_o, 1.0, 0.01, 50.0).make_observer(h)
        _, z3 = run_observer(observer, lambda t: 0.001, h, 0.4)
        assert (not np.all(np.isfinite(z3)) or np.max(np.abs(z3)) > 1e3) == diverges


def test_validator_catches_fals_gain_scaling_by_delta() -> None:
    # gains that are fine for delta = 0.1 become unstable at delta = 1e-4: the linear zone multiplies
    # beta3 by delta^(alpha2 - 1) = 1e3 instead of 0.1^-0.75 = 5.6
    h = 0.01
    tuned = bandwidth_parameters(omega_c=5.0, omega_o=40.0, b0=1.0, delta=0.1, r1=20.0)
    tuned.validate(h)
    shrunk = AdrcChannelParameters(**{**tuned.__dict__, "delta": 1e-4})
    with pytest.raises(AdrcParameterError, match="delta"):
        shrunk.validate(h)


@pytest.mark.parametrize(
    "change",
    [{"beta1": -1.0}, {"delta": 0.0}, {"b0": 0.0}, {"alpha1": 1.5}, {"h1": math.nan}, {"u_min": 2, "u_max": 1}],
)
def test_validator_refuses_non_physical_values(change: dict) -> None:
    base = bandwidth_parameters(omega_c=5.0, omega_o=20.0, b0=1.0, delta=0.01, r1=20.0)
    with pytest.raises(AdrcParameterError):
        AdrcChannelParameters(**{**base.__dict__, **change}).validate(0.01)


def test_validator_refuses_a_td_filter_factor_below_the_step() -> None:
    base = bandwidth_parameters(omega_c=5.0, omega_o=20.0, b0=1.0, delta=0.01, r1=20.0, r0=10.0, h0=0.005)
    with pytest.raises(AdrcParameterError, match="h0"):
        base.validate(0.01)
    base.validate(0.005)


def test_validator_refuses_a_closed_loop_too_fast_for_the_step() -> None:
    # observer fine (omega_o h = 1.5) but the feedback's linear zone at omega_c h = 1.2 is not
    p = bandwidth_parameters(omega_c=60.0, omega_o=150.0, b0=1.0, delta=0.01, r1=1e4)
    p.make_observer(0.01)  # constructs
    with pytest.raises(AdrcParameterError, match="closed loop"):
        p.validate(0.01)


def test_the_shipped_parameter_sets_are_accepted() -> None:
    attitude = AdrcAttitudeGains.load()
    for spec, inertia in ((attitude.roll, 0.085), (attitude.pitch, 0.083), (attitude.yaw, 0.151)):
        spec = dict(spec)
        make_channel(channel_parameters(spec, spec.pop("b0_scale", 1.0) / inertia), 1 / 250)
    outer = AdrcOuterGains.load()
    make_channel(outer.horizontal, 1 / 50)
    make_channel(outer.vertical, 1 / 50)


def test_channel_specs_refuse_typos_and_accept_the_papers_symbols() -> None:
    with pytest.raises(AdrcParameterError, match="unknown keys"):
        channel_parameters({"omega_c": 2, "omega_o": 8, "delta": 0.02, "r1": 5, "beta_1": 3}, 1.0)
    with pytest.raises(AdrcParameterError, match="incomplete"):
        channel_parameters({"omega_c": 2, "omega_o": 8}, 1.0)
    paper = channel_parameters(
        {"beta1": 100, "beta2": 300, "beta3": 1000, "delta": 0.01, "r1": 10, "h1": 0.1, "c": 0.8, "u_max": 2},
        2.0,
    )
    assert isinstance(paper, AdrcChannelParameters)
    assert (paper.b0, paper.c, paper.u_min, paper.u_max) == (2.0, 0.8, -2, 2)
