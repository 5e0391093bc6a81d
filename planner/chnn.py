"""Continuous Hopfield neural network (CHNN) for the buoy tour, paper Section V-B, eq. (14)-(16).

Neuron (x, i) says "buoy x is visited i-th"; the state is an m x m matrix v for m buoys. The depot is the
tour's fixed start and end, so it is not a neuron row: it is clamped before position 0 and after position m-1
(the same clamping re-optimises a stretch of a longer tour between two fixed cities, which is how the GA
uses the network as a mutation on large instances).

Energy, eq. (15), with distances divided by the largest one so that one parameter set fits any scale:
    E1 = A/2 sum_x sum_i sum_{j != i} v_xi v_xj          (each buoy in at most one position)
    E2 = B/2 sum_i sum_x sum_{y != x} v_xi v_yi          (each position holds at most one buoy)
    E3 = C/2 (sum_xi v_xi - n_bar)^2                     (m neurons on in total; n_bar = m + excess)
    E4 = D/2 sum_x sum_{y != x} sum_i d_xy v_xi (v_y,i+1 + v_y,i-1)   (tour length, depot legs included)
The weights of eq. (14) are the second derivatives of this E: w_xi,yj = -A δxy(1-δij) - B δij(1-δxy) - C
- D d_xy (δj,i+1 + δj,i-1); the C n_bar term is the neurons' bias. The dynamics is
    du/dt = -u/tau - dE/dv     (Hopfield & Tank; tau = None drops the leak: a pure gradient flow on E)
    v = 1/2 (1 + tanh(u / u0))                                   eq. (16), activation
    u(0) = 1/2 u0 ln(m - 1) + δ, δ uniform in (-1, 1) x init_noise eq. (16), initial state
    u(t + 1) = u(t) + du/dt Δt                                   eq. (16), Euler step
Every step is a few batched matrix products over all neurons of all networks at once: O(K m^3) per step
for K networks, no Python loop over neurons.

Two parameter sets are offered:
- ``HOPFIELD_TANK``: the classic 1985 values (A = B = 500, C = 200, D = 500, u0 = 0.02, n_bar = m + m/2,
  tau = 1, fixed Δt = 1e-5), famous for converging to invalid states.
- ``VALID_TOURS`` (the default): chosen from the stability of the hypercube's corners, in the spirit of
  Talavan & Yanez (2002), "Parameter setting of the Hopfield network applied to TSP". At a corner the
  gradient of neuron (x, i) is g = A (r_x - v) + B (c_i - v) + C (S - n_bar) + D h_xi, with r, c the row and
  column sums, S the total and 0 <= h_xi <= 2 (normalised distances). A neuron that is on stays on iff g < 0,
  one that is off stays off iff g > 0. With excess = n_bar - m:
    every valid tour is a stable corner        <=   C excess > 2 D  and  A + B > C excess
    a second neuron in a row/column is unstable <=   A > C excess  and  B > C excess
    a missing row/column is filled              <=   C (1 + excess) > 2 D
  so A = B = 8, C = 4, excess = 1.5, D = 2.9 satisfies all (D as large as they allow: the larger D relative
  to A and B, the shorter the tours; a sweep of such sets gave 99 % valid runs here against 80 % for bolder
  ones). δ is scaled down (init_noise = 0.01, with gain u0 = 1) so that the distances, not the
  initial noise, decide which corner the flow falls into. The leak is dropped (tau = None) so E is a
  Lyapunov function of the flow: dE/dt = -sum f'(u) (dE/dv)^2 <= 0. The Euler steps keep that property
  with step control (a step that would raise E is refused and Δt halved; accepted steps grow Δt up to 0.3):
  the early phase, with every neuron half on, is stiff (the E3 curvature is C m^2), the late phase is slow.
  These are conditions on the corners only, not a proof of convergence from every start: 300 steps end on a
  valid tour in nearly every run on the 13-buoy set (bench/planner_bench.py measures the rate).
  Valid end states are what Algorithm 2 needs: an invalid child is wasted work.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np


@dataclass(frozen=True)
class CHNNParameters:
    """Weights of eq. (14)-(15) and the integration settings of eq. (16)."""

    name: str
    A: float
    B: float
    C: float
    D: float
    u0: float  # activation gain: v = 1/2 (1 + tanh(u / u0))
    dt: float  # Euler step Δt
    steps: int  # Euler steps per run (k_chnn of Algorithm 2)
    excess: float  # n_bar = m + excess * (m if excess_per_node else 1)
    excess_per_node: bool = False
    tau: float | None = None  # leak time constant; None = pure gradient flow
    init_noise: float = 1.0  # δ of eq. (16) is uniform in (-init_noise, init_noise)
    adaptive_step: bool = False  # refuse Euler steps that raise E (halve Δt), else grow Δt up to dt_max
    dt_max: float = 0.0

    def n_bar(self, m: int) -> float:
        return m + self.excess * (m if self.excess_per_node else 1.0)


HOPFIELD_TANK = CHNNParameters(
    name="hopfield-tank",
    A=500.0,
    B=500.0,
    C=200.0,
    D=500.0,
    u0=0.02,
    dt=1e-5,
    steps=1000,
    excess=0.5,
    excess_per_node=True,
    tau=1.0,
    init_noise=0.002,
)
VALID_TOURS = CHNNParameters(
    name="valid-tours",
    A=8.0,
    B=8.0,
    C=4.0,
    D=2.9,
    u0=1.0,
    dt=0.01,
    steps=300,
    excess=1.5,
    init_noise=0.01,
    adaptive_step=True,
    dt_max=0.3,
)


@dataclass
class CHNNRun:
    """The final states of K networks run side by side, and their energy per Euler step."""

    v: np.ndarray  # (K, m, m) activations, rows = buoys, columns = visiting order
    energy: np.ndarray  # (steps + 1, K) energy E of eq. (15) at every step


def _shift_matrix(m: int) -> np.ndarray:
    """S with (v S)_xi = v_x,i+1 + v_x,i-1 (zero beyond the first and last position)."""
    return np.eye(m, k=1) + np.eye(m, k=-1)


def _boundary(d_start: np.ndarray, d_end: np.ndarray, m: int) -> np.ndarray:
    """The clamped ends' share of the neighbour field: d_x,start in the first column, d_x,end in the last."""
    bound = np.zeros((*np.shape(d_start)[:-1], m, m))
    bound[..., :, 0] += d_start
    bound[..., :, -1] += d_end
    return bound


