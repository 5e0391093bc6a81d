"""Route planner: CHNN-GA (paper Section V) with Held-Karp as the exact oracle. Pure computation."""

from planner.api import METHODS, NoValidTourError, PlanResult, plan_tour

__all__ = ["METHODS", "NoValidTourError", "PlanResult", "plan_tour"]
