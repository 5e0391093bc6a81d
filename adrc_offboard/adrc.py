"""Han's nonlinear active disturbance rejection control for one second-order channel (paper Section IV).

A channel is a plant  y'' = f(t) + b0 u  where f lumps every unknown: couplings, model error, wind. It is
controlled by three parts, each a class here with the paper's symbols:

- `TrackingDifferentiator` (eq. 9, 10): shapes the reference v into a smooth v1 and its rate v2;
- `ExtendedStateObserver` (eq. 11, 13): estimates z1 ~ y, z2 ~ y', z3 ~ f from the measured y and the
  applied u;
- `NonlinearStateErrorFeedback` (eq. 12): u0 = -fhan(e1, c e2, r1, h1) and U = (u0 - z3) / b0, so the
  estimated disturbance is cancelled and the rest behaves like a double integrator.

`AdrcChannel` composes them with output limits. Two corrections to the equations as printed, both Han's
standard discrete forms (J. Han, "From PID to active disturbance rejection control", IEEE TIE 2009):

- eq. (9) prints  psi2(k+1) = psi2(k) + fhan(...);  fhan is an acceleration, so it is multiplied by the
  step h like every other Euler term:  v2(k+1) = v2(k) + h fhan(v1 - v, v2, r0, h0).
- eq. (11) prints the z2 update as  z2 + h1 (z3 - beta2 fal(...)) + b0 u,  with b0 u outside the step. b0 u
  is an acceleration too, and outside the factor it would make the observer's model depend on the sampling
  rate (at 250 Hz it would count the control 250 times too strongly). We use
  z2(k+1) = z2 + h (z3 - beta2 fal(eps1, alpha1, delta) + b0 u).

Discrete-time pitfalls are checked when a channel is built (`AdrcChannelParameters.validate`): the Euler
observer's linearisation (fal replaced by its linear-zone slope delta^(alpha-1), which multiplies the gain)
must have spectral radius < 1 at the configured step, and so must the linearised closed loop.

Sign convention: z3 estimates f in y'' = f + b0 u, in the channel's own units (m/s^2 for a position
channel, rad/s^2 for an attitude channel). A wind pushing the vehicle north gives a positive z3 on x.

Inner loops run this 250 times a simulated second, so every law is a numba kernel on floats (`fhan`, `fal`,
`td_step`, `eso_step`, `nlsef_control`) and `AdrcChannel` keeps its parameters and state in flat arrays
(`P_*`, `S_*` layouts) that `adrc_channel_control` / `adrc_channel_observe` advance: the classes are the
Python face, and the vehicle's compiled attitude loop (adrc_offboard.adrc_attitude, sitl_quad.attitude_loops)
runs the very same kernels. numba's on-disk cache is invalidated by edits to a kernel's own file only: after
changing a kernel here, delete adrc_offboard/__pycache__/*.nbi and sitl_quad/__pycache__/*.nbi.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from uavcore.kernel_cache import cached_kernel


class AdrcParameterError(ValueError):
    """A parameter set that cannot work: non-physical values, or a discrete loop unstable at its step."""


@cached_kernel
def sign(x: float) -> float:
    """sign() as in the paper: -1, 0 or +1."""
    return 1.0 if x > 0.0 else (-1.0 if x < 0.0 else 0.0)


@cached_kernel
def fsg(x: float, d: float) -> float:
    """fsg(x, d) = (sign(x + d) - sign(x - d)) / 2, eq. (10), for d > 0: 1 inside |x| < d, 0 outside,
    1/2 on the edge. Written with comparisons: it sits on the 250 Hz path."""
    magnitude = abs(x)
    return 1.0 if magnitude < d else (0.0 if magnitude > d else 0.5)


@cached_kernel
def fhan(x1: float, x2: float, r: float, h: float) -> float:
    """Han's discrete time-optimal synthesis function, eq. (10) (gamma = r, eta = h).

    The acceleration, bounded by r, that brings the double integrator (x1, x2) to the origin fastest at
    step h. Near the origin (|a| <= d) it is linear: -(x1 + 2 h x2) / h^2, a PD with omega = 1/h, zeta = 1.
    """
    d = r * h * h
    a0 = h * x2
    y = x1 + a0
    a1 = math.sqrt(d * (d + 8.0 * abs(y)))
    a2 = a0 + 0.5 * sign(y) * (a1 - d)
    fsg_y = fsg(y, d)
    a = (a0 + y) * fsg_y + a2 * (1.0 - fsg_y)
    fsg_a = fsg(a, d)
    return -r * (a / d) * fsg_a - r * sign(a) * (1.0 - fsg_a)


@cached_kernel
def fal(e: float, alpha: float, delta: float) -> float:
    """Han's power function with a linear zone, eq. (13): e / delta^(1-alpha) inside |e| <= delta,
    |e|^alpha sign(e) outside; continuous at |e| = delta. Its linear-zone slope is delta^(alpha-1)."""
    magnitude = abs(e)
    if magnitude < delta:  # s = 1
        return e / delta ** (1.0 - alpha)
    if magnitude > delta:  # s = 0
        return math.copysign(magnitude**alpha, e)
    return e * 0.5 / delta ** (1.0 - alpha) + 0.5 * math.copysign(magnitude**alpha, e)  # s = 1/2: = e^alpha


@cached_kernel
def td_step(
    v1: float, v2: float, reference: float, reference_rate: float, r0: float, h0: float, h: float
) -> tuple[float, float]:
    """One step of the tracking differentiator, eq. (9) (see `TrackingDifferentiator`): (v1, v2) after it."""
    return v1 + h * v2, v2 + h * fhan(v1 - reference, v2 - reference_rate, r0, h0)


@cached_kernel
def eso_step(
    z1: float,
    z2: float,
    z3: float,
    y: float,
    u: float,
    beta1: float,
    beta2: float,
    beta3: float,
    b0: float,
    delta: float,
    alpha1: float,
    alpha2: float,
    h: float,
) -> tuple[float, float, float]:
    """One step of the ESO, eq. (11) in Han's Euler form (see `ExtendedStateObserver`): (z1, z2, z3) after it."""
    eps1 = z1 - y
    return (
        z1 + h * (z2 - beta1 * eps1),
        z2 + h * (z3 - beta2 * fal(eps1, alpha1, delta) + b0 * u),
        z3 - h * beta3 * fal(eps1, alpha2, delta),
    )


