"""Flight modes in PX4's encoding: HEARTBEAT.custom_mode = (sub_mode << 24) | (main_mode << 16)."""

from __future__ import annotations

from enum import Enum


class FlightMode(Enum):
    """(main_mode, sub_mode) as PX4 numbers them."""

    POSCTL = (3, 0)
    AUTO_READY = (4, 1)
    AUTO_TAKEOFF = (4, 2)
    AUTO_LOITER = (4, 3)
    AUTO_MISSION = (4, 4)
    AUTO_RTL = (4, 5)
    AUTO_LAND = (4, 6)
    OFFBOARD = (6, 0)

    @property
    def custom_mode(self) -> int:
        main, sub = self.value
        return (sub << 24) | (main << 16)

    @property
    def label(self) -> str:
        return self.name.replace("_", ".", 1) if self.name.startswith("AUTO_") else self.name

    @classmethod
    def from_main_sub(cls, main: int, sub: int) -> FlightMode | None:
        """The mode for PX4 numbers, or None if this vehicle does not fly it (e.g. MANUAL: no RC here)."""
        for mode in cls:
            if mode.value == (main, sub):
                return mode
        if main == 4 and sub == 0:  # "AUTO" with no sub mode: PX4 treats it as mission
            return cls.AUTO_MISSION
        if main == 3:
            return cls.POSCTL
        return None

    @classmethod
    def from_custom_mode(cls, custom_mode: int) -> FlightMode | None:
        return cls.from_main_sub((custom_mode >> 16) & 0xFF, (custom_mode >> 24) & 0xFF)
