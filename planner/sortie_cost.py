"""What one sortie costs: flight time and energy of an ordered list of buoys flown from the depot and back.

The multi-sortie planner (planner.sorties) reads only a ``SortieCost``: leg matrices (asymmetric allowed:
with wind, A->B and B->A differ), per-buoy dwell, a fixed per-sortie part (take-off, climb, descent, landing)
and the usable energy of one battery. How those numbers come about is this module's default model, a
simple physical one with its parameters as data; the calibrated energy model (planner.energy, fitted on
simulated flights: ``calibrated_sortie_cost``) hands the planner the same object.

Default model (``FlightEnergyModel``):
- a leg i->j is flown at the commanded air speed V_a with a constant wind w. The ground velocity must point
  along the leg's unit vector u, so V_a h = v_g u - w for the heading h, and |h| = 1 gives the wind triangle
      v_g = w.u + sqrt(V_a^2 - |w - (w.u) u|^2)
  (the crosswind is cancelled by crabbing, the along-track wind adds to the air speed);
  leg time t_ij = d_ij / v_g, leg energy P_cruise t_ij;
- a buoy's dwell (the inspection hover) costs P_hover t_dwell;
- each sortie adds the take-off + climb and descent + landing: fixed time and energy;
- usable energy per sortie = capacity x (1 - reserve).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from planner.distances import check_points, euclidean_matrix
from planner.errors import InputError

WH_PER_J = 1.0 / 3600.0


@dataclass(frozen=True)
class EnergyBudget:
    """One battery: its capacity and the share held back as the landing reserve."""

    capacity_wh: float
    reserve: float = 0.2  # fraction of the capacity never planned for

    @property
    def usable_wh(self) -> float:
        return self.capacity_wh * (1.0 - self.reserve)


@dataclass(frozen=True)
class FlightEnergyModel:
    """The default model's parameters (SI units); defaults are a ~2 kg quadrotor's order of magnitude."""

    air_speed_m_s: float = 10.0  # commanded cruise air speed (planner.scenario.CRUISE_SPEED_M_S)
    cruise_power_w: float = 160.0  # electrical power in level cruise at air_speed_m_s
    hover_power_w: float = 175.0  # electrical power in the dwell hover
    dwell_s: float = 10.0  # inspection hover at each buoy
    takeoff_s: float = 12.0  # spool-up, take-off and climb to the cruise altitude
    takeoff_power_w: float = 210.0
    landing_s: float = 12.0  # descent and landing
    landing_power_w: float = 150.0
    wind_east_m_s: float = 0.0  # constant wind vector the air moves WITH (east, north)
    wind_north_m_s: float = 0.0


@dataclass(frozen=True)
class SortieCost:
    """Everything the sortie planner knows about cost; node 0 is the depot, nodes 1..n-1 the buoys.

    A sortie [b1, ..., bk] is flown 0 -> b1 -> ... -> bk -> 0; its time is
        sortie_time_s + sum of leg_time_s over its legs + sum of dwell_time_s over its buoys
    and its energy likewise with the energy arrays; it is feasible when its energy <= budget_wh.
    """

    leg_time_s: np.ndarray  # (n, n); leg_time_s[i, j] flies i -> j (may differ from j -> i)
    leg_energy_wh: np.ndarray  # (n, n)
    leg_distance_m: np.ndarray  # (n, n) horizontal distance
    dwell_time_s: np.ndarray  # (n,), 0 at the depot
    dwell_energy_wh: np.ndarray  # (n,)
    sortie_time_s: float  # fixed part of every sortie
    sortie_energy_wh: float
    budget_wh: float  # usable energy of one battery

    def __post_init__(self) -> None:
        n = len(self.leg_time_s)
        for name in ("leg_time_s", "leg_energy_wh", "leg_distance_m"):
            value = getattr(self, name)
            if value.shape != (n, n) or not np.all(np.isfinite(value)) or np.any(value < 0):
                raise InputError(f"{name} must be a finite non-negative ({n}, {n}) matrix")
        for name in ("dwell_time_s", "dwell_energy_wh"):
            value = getattr(self, name)
            if value.shape != (n,) or not np.all(np.isfinite(value)) or np.any(value < 0):
                raise InputError(f"{name} must be {n} finite non-negative numbers")
        if n < 2:
            raise InputError(f"need a depot and at least one buoy (2 nodes); got {n}")
        if not (self.budget_wh > 0 and math.isfinite(self.budget_wh)):
            raise InputError(f"budget_wh must be a positive number, got {self.budget_wh!r}")

    @property
    def n(self) -> int:
        """Nodes, the depot included."""
        return len(self.leg_time_s)

    def _legs(self, sortie) -> tuple[np.ndarray, np.ndarray]:
        path = np.asarray([0, *sortie, 0], dtype=np.int64)
        return path[:-1], path[1:]

    def time_s(self, sortie) -> float:
        """Flight time of one sortie, take-off to landing."""
        frm, to = self._legs(sortie)
        return float(self.sortie_time_s + self.leg_time_s[frm, to].sum() + self.dwell_time_s[list(sortie)].sum())

    def energy_wh(self, sortie) -> float:
        """Energy of one sortie."""
        frm, to = self._legs(sortie)
        return float(
            self.sortie_energy_wh + self.leg_energy_wh[frm, to].sum() + self.dwell_energy_wh[list(sortie)].sum()
        )

    def distance_m(self, sortie) -> float:
        """Horizontal distance of one sortie."""
        frm, to = self._legs(sortie)
        return float(self.leg_distance_m[frm, to].sum())

    def alone_energy_wh(self) -> np.ndarray:
        """Energy of flying to each buoy alone and back ([0] is 0): the least any sortie through it needs."""
        e = self.sortie_energy_wh + self.leg_energy_wh[0, :] + self.leg_energy_wh[:, 0] + self.dwell_energy_wh
        e[0] = 0.0
        return e

    def violations(self, sorties) -> list[str]:
        """Why a set of sorties is not a valid plan (empty list when it is): every buoy exactly once, the
        depot in none, each sortie within the budget. The planner's own check and the benchmark's judge."""
        problems = []
        seen = [b for sortie in sorties for b in sortie]
        if sorted(seen) != list(range(1, self.n)):
            missing = sorted(set(range(1, self.n)) - set(seen))
            twice = sorted({b for b in seen if seen.count(b) > 1})
            problems.append(f"buoys missing {missing}, visited twice {twice}, or a depot/unknown node in a sortie")
        tolerance = 1e-9 * self.budget_wh
        for k, sortie in enumerate(sorties):
            if not sortie:
                problems.append(f"sortie {k} is empty")
                continue
            energy = self.energy_wh(sortie)
            if energy > self.budget_wh + tolerance:
                problems.append(f"sortie {k} needs {energy:.3f} Wh > budget {self.budget_wh:.3f} Wh")
        return problems


def ground_speed(air_speed: float, wind: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """Ground speed along unit vectors ``direction`` (..., 2) flying at ``air_speed`` in ``wind`` (2,): the wind
    triangle v_g = w.u + sqrt(V_a^2 - |w_perp|^2). Needs V_a > |w| so that every direction is flyable."""
    along = direction @ wind
    cross_sq = np.maximum(wind @ wind - along**2, 0.0)
    return along + np.sqrt(air_speed**2 - cross_sq)


def default_sortie_cost(points, budget: EnergyBudget, model: FlightEnergyModel | None = None) -> SortieCost:
    """The default model's SortieCost for planar points ((n, 2) metres east/north, node 0 the depot)."""
    model = model or FlightEnergyModel()
    pts = check_points(points)
    wind = np.array([model.wind_east_m_s, model.wind_north_m_s], dtype=float)
    if not model.air_speed_m_s > math.hypot(*wind):
        raise InputError(
            f"air speed {model.air_speed_m_s} m/s must exceed the wind {math.hypot(*wind):.1f} m/s to fly every leg"
        )
    if not 0.0 <= budget.reserve < 1.0 or not budget.capacity_wh > 0:
        raise InputError(f"battery capacity must be > 0 and reserve in [0, 1); got {budget}")
    dist = euclidean_matrix(pts)
    delta = pts[None, :, :] - pts[:, None, :]  # delta[i, j] points from i to j
    with np.errstate(invalid="ignore", divide="ignore"):
        unit = np.where(dist[..., None] > 0, delta / dist[..., None], 0.0)
    speed = ground_speed(model.air_speed_m_s, wind, unit)
    leg_time = np.where(dist > 0, dist / speed, 0.0)
    n = len(pts)
    dwell = np.full(n, model.dwell_s)
    dwell[0] = 0.0
    return SortieCost(
        leg_time_s=leg_time,
        leg_energy_wh=model.cruise_power_w * leg_time * WH_PER_J,
        leg_distance_m=dist,
        dwell_time_s=dwell,
        dwell_energy_wh=model.hover_power_w * dwell * WH_PER_J,
        sortie_time_s=model.takeoff_s + model.landing_s,
        sortie_energy_wh=(model.takeoff_power_w * model.takeoff_s + model.landing_power_w * model.landing_s) * WH_PER_J,
        budget_wh=budget.usable_wh,
    )
