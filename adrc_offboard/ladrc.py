"""Linear ADRC with Gao's bandwidth parameterisation and an exactly discretised observer (an option).

Z. Gao, "Scaling and bandwidth-parameterization based controller tuning", ACC 2003: the observer gains put
the three poles of the continuous ESO at -omega_o (beta = 3 wo, 3 wo^2, wo^3) and the feedback is a PD with
kp = wc^2, kd = 2 wc. A discrete loop must not simply Euler-integrate that observer: the Euler form is
unstable once omega_o h reaches 2. Here the observer is the current discrete ESO of Miklosovic, Radke and
Gao ("Discrete implementation and generalization of the extended state observer", ACC 2006):

- the plant model y'' = z3 + b0 u is discretised exactly under zero-order hold (Phi, Gamma);
- each step first corrects the prediction with this step's measurement, z(k|k) = z(k|k-1) + L (y - z1),
  so the control uses y(k) with no sample of delay, then predicts z(k+1|k) = Phi z(k|k) + Gamma u(k);
- L places all three poles of Phi (I - L C) at beta = exp(-omega_o h), stable for every omega_o > 0.

`LinearAdrcChannel` has the same methods as `adrc.AdrcChannel` so a controller can hold either.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from adrc_offboard.adrc import AdrcParameterError, ChannelBase, spectral_radius


@dataclass(frozen=True)
class LinearAdrcParameters:
    """One linear ADRC channel: bandwidths in rad/s, b0 the input gain, optional TD (r0, h0) as in
    `adrc.AdrcChannelParameters`."""

    b0: float
    omega_o: float
    omega_c: float
    r0: float | None = None
    h0: float | None = None
    u_min: float = -math.inf
    u_max: float = math.inf

    def gains(self, h: float) -> tuple[tuple[float, float, float], float, float]:
        """((l1, l2, l3), kp, kd): current-estimator gains for poles at exp(-omega_o h), and the PD."""
        beta = math.exp(-self.omega_o * h)
        l1 = 1.0 - beta**3
        l2 = 1.5 * (1.0 - beta) ** 2 * (1.0 + beta) / h
        l3 = (1.0 - beta) ** 3 / (h * h)
        return (l1, l2, l3), self.omega_c**2, 2.0 * self.omega_c

    def observer_matrices(self, h: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(Phi, Gamma, L): the zero-order-hold model and the correction gain."""
        phi = np.array([[1.0, h, h * h / 2.0], [0.0, 1.0, h], [0.0, 0.0, 1.0]])
        gamma = np.array([self.b0 * h * h / 2.0, self.b0 * h, 0.0])
        (l1, l2, l3), _, _ = self.gains(h)
        return phi, gamma, np.array([l1, l2, l3])

    def error_transition_matrix(self, h: float) -> np.ndarray:
        """Prediction-error dynamics e(k+1) = Phi (I - L C) e(k)."""
        phi, _, gain = self.observer_matrices(h)
        return phi @ (np.eye(3) - np.outer(gain, [1.0, 0.0, 0.0]))

    def closed_loop_transition_matrix(self, h: float) -> np.ndarray:
        """Loop on the nominal plant y'' = b0 u (ZOH), reference 0; state (y, y', z1, z2, z3) predicted."""
        phi, gamma, gain = self.observer_matrices(h)
        _, kp, kd = self.gains(h)
        # corrected estimate z(k|k) = M @ state, with M mapping (y, y', zbar) -> zhat
        correct = np.hstack([np.outer(gain, [1.0, 0.0]), np.eye(3) - np.outer(gain, [1.0, 0.0, 0.0])])
        b0u = np.array([-kp, -kd, -1.0]) @ correct  # b0 U = -kp z1 - kd z2 - z3, as a row on the state
        plant = np.hstack([[[1.0, h], [0.0, 1.0]], np.zeros((2, 3))]) + np.outer([h * h / 2.0, h], b0u)
        observer = phi @ correct + np.outer(gamma / self.b0, b0u)
        return np.vstack([plant, observer])

    def validate(self, h: float) -> None:
        for name, value in (("h", h), ("omega_o", self.omega_o), ("omega_c", self.omega_c)):
            if not (math.isfinite(value) and value > 0.0):
                raise AdrcParameterError(f"{name} must be a finite positive number, got {value!r}")
        if not math.isfinite(self.b0) or self.b0 == 0.0:
            raise AdrcParameterError(f"b0 must be finite and non-zero, got {self.b0}")
        if self.r0 is not None and not (math.isfinite(self.r0) and self.r0 > 0.0):
            raise AdrcParameterError(f"r0 must be a finite positive number, got {self.r0!r}")
        if self.r0 is not None and self.h0 is not None and not self.h0 >= h:
            raise AdrcParameterError(f"TD filter factor h0 = {self.h0} is below the step h = {h}; use h0 >= h")
        if not self.u_min < self.u_max:
            raise AdrcParameterError(f"output limits must satisfy u_min < u_max, got {self.u_min}, {self.u_max}")
        for what, matrix in (
            ("observer", self.error_transition_matrix(h)),
            ("closed loop", self.closed_loop_transition_matrix(h)),
        ):
            rho = spectral_radius(matrix)
            if rho >= 1.0:
                raise AdrcParameterError(
                    f"linear ADRC {what} unstable at step h = {h} s (spectral radius "
                    f"{rho:.3f}) with omega_o = {self.omega_o}, omega_c = {self.omega_c}"
                )