@cached_kernel
def nlsef_control(
    e1: float, e2: float, z3: float, reference_acceleration: float, r1: float, h1: float, c: float, b0: float
) -> float:
    """Eq. (12): U = (u0 - z3) / b0 with u0 = -fhan(e1, c e2, r1, h1) (+ the reference acceleration)."""
    u0 = reference_acceleration - fhan(e1, c * e2, r1, h1)
    return (u0 - z3) / b0


@cached_kernel
def clip(u: float, u_min: float, u_max: float) -> float:
    """u limited to [u_min, u_max] (a NaN passes through, to be caught downstream)."""
    return u_min if u < u_min else (u_max if u > u_max else u)


class TrackingDifferentiator:
    """Second-order tracking differentiator, eq. (9): v1 follows the reference with acceleration at most
    r0 and without overshoot; v2 is its rate. h0 >= h filters noise (h0 = h is time-optimal).

    When the reference's own rate is known (a feed-forward: the navigator's yaw rate), fhan acts on the
    tracking error (v1 - v, v2 - v'), not on (v1 - v, v2): fhan is the time-optimal control bringing a double
    integrator to the origin, and for a reference moving at a steady rate the error is such a double
    integrator. v2 then converges to v' and v1 onto v with no lag on a ramp; with v' = 0 it is eq. (9) as
    printed, which lags a ramp by about 2 h0 v' and only learns v' from that lag.
    """

    __slots__ = ("h", "h0", "r0", "v1", "v2")

    def __init__(self, r0: float, h0: float, h: float) -> None:
        self.r0, self.h0, self.h = r0, h0, h
        self.v1 = self.v2 = 0.0

    def reset(self, v1: float = 0.0, v2: float = 0.0) -> None:
        self.v1, self.v2 = v1, v2

    def update(self, reference: float, reference_rate: float = 0.0) -> tuple[float, float]:
        """One step toward the reference v moving at the known rate v' (0: unknown); returns (v1, v2) after it."""
        self.v1, self.v2 = td_step(self.v1, self.v2, reference, reference_rate, self.r0, self.h0, self.h)
        return self.v1, self.v2


