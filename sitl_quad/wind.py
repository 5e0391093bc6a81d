"""Wind: a constant mean wind, a 1-cosine discrete gust, Dryden turbulence (MIL-F-8785C, low altitude) and,
optionally, a slowly wandering mean wind.

All velocities are NED m/s of the air mass. Directions are meteorological: the direction the wind comes
FROM, degrees clockwise from north (a 270 deg wind blows toward the east).

Dryden turbulence, low-altitude forms of MIL-F-8785C (h in feet, clamped to 10..1000 ft; W20 = wind speed
at 20 ft):
    L_w = h,  L_u = L_v = h / (0.177 + 0.000823 h)^1.2
    sigma_w = 0.1 W20,  sigma_u = sigma_v = sigma_w / (0.177 + 0.000823 h)^0.4
    H_u(s) ~ 1 / (1 + (L_u/V) s),   H_v(s), H_w(s) ~ (1 + sqrt(3) (L/V) s) / (1 + (L/V) s)^2
u blows along the mean wind (north when there is none), v to its right, w down. V is the airspeed, held at
1 m/s or more because Dryden's frozen-turbulence form degenerates at hover.

Each filter is integrated exactly over the step (state transition and noise covariance of the continuous
process over dt), with its state kept in units where the stationary covariance is fixed. So the output's
standard deviation is the configured intensity at any step size and the state does not jump when the
airspeed or altitude changes; the initial state is drawn from the stationary distribution.

Wandering mean wind (`wander_std_m_s` > 0; off by default): the mean wind vector drifts. Its north and east
components each get an independent first-order Gauss-Markov (Ornstein-Uhlenbeck) deviation
    dx = -x / T dt + sqrt(2 / T) sigma dW,  T = wander_time_constant_s, sigma = wander_std_m_s,
started from its stationary distribution (so the spread is sigma from the first second) and sampled exactly
every WANDER_SAMPLE_S on the disturbance clock over wander_horizon_s (held after that), linearly
interpolated in between: over a window much longer than T each component's standard deviation is sigma and
its autocorrelation exp(-lag / T). The path is drawn once per WindModel from its own seed stream (a child of the
wind's seed that leaves the turbulence's draws untouched), so it is deterministic per seed and a flight without
wander keeps exactly the numbers it had before the option existed. The turbulence's axes stay aligned with the
configured mean direction.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sitl_quad.normal_stream import NormalStream, Zeros
from uavcore.airframe import ModelParameterError
from uavcore.kernel_cache import cached_kernel

FEET = 0.3048
MIN_TURBULENCE_AIRSPEED = 1.0  # m/s
TURBULENCE_NOISE_PER_STEP = 5  # unit normals per step: u 1, v 2, w 2

# Layout of the flat parameter array the kernels read (WindModel.params).
W_MEAN_N, W_MEAN_E, W_GUST_AMPLITUDE, W_GUST_RISE, W_GUST_START, W_GUST_HOLD = 0, 1, 2, 3, 4, 5
W_GUST_DIR_N, W_GUST_DIR_E, W_W20, W_TURB_DIR_N, W_TURB_DIR_E = 6, 7, 8, 9, 10
N_WIND_PARAMS = 11
# With a wandering mean wind the array goes on: [N_WIND_PARAMS] = sample interval, then north, east per sample.
W_WANDER_DT = N_WIND_PARAMS
WANDER_SAMPLE_S = 0.5
WANDER_SEED_KEY = 0x57A0  # the wander's seed stream: the wind's seed sequence with this appended to its spawn key


@dataclass(frozen=True)
class WindConfig:
    """Wind seen by the vehicle. All zero (the default) is still air."""

    speed_m_s: float = 0.0  # constant mean wind
    direction_from_deg: float = 0.0
    gust_amplitude_m_s: float = 0.0  # 1-cosine gust added to the mean wind
    gust_rise_time_s: float = 0.1  # time to reach the amplitude
    gust_start_s: float = 0.0
    gust_hold_s: float = math.inf  # time at full amplitude before a mirrored fall; inf = stays (MIL-F-8785C)
    gust_direction_from_deg: float = 0.0
    turbulence_w20_m_s: float = 0.0  # Dryden intensity set by the wind speed at 20 ft; 0 = no turbulence
    wander_std_m_s: float = 0.0  # wandering mean wind: std of each horizontal component's drift; 0 = none
    wander_time_constant_s: float = 30.0  # its correlation time T
    wander_horizon_s: float = 3600.0  # the drift is drawn over this much disturbance-clock time, then held

    def __post_init__(self) -> None:
        for name in (
            "speed_m_s",
            "direction_from_deg",
            "gust_amplitude_m_s",
            "gust_rise_time_s",
            "gust_start_s",
            "gust_direction_from_deg",
            "turbulence_w20_m_s",
        ):
            value = getattr(self, name)
            if not isinstance(value, int | float) or not math.isfinite(value):
                raise ModelParameterError(f"wind parameter {name} must be a finite number, got {value!r}")
        if self.speed_m_s < 0 or self.turbulence_w20_m_s < 0:
            raise ModelParameterError("wind speed and turbulence W20 must be >= 0")
        if self.gust_rise_time_s <= 0:
            raise ModelParameterError(f"gust_rise_time_s must be positive, got {self.gust_rise_time_s}")
        if not self.gust_hold_s >= 0:
            raise ModelParameterError(f"gust_hold_s must be >= 0 (inf to hold), got {self.gust_hold_s}")
        for name in ("wander_std_m_s", "wander_time_constant_s", "wander_horizon_s"):
            value = getattr(self, name)
            if not isinstance(value, int | float) or not math.isfinite(value) or value < 0:
                raise ModelParameterError(f"wind parameter {name} must be finite and >= 0, got {value!r}")
        if self.wander_std_m_s > 0 and (self.wander_time_constant_s <= 0 or self.wander_horizon_s <= 0):
            raise ModelParameterError("a wandering wind needs wander_time_constant_s > 0 and wander_horizon_s > 0")

    def wander_path(self, rng: np.random.Generator) -> np.ndarray:
        """(n, 2) north, east deviations of the mean wind every WANDER_SAMPLE_S from t = 0 (empty without
        wander): the exact discrete Ornstein-Uhlenbeck process, first sample from its stationary law."""
        if self.wander_std_m_s == 0:
            return np.zeros((0, 2))
        n = math.ceil(self.wander_horizon_s / WANDER_SAMPLE_S) + 1
        phi = math.exp(-WANDER_SAMPLE_S / self.wander_time_constant_s)
        innovation = self.wander_std_m_s * math.sqrt(1.0 - phi * phi)
        normals = rng.standard_normal((n, 2))
        path = np.empty((n, 2))
        path[0] = self.wander_std_m_s * normals[0]
        for k in range(1, n):
            path[k] = phi * path[k - 1] + innovation * normals[k]
        return path

    def as_array(self) -> np.ndarray:
        params = np.zeros(N_WIND_PARAMS)
        to_n, to_e = _blowing_toward(self.direction_from_deg)
        params[W_MEAN_N], params[W_MEAN_E] = self.speed_m_s * to_n, self.speed_m_s * to_e
        params[W_GUST_AMPLITUDE] = self.gust_amplitude_m_s
        params[W_GUST_RISE] = self.gust_rise_time_s
        params[W_GUST_START] = self.gust_start_s
        params[W_GUST_HOLD] = self.gust_hold_s
        params[W_GUST_DIR_N], params[W_GUST_DIR_E] = _blowing_toward(self.gust_direction_from_deg)
        params[W_W20] = self.turbulence_w20_m_s
        if self.speed_m_s > 0:
            params[W_TURB_DIR_N], params[W_TURB_DIR_E] = to_n, to_e
        else:
            params[W_TURB_DIR_N] = 1.0
        return params


def _blowing_toward(direction_from_deg: float) -> tuple[float, float]:
    angle = math.radians(direction_from_deg)
    return -math.cos(angle), -math.sin(angle)


@cached_kernel
def _regularized_gamma_p(k: int, x: float) -> float:
    """P(k, x) = 1 - exp(-x) sum_{j<k} x^j / j!  for integer k >= 1, accurate also for tiny x."""
    if x > 1.0:
        partial, term = 0.0, 1.0
        for j in range(k):
            partial += term
            term *= x / (j + 1)
        return 1.0 - math.exp(-x) * partial
    term = 1.0
    for j in range(k):
        term *= x / (j + 1)
    total = 0.0
    j = k
    while term > 1e-18 * total and j < k + 60:
        total += term
        j += 1
        term *= x / j
    return math.exp(-x) * total


@cached_kernel
def _first_order_step(state: np.ndarray, i: int, rate: float, dt: float, noise: float) -> None:
    """Exact step of x' = -a x + sqrt(2a) eta with unit stationary variance."""
    state[i] = math.exp(-rate * dt) * state[i] + math.sqrt(_regularized_gamma_p(1, 2.0 * rate * dt)) * noise


