"""The planner's typed errors: callers catch these, never a bare exception."""


class PlannerError(Exception):
    """Base class of every error the planner raises on purpose."""


class InputError(PlannerError, ValueError):
    """The buoys, depot or file given to the planner are unusable (the message says why)."""


class TooLargeError(PlannerError, ValueError):
    """The instance has more nodes than the chosen method accepts (e.g. Held-Karp beyond 16)."""