def _energy_and_gradient(v, d, shift, boundary, params: CHNNParameters):
    """E of eq. (15) per network of a (K, m, m) batch and dE/dv = -(sum_yj w_xi,yj v_yj + bias) with the
    weights w of eq. (14). E is quadratic, E = 1/2 v.(H v) + b.v + C n_bar^2 / 2 with dE/dv = H v + b, so
    E = 1/2 v.(dE/dv + b) + C n_bar^2 / 2 costs one more product instead of re-evaluating E1..E4."""
    m = v.shape[-1]
    n_bar = params.n_bar(m)
    rows = v.sum(axis=-1, keepdims=True)
    cols = v.sum(axis=-2, keepdims=True)
    total = rows.sum(axis=-2, keepdims=True)
    # neighbour field h_xi = sum_y d_xy (v_y,i+1 + v_y,i-1), the clamped ends included
    field = d @ v @ shift + boundary
    gradient = (
        params.A * rows + params.B * cols + params.C * (total - n_bar) - (params.A + params.B) * v + params.D * field
    )
    linear = params.D * (v * boundary).sum(axis=(-1, -2)) - params.C * n_bar * total[..., 0, 0]
    e = 0.5 * ((v * gradient).sum(axis=(-1, -2)) + linear) + 0.5 * params.C * n_bar**2
    return e, gradient


def energy_terms(
    v: np.ndarray, d: np.ndarray, d_start: np.ndarray, d_end: np.ndarray, params: CHNNParameters
) -> dict[str, np.ndarray]:
    """E1..E4 of eq. (15) evaluated term by term (for tests and plots; the dynamics uses the fast form)."""
    m = v.shape[-1]
    rows = v.sum(axis=-1)
    cols = v.sum(axis=-2)
    squares = (v**2).sum(axis=(-1, -2))
    adjacent = v @ _shift_matrix(m)
    interior = (v * (d @ adjacent)).sum(axis=(-1, -2))  # counts each leg between buoys twice
    depot_legs = (v[..., :, 0] * d_start).sum(-1) + (v[..., :, -1] * d_end).sum(-1)
    return {
        "E1": params.A / 2 * ((rows**2).sum(axis=-1) - squares),
        "E2": params.B / 2 * ((cols**2).sum(axis=-1) - squares),
        "E3": params.C / 2 * (v.sum(axis=(-1, -2)) - params.n_bar(m)) ** 2,
        "E4": params.D / 2 * interior + params.D * depot_legs,
    }