class LinearAdrcChannel(ChannelBase):
    """Linear ADRC for one second-order channel: optional TD, current discrete ESO, PD + cancellation."""

    __slots__ = (
        "_b0",
        "_g1",
        "_g2",
        "_h",
        "_kd",
        "_kp",
        "_l1",
        "_l2",
        "_l3",
        "parameters",
        "z1",
        "z2",
        "z3",
    )

    def __init__(self, parameters: LinearAdrcParameters, h: float) -> None:
        parameters.validate(h)
        self.parameters = parameters
        (self._l1, self._l2, self._l3), self._kp, self._kd = parameters.gains(h)
        self._h, self._b0 = h, parameters.b0
        self._g1, self._g2 = parameters.b0 * h * h / 2.0, parameters.b0 * h
        self._setup(parameters.r0, parameters.h0, h, parameters.u_min, parameters.u_max)
        self.z1 = self.z2 = self.z3 = 0.0  # after control(): z(k|k); after observe_applied(): z(k+1|k)

    @property
    def h(self) -> float:
        return self._h

    @property
    def disturbance(self) -> float:
        return self.z3

    def control(
        self,
        reference: float,
        measurement: float,
        reference_rate: float = 0.0,
        reference_acceleration: float = 0.0,
        measured_rate: float | None = None,
    ) -> float:
        """Correct the estimate with y(k), then U(k), clipped (see `adrc.AdrcChannel.control`)."""
        if not self._started:
            self.z1, self.z2, self.z3 = measurement, (measured_rate if measured_rate is not None else 0.0), 0.0
            self._start_reference(reference, reference_rate)
        innovation = measurement - self.z1
        self.z1 += self._l1 * innovation
        self.z2 += self._l2 * innovation
        self.z3 += self._l3 * innovation
        v1, v2, reference_acceleration = self._reference(reference, reference_rate, reference_acceleration)
        rate = self.z2 if measured_rate is None else measured_rate
        return self._clip(
            (reference_acceleration + self._kp * (v1 - self.z1) + self._kd * (v2 - rate) - self.z3) / self._b0
        )

    def observe_applied(self, applied_control: float) -> None:
        """Predict z(k+1|k) = Phi z(k|k) + Gamma u(k) with the control actually applied."""
        h, z2, z3 = self._h, self.z2, self.z3
        self.z1 += h * z2 + 0.5 * h * h * z3 + self._g1 * applied_control
        self.z2 = z2 + h * z3 + self._g2 * applied_control

    def state(self) -> dict[str, float]:
        return {"z1": self.z1, "z2": self.z2, "z3": self.z3}