class ExtendedStateObserver:
    """Nonlinear ESO, eq. (11) in Han's standard Euler form (b0 u inside the step; see module docstring)."""

    __slots__ = ("alpha1", "alpha2", "b0", "beta1", "beta2", "beta3", "delta", "h", "z1", "z2", "z3")

    def __init__(
        self,
        beta1: float,
        beta2: float,
        beta3: float,
        b0: float,
        delta: float,
        h: float,
        alpha1: float = 0.5,
        alpha2: float = 0.25,
    ) -> None:
        self.beta1, self.beta2, self.beta3 = beta1, beta2, beta3
        self.b0, self.delta, self.h = b0, delta, h
        self.alpha1, self.alpha2 = alpha1, alpha2
        self.z1 = self.z2 = self.z3 = 0.0

    def reset(self, y: float = 0.0, y_rate: float = 0.0, disturbance: float = 0.0) -> None:
        self.z1, self.z2, self.z3 = y, y_rate, disturbance

    def update(self, y: float, u: float) -> None:
        """Advance one step with the measured output y(k) and the control u(k) actually applied."""
        self.z1, self.z2, self.z3 = eso_step(
            self.z1,
            self.z2,
            self.z3,
            y,
            u,
            self.beta1,
            self.beta2,
            self.beta3,
            self.b0,
            self.delta,
            self.alpha1,
            self.alpha2,
            self.h,
        )

    def linear_zone_gains(self) -> tuple[float, float, float]:
        """(beta1, beta2, beta3) as the observer applies them to small errors (|eps1| <= delta)."""
        return (
            self.beta1,
            self.beta2 * self.delta ** (self.alpha1 - 1.0),
            self.beta3 * self.delta ** (self.alpha2 - 1.0),
        )

    def error_transition_matrix(self) -> np.ndarray:
        """Linearised discrete error dynamics e(k+1) = Phi e(k), e = z - (y, y', f); fal -> linear zone."""
        l1, l2, l3 = self.linear_zone_gains()
        a = np.array([[-l1, 1.0, 0.0], [-l2, 0.0, 1.0], [-l3, 0.0, 0.0]])
        return np.eye(3) + self.h * a


class NonlinearStateErrorFeedback:
    """Eq. (12): u0 = -fhan(e1, c e2, r1, h1) (+ reference acceleration), U = (u0 - z3) / b0.

    In fhan's linear zone this is u0 = kp e1 + kd e2 with kp = 1/h1^2, kd = 2c/h1: h1 is the inverse of the
    closed-loop bandwidth and c its damping ratio. Far from the target u0 saturates at r1 (bang-bang along
    the time-optimal switching curve), so r1 is the feedback's acceleration authority.
    """

    __slots__ = ("b0", "c", "h1", "r1")

    def __init__(self, r1: float, h1: float, c: float, b0: float) -> None:
        self.r1, self.h1, self.c, self.b0 = r1, h1, c, b0

    def control(self, e1: float, e2: float, z3: float, reference_acceleration: float = 0.0) -> float:
        """U for tracking errors e1 = v1 - z1, e2 = v2 - z2 and disturbance estimate z3."""
        return nlsef_control(e1, e2, z3, reference_acceleration, self.r1, self.h1, self.c, self.b0)


