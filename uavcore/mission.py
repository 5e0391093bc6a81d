"""Mission items as MISSION_ITEM_INT carries them: MAVLink's fields, verbatim, with no MAVLink objects.

The vehicle's mission protocol fills these from MISSION_ITEM_INT and serves them back unchanged on download;
its navigator reads them; the ground station builds them from a plan. `uavcore.mavlink` converts them to and
from the wire. Commands and frames are MAVLink's numbers, named by the enums below (IntEnum, so an item read
off the wire compares equal to its enum member).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from enum import IntEnum


class MavCmd(IntEnum):
    """The MAV_CMD values this project's missions use (MAVLink common.xml numbers)."""

    NAV_WAYPOINT = 16
    NAV_LOITER_TIME = 19
    NAV_RETURN_TO_LAUNCH = 20
    NAV_LAND = 21
    NAV_TAKEOFF = 22
    DO_ORBIT = 34
    DO_CHANGE_SPEED = 178
    DO_REPOSITION = 192
    DO_SET_ROI_LOCATION = 195
    DO_SET_ROI_NONE = 197
    DO_GIMBAL_MANAGER_PITCHYAW = 1000
    IMAGE_START_CAPTURE = 2000
    IMAGE_STOP_CAPTURE = 2001
    NAV_FENCE_RETURN_POINT = 5000
    NAV_FENCE_POLYGON_VERTEX_INCLUSION = 5001  # param1: the polygon's vertex count
    NAV_FENCE_POLYGON_VERTEX_EXCLUSION = 5002  # param1: the polygon's vertex count
    NAV_FENCE_CIRCLE_INCLUSION = 5003  # param1: radius, m
    NAV_FENCE_CIRCLE_EXCLUSION = 5004  # param1: radius, m
    NAV_RALLY_POINT = 5100


class MavFrame(IntEnum):
    """MAV_FRAME values for mission positions and offboard setpoints."""

    GLOBAL = 0  # altitude AMSL, lat/lon as float degrees (legacy MISSION_ITEM)
    LOCAL_NED = 1  # metres from the local origin (home), north-east-down
    MISSION = 2  # for DO_ commands without a position
    GLOBAL_RELATIVE_ALT = 3
    GLOBAL_INT = 5  # altitude AMSL, lat/lon as degE7
    GLOBAL_RELATIVE_ALT_INT = 6  # altitude above home, lat/lon as degE7
    LOCAL_OFFSET_NED = 7  # north-east-down, relative to the vehicle's position
    BODY_NED = 8  # velocity/acceleration along the vehicle's heading (forward, right, down); position as LOCAL_NED
    BODY_OFFSET_NED = 9  # as BODY_NED, position relative to the vehicle along its heading


class MissionType(IntEnum):
    """MAV_MISSION_TYPE: the three lists a vehicle stores."""

    MISSION = 0
    FENCE = 1
    RALLY = 2


# DO_ items for the camera and its gimbal: the vehicle hands them to the payload when the mission reaches them
PAYLOAD_COMMANDS = frozenset(
    {
        MavCmd.DO_SET_ROI_LOCATION,
        MavCmd.DO_SET_ROI_NONE,
        MavCmd.DO_GIMBAL_MANAGER_PITCHYAW,
        MavCmd.IMAGE_START_CAPTURE,
        MavCmd.IMAGE_STOP_CAPTURE,
    }
)
# Mission commands whose x / y / z are not a place (MISSION_ITEM_INT's params 5-7 used otherwise, or unused)
UNPLACED_COMMANDS = PAYLOAD_COMMANDS - {MavCmd.DO_SET_ROI_LOCATION} | {MavCmd.DO_CHANGE_SPEED}

# What each list may hold: the flight plan's commands, the fence's shapes, the rally points
MISSION_COMMANDS = frozenset(
    {
        MavCmd.NAV_WAYPOINT,
        MavCmd.NAV_LOITER_TIME,
        MavCmd.NAV_RETURN_TO_LAUNCH,
        MavCmd.NAV_LAND,
        MavCmd.NAV_TAKEOFF,
        MavCmd.DO_CHANGE_SPEED,
        *PAYLOAD_COMMANDS,
    }
)
FENCE_COMMANDS = frozenset(
    {
        MavCmd.NAV_FENCE_RETURN_POINT,
        MavCmd.NAV_FENCE_POLYGON_VERTEX_INCLUSION,
        MavCmd.NAV_FENCE_POLYGON_VERTEX_EXCLUSION,
        MavCmd.NAV_FENCE_CIRCLE_INCLUSION,
        MavCmd.NAV_FENCE_CIRCLE_EXCLUSION,
    }
)
RALLY_COMMANDS = frozenset({MavCmd.NAV_RALLY_POINT})
COMMANDS_OF_TYPE = {
    MissionType.MISSION: MISSION_COMMANDS,
    MissionType.FENCE: FENCE_COMMANDS,
    MissionType.RALLY: RALLY_COMMANDS,
}
# Frames a stored item's position may be given in (latitude/longitude, altitude AMSL or above home)
GLOBAL_FRAMES = frozenset(
    {MavFrame.GLOBAL, MavFrame.GLOBAL_RELATIVE_ALT, MavFrame.GLOBAL_INT, MavFrame.GLOBAL_RELATIVE_ALT_INT}
)
ITEM_FRAMES = GLOBAL_FRAMES | {MavFrame.MISSION}

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


def rally_point_items(points: Sequence[tuple[float, float, float]]) -> list[MissionItem]:
    """The MISSION_TYPE_RALLY list of rally points (latitude, longitude degrees, altitude above home metres): one
    MAV_CMD_NAV_RALLY_POINT each, in MAV_FRAME_GLOBAL_RELATIVE_ALT_INT (PX4's RTL goes to the nearest one, or
    home, whichever is closer: RTL_TYPE 0)."""
    return [
        MissionItem(
            seq=seq,
            frame=MavFrame.GLOBAL_RELATIVE_ALT_INT,
            command=MavCmd.NAV_RALLY_POINT,
            x=round(lat * 1e7),
            y=round(lon * 1e7),
            z=float(alt_m),
            mission_type=MissionType.RALLY,
        )
        for seq, (lat, lon, alt_m) in enumerate(points)
    ]