@cached_kernel
def _second_order_step(state: np.ndarray, i: int, rate: float, dt: float, n1: float, n2: float) -> float:
    """Exact step of the Dryden v/w shaping filter a^2 (1 + sqrt(3) s / a) / (s + a)^2 driven by white noise.

    States x1 = eta / (s + a), x2 = x1 / (s + a), scaled by a^(1/2), a^(3/2) so that the stationary
    covariance is [[1/2, 1/4], [1/4, 1/4]]; then sqrt(3) x1 + (1 - sqrt(3)) x2 has unit variance.
    Returns that unit-variance output.
    """
    e = rate * dt
    decay = math.exp(-e)
    x = 2.0 * e
    q11 = 0.5 * _regularized_gamma_p(1, x)
    q12 = 0.25 * _regularized_gamma_p(2, x)
    q22 = 0.25 * _regularized_gamma_p(3, x)
    l11 = math.sqrt(q11)
    l21 = q12 / l11 if l11 > 0.0 else 0.0
    l22 = math.sqrt(max(q22 - l21 * l21, 0.0))
    x1, x2 = state[i], state[i + 1]
    state[i] = decay * x1 + l11 * n1
    state[i + 1] = decay * (e * x1 + x2) + l21 * n1 + l22 * n2
    return math.sqrt(3.0) * state[i] + (1.0 - math.sqrt(3.0)) * state[i + 1]


