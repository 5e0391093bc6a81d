"""Mission items as MISSION_ITEM_INT carries them: MAVLink's fields, verbatim, with no MAVLink objects.

The vehicle's mission protocol fills these from MISSION_ITEM_INT and serves them back unchanged on download;
its navigator reads them; the ground station builds them from a plan. `uavcore.mavlink` converts them to and
from the wire. Commands and frames are MAVLink's numbers, named by the enums below (IntEnum, so an item read
off the wire compares equal to its enum member).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import IntEnum


class MavCmd(IntEnum):
    """The MAV_CMD values this project's missions use (MAVLink common.xml numbers)."""

    NAV_WAYPOINT = 16
    NAV_LOITER_TIME = 19
    NAV_RETURN_TO_LAUNCH = 20
    NAV_LAND = 21
    NAV_TAKEOFF = 22
    DO_CHANGE_SPEED = 178


class MavFrame(IntEnum):
    """MAV_FRAME values for mission positions."""

    GLOBAL = 0  # altitude AMSL, lat/lon as float degrees (legacy MISSION_ITEM)
    MISSION = 2  # for DO_ commands without a position
    GLOBAL_RELATIVE_ALT = 3
    GLOBAL_INT = 5  # altitude AMSL, lat/lon as degE7
    GLOBAL_RELATIVE_ALT_INT = 6  # altitude above home, lat/lon as degE7


class MissionType(IntEnum):
    """MAV_MISSION_TYPE: the three lists a vehicle stores."""

    MISSION = 0
    FENCE = 1
    RALLY = 2


# Commands that name a place (lat/lon 0,0 means "here" for takeoff/land, as in PX4)
POSITION_COMMANDS = frozenset({MavCmd.NAV_WAYPOINT, MavCmd.NAV_LOITER_TIME, MavCmd.NAV_TAKEOFF, MavCmd.NAV_LAND})


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
    mission_type: int = MissionType.MISSION

    @property
    def lat(self) -> float:
        return self.x * 1e-7

    @property
    def lon(self) -> float:
        return self.y * 1e-7

    @property
    def has_position(self) -> bool:
        """Whether the item names a place (lat/lon 0,0 means "here" for takeoff/land/RTL, as in PX4)."""
        return self.command in POSITION_COMMANDS and (self.x != 0 or self.y != 0)