@dataclass(frozen=True)
class AdrcChannelParameters:
    """One nonlinear ADRC channel, in the paper's symbols. r0 = None means no TD (the reference and its
    derivatives are taken as given); h0 = None means h0 = the sampling step."""

    b0: float
    beta1: float
    beta2: float
    beta3: float
    delta: float
    r1: float
    h1: float
    c: float = 1.0
    alpha1: float = 0.5
    alpha2: float = 0.25
    r0: float | None = None
    h0: float | None = None
    u_min: float = -math.inf
    u_max: float = math.inf

    def validate(self, h: float) -> None:
        """Raise AdrcParameterError unless the set is usable at sampling step h (seconds)."""
        _require_finite_positive(
            h=h,
            beta1=self.beta1,
            beta2=self.beta2,
            beta3=self.beta3,
            delta=self.delta,
            r1=self.r1,
            h1=self.h1,
            c=self.c,
        )
        if not math.isfinite(self.b0) or self.b0 == 0.0:
            raise AdrcParameterError(f"b0 must be finite and non-zero, got {self.b0}")
        for name, alpha in (("alpha1", self.alpha1), ("alpha2", self.alpha2)):
            if not 0.0 < alpha <= 1.0:
                raise AdrcParameterError(f"{name} must lie in (0, 1], got {alpha}")
        if self.r0 is not None:
            _require_finite_positive(r0=self.r0)
            if self.h0 is not None and not self.h0 >= h:
                raise AdrcParameterError(
                    f"TD filter factor h0 = {self.h0} is below the step h = {h}: "
                    "the discrete TD then overshoots and chatters; use h0 >= h"
                )
        if not self.u_min < self.u_max:
            raise AdrcParameterError(f"output limits must satisfy u_min < u_max, got {self.u_min}, {self.u_max}")
        observer = self.make_observer(h)
        rho = spectral_radius(observer.error_transition_matrix())
        if rho >= 1.0:
            l1, l2, l3 = observer.linear_zone_gains()
            raise AdrcParameterError(
                f"ESO unstable at step h = {h} s: spectral radius {rho:.3f} >= 1 for linear-zone gains "
                f"({l1:.4g}, {l2:.4g}, {l3:.4g}) (fal's linear zone multiplies beta2, beta3 by "
                f"delta^(alpha-1) with delta = {self.delta}); lower the observer bandwidth or raise the rate"
            )
        rho = spectral_radius(self.closed_loop_transition_matrix(h))
        if rho >= 1.0:
            raise AdrcParameterError(
                f"linearised closed loop unstable at step h = {h} s (spectral radius "
                f"{rho:.3f}): lower the bandwidth 1/h1 or raise the rate"
            )

    def as_array(self, h: float) -> np.ndarray:
        """The parameters at sampling step h in the kernels' flat layout (`P_*`)."""
        p = np.zeros(CHANNEL_PARAMS_SIZE)
        p[P_B0], p[P_BETA1], p[P_BETA2], p[P_BETA3] = self.b0, self.beta1, self.beta2, self.beta3
        p[P_DELTA], p[P_ALPHA1], p[P_ALPHA2] = self.delta, self.alpha1, self.alpha2
        p[P_R1], p[P_H1], p[P_C] = self.r1, self.h1, self.c
        p[P_HAS_TD] = float(self.r0 is not None)
        p[P_R0] = self.r0 if self.r0 is not None else 0.0
        p[P_H0] = self.h0 if self.h0 is not None else h
        p[P_H], p[P_U_MIN], p[P_U_MAX] = h, self.u_min, self.u_max
        return p

    def make_observer(self, h: float) -> ExtendedStateObserver:
        return ExtendedStateObserver(
            self.beta1, self.beta2, self.beta3, self.b0, self.delta, h, self.alpha1, self.alpha2
        )

    def closed_loop_transition_matrix(self, h: float) -> np.ndarray:
        """Linearised loop on the nominal plant y'' = b0 u (zero-order hold), reference 0, in the order
        `AdrcChannel` runs: U(k) from z(k), then the ESO steps with y(k), U(k).
        State (y, y', z1, z2, z3)."""
        l1, l2, l3 = self.make_observer(h).linear_zone_gains()
        kp, kd = 1.0 / self.h1**2, 2.0 * self.c / self.h1
        # U = (-kp z1 - kd z2 - z3) / b0, so b0 U = k . state with k:
        k = np.array([0.0, 0.0, -kp, -kd, -1.0])
        plant = np.array([[1.0, h, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0, 0.0]]) + np.outer([h * h / 2, h], k)
        observer = np.array(
            [
                [h * l1, 0.0, 1.0 - h * l1, h, 0.0],
                [h * l2, 0.0, -h * l2, 1.0, h],
                [h * l3, 0.0, -h * l3, 0.0, 1.0],
            ]
        ) + np.outer([0.0, h, 0.0], k)
        return np.vstack([plant, observer])