@cached_kernel
def gust_speed(params: np.ndarray, t: float) -> float:
    """1-cosine gust magnitude at time t: rises over the rise time, holds, then falls back mirrored."""
    amplitude, rise = params[W_GUST_AMPLITUDE], params[W_GUST_RISE]
    start, hold = params[W_GUST_START], params[W_GUST_HOLD]
    if amplitude == 0.0 or t < start:
        return 0.0
    tau = t - start
    if tau < rise:
        return 0.5 * amplitude * (1.0 - math.cos(math.pi * tau / rise))
    tau -= rise + hold
    if tau < 0.0:
        return amplitude
    if tau < rise:
        return 0.5 * amplitude * (1.0 + math.cos(math.pi * tau / rise))
    return 0.0


@cached_kernel
def mean_and_gust(params: np.ndarray, t: float, out: np.ndarray) -> None:
    """Mean wind + gust (NED) into out: the part of the wind that is not turbulence."""
    gust = gust_speed(params, t)
    out[0] = params[W_MEAN_N] + gust * params[W_GUST_DIR_N]
    out[1] = params[W_MEAN_E] + gust * params[W_GUST_DIR_E]
    out[2] = 0.0
    samples = (params.shape[0] - W_WANDER_DT - 1) // 2
    if samples > 0:  # a wandering mean wind: its path, linearly interpolated
        x = max(t, 0.0) / params[W_WANDER_DT]
        k = min(int(x), samples - 1)
        frac = min(x - k, 1.0) if k < samples - 1 else 0.0
        base = W_WANDER_DT + 1 + 2 * k
        nxt = base + 2 if k < samples - 1 else base
        out[0] += (1.0 - frac) * params[base] + frac * params[nxt]
        out[1] += (1.0 - frac) * params[base + 1] + frac * params[nxt + 1]


@cached_kernel
def wind_velocity(
    params: np.ndarray,
    turbulence: np.ndarray,
    noise: np.ndarray,
    t: float,
    dt: float,
    altitude_m: float,
    airspeed_m_s: float,
    out: np.ndarray,
) -> None:
    """Advance the turbulence state by dt with the given 5 unit normals and write the wind at t into out."""
    mean_and_gust(params, t, out)
    w20 = params[W_W20]
    if w20 == 0.0:
        return
    h_ft = min(max(altitude_m / FEET, 10.0), 1000.0)
    factor = 0.177 + 0.000823 * h_ft
    length_w = h_ft * FEET
    length_uv = h_ft / factor**1.2 * FEET
    sigma_w = 0.1 * w20
    sigma_uv = sigma_w / factor**0.4
    speed = max(airspeed_m_s, MIN_TURBULENCE_AIRSPEED)
    _first_order_step(turbulence, 0, speed / length_uv, dt, noise[0])
    u = sigma_uv * turbulence[0]
    v = sigma_uv * _second_order_step(turbulence, 1, speed / length_uv, dt, noise[1], noise[2])
    w = sigma_w * _second_order_step(turbulence, 3, speed / length_w, dt, noise[3], noise[4])
    dn, de = params[W_TURB_DIR_N], params[W_TURB_DIR_E]
    out[0] += u * dn - v * de
    out[1] += u * de + v * dn
    out[2] += w