def energy(v: np.ndarray, d: np.ndarray, d_start: np.ndarray, d_end: np.ndarray, params: CHNNParameters) -> np.ndarray:
    """E = E1 + E2 + E3 + E4 of eq. (15) for each network of a (K, m, m) batch (distances normalised)."""
    m = v.shape[-1]
    return _energy_and_gradient(v, d, _shift_matrix(m), _boundary(d_start, d_end, m), params)[0]


def energy_gradient(
    v: np.ndarray, d: np.ndarray, d_start: np.ndarray, d_end: np.ndarray, params: CHNNParameters
) -> np.ndarray:
    """dE/dv for each network of a (K, m, m) batch."""
    m = v.shape[-1]
    return _energy_and_gradient(v, d, _shift_matrix(m), _boundary(d_start, d_end, m), params)[1]


def activation(u: np.ndarray, u0: float) -> np.ndarray:
    """Eq. (16): v = 1/2 (1 + tanh(u / u0))."""
    return 0.5 * (1.0 + np.tanh(u / u0))


def initial_state(
    batch: int,
    m: int,
    params: CHNNParameters,
    rng: np.random.Generator,
    parents: np.ndarray | None = None,
    parent_bias: float = 0.0,
) -> np.ndarray:
    """Eq. (16): u = 1/2 u0 ln(m - 1) + δ. With ``parents`` ((K, m) buoy order per network) the neurons of
    each parent's tour get +parent_bias and the others -parent_bias: the GA's "input of the next CHNN"."""
    delta = rng.uniform(-1.0, 1.0, size=(batch, m, m)) * params.init_noise
    u = 0.5 * params.u0 * np.log(max(m - 1, 1)) + delta
    if parents is not None:
        on = np.zeros((batch, m, m), dtype=bool)
        on[np.arange(batch)[:, None], parents, np.arange(m)[None, :]] = True
        u += np.where(on, parent_bias, -parent_bias)
    return u


def run_chnn(
    d: np.ndarray, d_start: np.ndarray, d_end: np.ndarray, params: CHNNParameters, u_init: np.ndarray
) -> CHNNRun:
    """Integrate K networks side by side from u_init ((K, m, m)) for params.steps Euler steps.

    d: (m, m) distances between the free nodes, d_start / d_end: (m,) distances to the clamped ends, all
    already normalised (see ``normalised``)."""
    u = np.array(u_init, dtype=float)
    m = u.shape[-1]
    shift, boundary = _shift_matrix(m), _boundary(d_start, d_end, m)
    v = activation(u, params.u0)
    trace = np.empty((params.steps + 1, len(u)))
    e, gradient = _energy_and_gradient(v, d, shift, boundary, params)
    trace[0] = e
    dt = np.full((len(u), 1, 1), params.dt)
    for step in range(params.steps):
        du = -gradient
        if params.tau is not None:
            du -= u / params.tau
        u_next = u + dt * du
        v_next = activation(u_next, params.u0)
        e_next, gradient_next = _energy_and_gradient(v_next, d, shift, boundary, params)
        if params.adaptive_step:
            # Euler with step control: a step that would raise E is refused and Δt halved (the stiff early
            # phase, when every neuron is half on); accepted steps let Δt grow back up to dt_max.
            accept = (e_next <= e)[:, None, None]
            u = np.where(accept, u_next, u)
            v = np.where(accept, v_next, v)
            gradient = np.where(accept, gradient_next, gradient)
            e = np.where(accept[:, 0, 0], e_next, e)
            dt = np.where(accept, np.minimum(dt * 1.25, params.dt_max), dt * 0.5)
        else:
            u, v, e, gradient = u_next, v_next, e_next, gradient_next
        trace[step + 1] = e
    return CHNNRun(v=v, energy=trace)


def normalised(dist: np.ndarray, free: np.ndarray, start: int, end: int):
    """Distances among the free nodes and to the clamped start/end, divided by the largest of them."""
    nodes = np.concatenate([free, [start, end]])
    scale = float(dist[np.ix_(nodes, nodes)].max()) or 1.0
    return dist[np.ix_(free, free)] / scale, dist[free, start] / scale, dist[free, end] / scale


def decode(v: np.ndarray) -> np.ndarray | None:
    """The visiting order (row index of the buoy in each position) if v > 1/2 is a permutation matrix, else
    None: the validity check of Algorithm 2, line 9."""
    on = v > 0.5
    if not (np.all(on.sum(axis=0) == 1) and np.all(on.sum(axis=1) == 1)):
        return None
    return np.argmax(on, axis=0)


def with_steps(params: CHNNParameters, steps: int) -> CHNNParameters:
    return replace(params, steps=steps)
