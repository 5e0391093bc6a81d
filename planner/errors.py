"""The planner's typed errors: callers catch these, never a bare exception."""


class PlannerError(Exception):
    """Base class of every error the planner raises on purpose."""


class InputError(PlannerError, ValueError):
    """The buoys, depot or file given to the planner are unusable (the message says why)."""


class TooLargeError(PlannerError, ValueError):
    """The instance has more nodes than the chosen method accepts (e.g. Held-Karp beyond 16)."""


class UnreachableBuoyError(PlannerError, ValueError):
    """A buoy that no sortie can serve: flying to it alone and back needs more than one battery's usable energy.

    ``buoys`` lists every such node (depot = 0), ``shortfall_wh[k]`` and ``shortfall_pct[k]`` how much energy
    buoys[k] lacks, in Wh and in % of the usable budget. The service answers it with a 422."""

    def __init__(self, buoys: list[int], needed_wh: list[float], budget_wh: float) -> None:
        self.buoys = list(buoys)
        self.budget_wh = float(budget_wh)
        self.shortfall_wh = [float(need - budget_wh) for need in needed_wh]
        self.shortfall_pct = [100.0 * short / budget_wh for short in self.shortfall_wh]
        named = ", ".join(
            f"buoy {b} (needs {need:.1f} Wh, short by {short:.1f} Wh = {pct:.1f} %)"
            for b, need, short, pct in list(
                zip(self.buoys, needed_wh, self.shortfall_wh, self.shortfall_pct, strict=True)
            )[:5]
        )
        if len(self.buoys) > 5:
            named += f" and {len(self.buoys) - 5} more buoys"
        super().__init__(
            f"cannot reach and return from {named} within the usable {budget_wh:.1f} Wh of one battery, even alone"
        )