@cached_kernel
def _wind_series(
    params: np.ndarray,
    turbulence: np.ndarray,
    noise: np.ndarray,
    t0: float,
    dt: float,
    altitude_m: float,
    airspeed_m_s: float,
) -> np.ndarray:
    n = noise.shape[0]
    series = np.empty((n, 3))
    for k in range(n):
        wind_velocity(params, turbulence, noise[k], t0 + (k + 1) * dt, dt, altitude_m, airspeed_m_s, series[k])
    return series


def initial_turbulence_state(rng: np.random.Generator) -> np.ndarray:
    """A draw from the filters' stationary distribution, so statistics are right from the first step."""
    state = np.empty(5)
    state[0] = rng.standard_normal()
    for i in (1, 3):  # covariance [[1/2, 1/4], [1/4, 1/4]], Cholesky [[sqrt(1/2), 0], [sqrt(1/8), sqrt(1/8)]]
        n1, n2 = rng.standard_normal(2)
        state[i] = math.sqrt(0.5) * n1
        state[i + 1] = math.sqrt(0.125) * (n1 + n2)
    return state


def wander_rng(rng: np.random.Generator) -> np.random.Generator:
    """The wandering wind's own stream: derived from the wind generator's seed sequence without drawing from it."""
    seq = rng.bit_generator.seed_seq
    if not isinstance(seq, np.random.SeedSequence):
        raise ModelParameterError("a wandering wind needs a wind generator made from a seed (SeedSequence)")
    return np.random.default_rng(
        np.random.SeedSequence(entropy=seq.entropy, spawn_key=(*seq.spawn_key, WANDER_SEED_KEY))
    )


class WindModel:
    """Stateful wind source. ``velocity`` advances the turbulence from the previous call's time to t."""

    def __init__(self, config: WindConfig | None = None, seed: int | np.random.Generator = 0) -> None:
        self.config = config or WindConfig()
        self.rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
        self.params = self.config.as_array()
        if self.config.wander_std_m_s > 0:
            self.wander = self.config.wander_path(wander_rng(self.rng))
            self.params = np.concatenate([self.params, [WANDER_SAMPLE_S], self.wander.ravel()])
        else:
            self.wander = np.zeros((0, 2))
        self.turbulent = self.config.turbulence_w20_m_s > 0
        self.turbulence = initial_turbulence_state(self.rng) if self.turbulent else np.zeros(5)
        self._t: float | None = None
        self._out = np.zeros(3)
        self._normals: NormalStream | Zeros | None = None

    def noise(self, steps: int) -> np.ndarray:
        """Unit normals driving `steps` turbulence updates (zeros, and no draw, without turbulence)."""
        if self._normals is None:
            self._normals = (
                NormalStream(self.rng, TURBULENCE_NOISE_PER_STEP)
                if self.turbulent
                else Zeros(TURBULENCE_NOISE_PER_STEP)
            )
        return self._normals.take(steps)

    def velocity(self, t: float, altitude_m: float, airspeed_m_s: float) -> np.ndarray:
        """Wind (NED m/s) at time t; t must not go backwards."""
        dt = 0.0 if self._t is None else t - self._t
        if dt < 0:
            raise ModelParameterError(f"wind time went backwards: {t} after {self._t}")
        self._t = t
        wind_velocity(self.params, self.turbulence, self.noise(1)[0], t, dt, altitude_m, airspeed_m_s, self._out)
        return self._out.copy()

    def series(self, steps: int, dt: float, altitude_m: float, airspeed_m_s: float) -> np.ndarray:
        """(steps, 3) wind samples every dt after the current time, at fixed altitude and airspeed (fast)."""
        if dt <= 0 or steps < 0:
            raise ModelParameterError("series needs dt > 0 and steps >= 0")
        t0 = 0.0 if self._t is None else self._t
        out = _wind_series(self.params, self.turbulence, self.noise(steps), t0, dt, altitude_m, airspeed_m_s)
        self._t = t0 + steps * dt
        return out
