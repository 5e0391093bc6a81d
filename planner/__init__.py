"""Route planner: CHNN-GA (paper Section V) with Held-Karp as the exact oracle. Pure computation.

``from planner import plan_tour, PlanResult`` is the public API. It is loaded on first use (PEP 562), so
importing a light module such as uavcore.geodesy or planner.errors does not pull in numba and the solvers.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from planner.tour import METHODS, NoValidTourError, PlanResult, plan_tour

__all__ = ["METHODS", "NoValidTourError", "PlanResult", "plan_tour"]


def __getattr__(name: str):
    if name in __all__:
        from planner import tour

        return getattr(tour, name)
    raise AttributeError(f"module 'planner' has no attribute {name!r}")
