"""Mission items as the vehicle stores them: MISSION_ITEM_INT's fields, verbatim, with no MAVLink objects.

The mission protocol module fills these from MISSION_ITEM_INT and serves them back unchanged on download;
the navigator reads them. Commands and frames are MAVLink's numbers.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

# MAV_CMD values the navigator flies
NAV_WAYPOINT = 16
NAV_LOITER_TIME = 19
NAV_RETURN_TO_LAUNCH = 20
NAV_LAND = 21
NAV_TAKEOFF = 22
DO_CHANGE_SPEED = 178
SUPPORTED_COMMANDS = frozenset(
    {NAV_WAYPOINT, NAV_LOITER_TIME, NAV_RETURN_TO_LAUNCH, NAV_LAND, NAV_TAKEOFF, DO_CHANGE_SPEED}
)

# MAV_FRAME values accepted for positions
FRAME_GLOBAL = 0  # altitude AMSL, lat/lon as float degrees (MISSION_ITEM)
FRAME_GLOBAL_RELATIVE_ALT = 3
FRAME_MISSION = 2  # for DO_ commands without a position
FRAME_GLOBAL_INT = 5  # altitude AMSL, lat/lon as degE7
FRAME_GLOBAL_RELATIVE_ALT_INT = 6  # altitude above home, lat/lon as degE7
SUPPORTED_FRAMES = frozenset(
    {FRAME_GLOBAL, FRAME_GLOBAL_RELATIVE_ALT, FRAME_MISSION, FRAME_GLOBAL_INT, FRAME_GLOBAL_RELATIVE_ALT_INT}
)


@dataclass(frozen=True)
class MissionItem:
    """One MISSION_ITEM_INT. x/y are lat/lon in degE7, z is altitude in metres (frame: relative to what)."""

    seq: int
    frame: int
    command: int
    current: int = 0
    autocontinue: int = 1
    param1: float = math.nan
    param2: float = math.nan
    param3: float = math.nan
    param4: float = math.nan
    x: int = 0
    y: int = 0
    z: float = 0.0
    mission_type: int = 0

    @property
    def lat(self) -> float:
        return self.x * 1e-7

    @property
    def lon(self) -> float:
        return self.y * 1e-7

    @property
    def has_position(self) -> bool:
        """Whether the item names a place (lat/lon 0,0 means "here" for takeoff/land/RTL, as in PX4)."""
        return self.command in (NAV_WAYPOINT, NAV_LOITER_TIME, NAV_TAKEOFF, NAV_LAND) and (self.x != 0 or self.y != 0)
