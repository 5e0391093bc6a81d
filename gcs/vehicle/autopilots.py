"""Autopilot flavours behind one interface (QGroundControl calls them firmware plugins): PX4 and ArduPilot Copter.

What differs between them and is handled here, so the ground station's mission logic holds no MAVLink numbers:
- flight-mode encoding (PX4: main/sub modes in custom_mode; ArduPilot Copter: a plain mode number);
- the mission as stored on the vehicle (ArduPilot's item 0 is home and is overwritten by the vehicle, so the
  planned items move up by one; PX4 stores them as they are);
- how a mission starts (PX4: AUTO.MISSION mode, or MAV_CMD_MISSION_START; ArduPilot: a takeoff in GUIDED, then
  AUTO with MAV_CMD_MISSION_START) and how the vehicle is sent home;
- how telemetry rates are asked for (SET_MESSAGE_INTERVAL; ArduPilot also understands REQUEST_DATA_STREAM);
- how an integer parameter travels in PARAM_VALUE's float (PX4: its bytes; ArduPilot: its value cast to float).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import ClassVar

from uavcore.mavlink import mavlink
from uavcore.mission import MavCmd, MavFrame, MissionItem
from uavcore.modes import FlightMode, Px4AutoSubMode, Px4MainMode, px4_custom_mode, px4_mode_name

CUSTOM_MODE_ENABLED = mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
# The two ways an autopilot puts an integer parameter into PARAM_VALUE.param_value (a float), as its
# AUTOPILOT_VERSION.capabilities announce them: the integer's bytes copied into the float's four, or the integer
# converted to a float (exact up to 2**24).
PARAM_ENCODE_BYTEWISE = mavlink.MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE
PARAM_ENCODE_C_CAST = mavlink.MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_C_CAST


class Autopilot:
    """What one autopilot flavour needs the link to do differently. Subclasses fill the class attributes."""

    name = "generic"
    mission_offset = 0  # planned item k is stored as item k + mission_offset
    takes_off_before_mission = False
    streams_by_data_stream_request = False
    param_encoding = PARAM_ENCODE_C_CAST  # PARAM_ENCODE_BYTEWISE or PARAM_ENCODE_C_CAST

    def mode_name(self, custom_mode: int) -> str:
        return f"custom {custom_mode}"

    def custom_mode(self, purpose: str) -> int:
        """The custom_mode for one of: "mission", "return", "land", "hold", "guided"."""
        raise NotImplementedError

    def is_mode(self, custom_mode: int, purpose: str) -> bool:
        return custom_mode == self.custom_mode(purpose)

    def items_for_vehicle(self, items: Sequence[MissionItem], home: tuple[float, float, float]) -> list[MissionItem]:
        """The planned items as this autopilot stores them."""
        return list(items)

    def items_from_vehicle(self, items: Sequence[MissionItem]) -> list[MissionItem]:
        """The vehicle's stored mission in the planned numbering (inverse of `items_for_vehicle`)."""
        return list(items)

    def planned_seq(self, vehicle_seq: int) -> int:
        return vehicle_seq - self.mission_offset


class Px4(Autopilot):
    name = "PX4"
    param_encoding = PARAM_ENCODE_BYTEWISE  # PX4's mavlink_parameters.cpp copies an INT32's bytes into the float
    _modes: ClassVar[dict[str, tuple[int, int]]] = {
        "mission": (Px4MainMode.AUTO, Px4AutoSubMode.MISSION),
        "return": (Px4MainMode.AUTO, Px4AutoSubMode.RTL),
        "land": (Px4MainMode.AUTO, Px4AutoSubMode.LAND),
        "hold": (Px4MainMode.AUTO, Px4AutoSubMode.LOITER),
        "guided": (Px4MainMode.AUTO, Px4AutoSubMode.LOITER),
    }

    def mode_name(self, custom_mode: int) -> str:
        return px4_mode_name(custom_mode)

    def custom_mode(self, purpose: str) -> int:
        return px4_custom_mode(*self._modes[purpose])

    def is_mode(self, custom_mode: int, purpose: str) -> bool:
        if purpose == "mission":  # PX4 flies a mission's takeoff in AUTO.TAKEOFF, and OFFBOARD keeps sequencing it
            return FlightMode.from_custom_mode(custom_mode) in (FlightMode.AUTO_MISSION, FlightMode.AUTO_TAKEOFF)
        return custom_mode == self.custom_mode(purpose)


class ArduCopter(Autopilot):
    """ArduPilot Copter (mode numbers from ArduCopter/mode.h)."""

    name = "ArduPilot"
    mission_offset = 1
    takes_off_before_mission = True
    streams_by_data_stream_request = True
    param_encoding = PARAM_ENCODE_C_CAST  # ArduPilot sends every parameter's value as a float number
    MODES: ClassVar[dict[int, str]] = {
        0: "STABILIZE",
        1: "ACRO",
        2: "ALT_HOLD",
        3: "AUTO",
        4: "GUIDED",
        5: "LOITER",
        6: "RTL",
        7: "CIRCLE",
        9: "LAND",
        16: "POSHOLD",
        17: "BRAKE",
        21: "SMART_RTL",
    }
    _purposes: ClassVar[dict[str, int]] = {"mission": 3, "guided": 4, "hold": 5, "return": 6, "land": 9}

    def mode_name(self, custom_mode: int) -> str:
        return self.MODES.get(custom_mode, f"mode {custom_mode}")

    def custom_mode(self, purpose: str) -> int:
        return self._purposes[purpose]

    def items_for_vehicle(self, items: Sequence[MissionItem], home: tuple[float, float, float]) -> list[MissionItem]:
        lat, lon, alt = home
        home_item = MissionItem(
            seq=0,
            frame=MavFrame.GLOBAL,
            command=MavCmd.NAV_WAYPOINT,
            param1=0.0,
            param2=0.0,
            param3=0.0,
            param4=0.0,
            x=round(lat * 1e7),
            y=round(lon * 1e7),
            z=alt,
        )
        return [home_item, *(dataclasses.replace(item, seq=item.seq + 1, current=0) for item in items)]

    def items_from_vehicle(self, items: Sequence[MissionItem]) -> list[MissionItem]:
        return [dataclasses.replace(item, seq=item.seq - 1) for item in items[1:]]


def autopilot_for(mav_autopilot: int) -> Autopilot:
    """The flavour for HEARTBEAT.autopilot (MAV_AUTOPILOT); anything not ArduPilot is spoken to as PX4."""
    if mav_autopilot == mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA:
        return ArduCopter()
    return Px4()
