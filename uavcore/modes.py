"""Autopilot flight modes in PX4's encoding: HEARTBEAT.custom_mode = (sub_mode << 24) | (main_mode << 16).

`FlightMode` names the modes this project's vehicle flies; `px4_mode_name` names any PX4 mode for display.
"""

from __future__ import annotations

from enum import Enum, IntEnum


class Px4MainMode(IntEnum):
    """PX4_CUSTOM_MAIN_MODE (px4_custom_mode.h)."""

    MANUAL = 1
    ALTCTL = 2
    POSCTL = 3
    AUTO = 4
    ACRO = 5
    OFFBOARD = 6
    STABILIZED = 7


class Px4AutoSubMode(IntEnum):
    """PX4_CUSTOM_SUB_MODE_AUTO: the sub mode under main mode AUTO."""

    READY = 1
    TAKEOFF = 2
    LOITER = 3
    MISSION = 4
    RTL = 5
    LAND = 6


class Px4PosctlSubMode(IntEnum):
    """PX4_CUSTOM_SUB_MODE_POSCTL: the sub mode under main mode POSCTL (orbit is one, as PX4 reports it)."""

    POSCTL = 0
    ORBIT = 1


def px4_custom_mode(main: int, sub: int = 0) -> int:
    """HEARTBEAT / SET_MODE custom_mode for PX4 main and sub mode numbers."""
    return (sub << 24) | (main << 16)


def px4_main_sub(custom_mode: int) -> tuple[int, int]:
    """(main_mode, sub_mode) of a PX4 custom_mode."""
    return (custom_mode >> 16) & 0xFF, (custom_mode >> 24) & 0xFF


def px4_mode_name(custom_mode: int) -> str:
    """A PX4 custom_mode as QGroundControl shows it ("AUTO.MISSION", "OFFBOARD", ...)."""
    main, sub = px4_main_sub(custom_mode)
    try:
        main_name = Px4MainMode(main).name
    except ValueError:
        return f"main {main} sub {sub}"
    if main == Px4MainMode.POSCTL and sub == Px4PosctlSubMode.ORBIT:
        return "POSCTL.ORBIT"
    if main != Px4MainMode.AUTO:
        return main_name if sub == 0 else f"{main_name} sub {sub}"
    try:
        return f"AUTO.{Px4AutoSubMode(sub).name}"
    except ValueError:
        return f"AUTO sub {sub}"


class FlightMode(Enum):
    """The modes this project's vehicle flies, as (main_mode, sub_mode) PX4 numbers."""

    POSCTL = (Px4MainMode.POSCTL, 0)
    ORBIT = (Px4MainMode.POSCTL, Px4PosctlSubMode.ORBIT)
    AUTO_READY = (Px4MainMode.AUTO, Px4AutoSubMode.READY)
    AUTO_TAKEOFF = (Px4MainMode.AUTO, Px4AutoSubMode.TAKEOFF)
    AUTO_LOITER = (Px4MainMode.AUTO, Px4AutoSubMode.LOITER)
    AUTO_MISSION = (Px4MainMode.AUTO, Px4AutoSubMode.MISSION)
    AUTO_RTL = (Px4MainMode.AUTO, Px4AutoSubMode.RTL)
    AUTO_LAND = (Px4MainMode.AUTO, Px4AutoSubMode.LAND)
    OFFBOARD = (Px4MainMode.OFFBOARD, 0)

    @property
    def custom_mode(self) -> int:
        return px4_custom_mode(*self.value)

    @property
    def label(self) -> str:
        return px4_mode_name(self.custom_mode)

    @classmethod
    def from_main_sub(cls, main: int, sub: int) -> FlightMode | None:
        """The mode for PX4 numbers, or None if this vehicle does not fly it (e.g. MANUAL: no RC here)."""
        for mode in cls:
            if mode.value == (main, sub):
                return mode
        if main == Px4MainMode.AUTO and sub == 0:  # "AUTO" with no sub mode: PX4 treats it as mission
            return cls.AUTO_MISSION
        if main == Px4MainMode.POSCTL:
            return cls.POSCTL
        return None

    @classmethod
    def from_custom_mode(cls, custom_mode: int) -> FlightMode | None:
        return cls.from_main_sub(*px4_main_sub(custom_mode))