class ChannelBase:
    """What the nonlinear `AdrcChannel` and `ladrc.LinearAdrcChannel` share: the optional TD on the reference,
    the output clip, and `update()` = `control()` then `observe_applied()`."""

    __slots__ = ("_started", "_u_max", "_u_min", "tracking_differentiator")

    def _setup(self, r0: float | None, h0: float | None, h: float, u_min: float, u_max: float) -> None:
        self.tracking_differentiator = (
            None if r0 is None else TrackingDifferentiator(r0, h0 if h0 is not None else h, h)
        )
        self._u_min, self._u_max = u_min, u_max
        self._started = False

    def reset(self) -> None:
        """Forget all state; the next call starts the TD and ESO at the reference and measurement."""
        self._started = False

    def _start_reference(self, reference: float, reference_rate: float) -> None:
        if self.tracking_differentiator is not None:
            self.tracking_differentiator.reset(reference, reference_rate)
        self._started = True

    def _reference(self, reference: float, reference_rate: float, reference_acceleration: float):
        """(v1, v2, feed-forward acceleration): the TD's outputs (tracking the reference at its known rate) and
        none, or the reference as given."""
        td = self.tracking_differentiator
        if td is None:
            return reference, reference_rate, reference_acceleration
        v1, v2 = td.update(reference, reference_rate)
        return v1, v2, 0.0  # eq. (12) uses only e1, e2; see AdrcChannel's docstring

    def _clip(self, u: float) -> float:
        return clip(u, self._u_min, self._u_max)

    def control(
        self,
        reference: float,
        measurement: float,
        reference_rate: float = 0.0,
        reference_acceleration: float = 0.0,
        measured_rate: float | None = None,
    ) -> float:
        raise NotImplementedError

    def observe_applied(self, applied_control: float) -> None:
        raise NotImplementedError

    def update(
        self,
        reference: float,
        measurement: float,
        reference_rate: float = 0.0,
        reference_acceleration: float = 0.0,
        measured_rate: float | None = None,
    ) -> float:
        u = self.control(reference, measurement, reference_rate, reference_acceleration, measured_rate)
        self.observe_applied(u)
        return u


# AdrcChannel's parameters (AdrcChannelParameters.as_array) and state, as flat arrays for the kernels below.
(P_B0, P_BETA1, P_BETA2, P_BETA3, P_DELTA, P_ALPHA1, P_ALPHA2, P_R1, P_H1, P_C) = range(10)
(P_HAS_TD, P_R0, P_H0, P_H, P_U_MIN, P_U_MAX) = range(10, 16)
CHANNEL_PARAMS_SIZE = 16
# started (0/1), the TD's v1 v2, the ESO's z1 z2 z3, and the measurement y(k) that observe() pairs with U(k)
S_STARTED, S_V1, S_V2, S_Z1, S_Z2, S_Z3, S_Y = range(7)
CHANNEL_STATE_SIZE = 7


@cached_kernel
def adrc_channel_control(
    p: np.ndarray,
    s: np.ndarray,
    reference: float,
    measurement: float,
    reference_rate: float,
    reference_acceleration: float,
    measured_rate: float,
    rate_measured: bool,
) -> float:
    """`AdrcChannel.control` on the flat parameters p and state s (measured_rate is used when rate_measured)."""
    if s[S_STARTED] == 0.0:  # start the ESO at the measurement, the TD at the reference
        s[S_Z1], s[S_Z2], s[S_Z3] = measurement, (measured_rate if rate_measured else 0.0), 0.0
        s[S_V1], s[S_V2] = reference, reference_rate
        s[S_STARTED] = 1.0
    s[S_Y] = measurement
    if p[P_HAS_TD] != 0.0:  # eq. (12) uses only e1, e2; see AdrcChannel's docstring
        v1, v2 = td_step(s[S_V1], s[S_V2], reference, reference_rate, p[P_R0], p[P_H0], p[P_H])
        s[S_V1], s[S_V2] = v1, v2
        reference_acceleration = 0.0
    else:
        v1, v2 = reference, reference_rate
    rate = measured_rate if rate_measured else s[S_Z2]
    u = nlsef_control(v1 - s[S_Z1], v2 - rate, s[S_Z3], reference_acceleration, p[P_R1], p[P_H1], p[P_C], p[P_B0])
    return clip(u, p[P_U_MIN], p[P_U_MAX])


@cached_kernel
def adrc_channel_observe(p: np.ndarray, s: np.ndarray, applied_control: float) -> None:
    """`AdrcChannel.observe_applied` on the flat parameters p and state s."""
    s[S_Z1], s[S_Z2], s[S_Z3] = eso_step(
        s[S_Z1],
        s[S_Z2],
        s[S_Z3],
        s[S_Y],
        applied_control,
        p[P_BETA1],
        p[P_BETA2],
        p[P_BETA3],
        p[P_B0],
        p[P_DELTA],
        p[P_ALPHA1],
        p[P_ALPHA2],
        p[P_H],
    )


class AdrcChannel(ChannelBase):
    """TD + ESO + NLSEF for one second-order channel, with output limits.

    Per step: `control()` computes U(k) from the observer's z(k) (and the reference), clipped to
    [u_min, u_max]; `observe_applied(u)` then steps the ESO with y(k) and the control actually applied, so a
    saturation further downstream (tilt limit, mixer) never winds the observer up. `update()` does both when
    the channel's own clip is the only limit.

    Without a TD (r0 = None) the reference is used as given, with its rate and acceleration as feed-forward
    (a navigator's smooth setpoint needs no re-differentiation). With a TD, the TD's v1, v2 are the
    reference (the TD tracking the reference at its rate, when one is given) and, as in eq. (12), no
    acceleration is fed forward: the TD's own acceleration is bang-bang at +-r0, and
    with a reference that steps at a lower rate (a 50 Hz target into a 250 Hz loop) feeding it forward
    makes the output chatter between its limits.

    ``kernel_params`` and ``kernel_state`` are the flat arrays the kernels read and advance (`P_*`, `S_*`);
    a caller may hand in the state array (the attitude loop keeps its three channels' states in one array).
    """

    __slots__ = ("h", "kernel_params", "kernel_state", "parameters")

    def __init__(self, parameters: AdrcChannelParameters, h: float, state: np.ndarray | None = None) -> None:
        parameters.validate(h)
        self.parameters, self.h = parameters, h
        self.kernel_params = parameters.as_array(h)
        self.kernel_state = np.zeros(CHANNEL_STATE_SIZE) if state is None else state
        self.reset()

    def reset(self) -> None:
        """Forget all state; the next call starts the TD and ESO at the reference and measurement."""
        self.kernel_state[:] = 0.0

    @property
    def disturbance(self) -> float:
        """The ESO's z3: total disturbance f in y'' = f + b0 u."""
        return float(self.kernel_state[S_Z3])

    def control(
        self,
        reference: float,
        measurement: float,
        reference_rate: float = 0.0,
        reference_acceleration: float = 0.0,
        measured_rate: float | None = None,
    ) -> float:
        """U(k), clipped to the channel's limits. measured_rate, when given, replaces the ESO's z2 in the
        rate error (a measured velocity or gyro rate is fresher than the estimate)."""
        return adrc_channel_control(
            self.kernel_params,
            self.kernel_state,
            reference,
            measurement,
            reference_rate,
            reference_acceleration,
            0.0 if measured_rate is None else measured_rate,
            measured_rate is not None,
        )

    def observe_applied(self, applied_control: float) -> None:
        """Step the ESO with this step's measurement and the control the plant really received."""
        adrc_channel_observe(self.kernel_params, self.kernel_state, applied_control)

    def state(self) -> dict[str, float]:
        s = self.kernel_state
        return {"z1": float(s[S_Z1]), "z2": float(s[S_Z2]), "z3": float(s[S_Z3])}


def bandwidth_parameters(
    omega_c: float,
    omega_o: float,
    b0: float,
    delta: float,
    r1: float,
    alpha1: float = 0.5,
    alpha2: float = 0.25,
    damping: float = 1.0,
    r0: float | None = None,
    h0: float | None = None,
    u_min: float = -math.inf,
    u_max: float = math.inf,
) -> AdrcChannelParameters:
    """Gao's bandwidth parameterisation carried over to the nonlinear channel.

    The ESO's linear-zone gains are placed at a triple pole -omega_o (beta = 3 wo, 3 wo^2, wo^3 after fal's
    slope delta^(alpha-1) is divided out), and the NLSEF's linear zone at a double pole -omega_c
    (h1 = 1/omega_c, c = damping); r1 bounds the feedback's acceleration for large errors.
    """
    _require_finite_positive(omega_c=omega_c, omega_o=omega_o, delta=delta)
    return AdrcChannelParameters(
        b0=b0,
        beta1=3.0 * omega_o,
        beta2=3.0 * omega_o**2 * delta ** (1.0 - alpha1),
        beta3=omega_o**3 * delta ** (1.0 - alpha2),
        delta=delta,
        r1=r1,
        h1=1.0 / omega_c,
        c=damping,
        alpha1=alpha1,
        alpha2=alpha2,
        r0=r0,
        h0=h0,
        u_min=u_min,
        u_max=u_max,
    )


def spectral_radius(matrix: np.ndarray) -> float:
    return float(np.max(np.abs(np.linalg.eigvals(matrix))))


def _require_finite_positive(**values: float) -> None:
    for name, value in values.items():
        if not (isinstance(value, int | float) and math.isfinite(value) and value > 0.0):
            raise AdrcParameterError(f"{name} must be a finite positive number, got {value!r}")
