"""COMMAND_LONG / COMMAND_INT and the SET_MODE message: every command gets a COMMAND_ACK.

Handlers are registered per MAV_CMD by the capability that owns them (telemetry registers
REQUEST_MESSAGE, the vehicle's actions register arming and modes); anything else is UNSUPPORTED.
"""

from __future__ import annotations

import functools
import logging
import math
from collections.abc import Callable
from dataclasses import dataclass

from sitl_quad.vehicle import FORCE_DISARM_MAGIC, CommandResult, Vehicle
from uavcore.mavlink import MAV_CMD_BATTERY_RESET, mavlink
from uavcore.modes import FlightMode

log = logging.getLogger(__name__)

# handler(params: tuple of 7 floats) -> CommandResult
POSITIONAL_COMMANDS = {
    mavlink.MAV_CMD_DO_REPOSITION,
    mavlink.MAV_CMD_DO_ORBIT,
    mavlink.MAV_CMD_NAV_TAKEOFF,
    mavlink.MAV_CMD_NAV_LAND,
    mavlink.MAV_CMD_DO_SET_ROI_LOCATION,
}
INT32_MAX = 2**31 - 1  # COMMAND_INT's "unused" x / y
CommandHandler = Callable[[tuple], CommandResult]


@dataclass(frozen=True)
class CommandSource:
    """Who sent a command: for handlers whose answer depends on the sender (the gimbal manager obeys the client
    in control only)."""

    sysid: int
    compid: int


SourcedHandler = Callable[..., CommandResult]  # handler(params, source=CommandSource)


class Commands:
    def __init__(self, vehicle: Vehicle, send) -> None:
        self.vehicle = vehicle
        self.send = send  # callable(msg, peer=None)
        # callable(): publish what the command changed (the server's events: HEARTBEAT, STATUSTEXT) before its
        # COMMAND_ACK, so a client that acts on the ACK never gets the old state afterwards. MAVSDK's offboard
        # plugin stops streaming setpoints on a non-OFFBOARD heartbeat; one arriving just after the ARM ack,
        # while the example sets its first setpoint, made offboard.start() fail with NO_SETPOINT_SET.
        self.before_ack = lambda: None
        self.table: dict[int, CommandHandler] = {
            mavlink.MAV_CMD_COMPONENT_ARM_DISARM: self.arm_disarm,
            mavlink.MAV_CMD_DO_SET_MODE: self.do_set_mode,
            mavlink.MAV_CMD_MISSION_START: self.mission_start,
            mavlink.MAV_CMD_NAV_TAKEOFF: self.takeoff,
            mavlink.MAV_CMD_NAV_LAND: lambda p: self.vehicle.set_mode(FlightMode.AUTO_LAND),
            mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH: lambda p: self.vehicle.set_mode(FlightMode.AUTO_RTL),
            mavlink.MAV_CMD_DO_SET_MISSION_CURRENT: self.set_mission_current,
            mavlink.MAV_CMD_NAV_LOITER_UNLIM: lambda p: self.vehicle.set_mode(FlightMode.AUTO_LOITER),
            mavlink.MAV_CMD_DO_CHANGE_SPEED: lambda p: self.vehicle.change_speed(p[1]),
            mavlink.MAV_CMD_DO_REPOSITION: self.reposition,
            mavlink.MAV_CMD_DO_ORBIT: self.orbit,
            MAV_CMD_BATTERY_RESET: self.battery_reset,
        }
        self.sourced: dict[int, SourcedHandler] = {}

    def register(self, command: int, handler: CommandHandler) -> None:
        self.table[command] = handler

    def register_sourced(self, command: int, handler: SourcedHandler) -> None:
        """A handler that is also told who sent the command (CommandSource)."""
        self.sourced[command] = handler

    def handlers(self) -> dict:
        return {"COMMAND_LONG": self.command_long, "COMMAND_INT": self.command_int, "SET_MODE": self.set_mode_msg}

    def command_long(self, peer, msg) -> None:
        params = (msg.param1, msg.param2, msg.param3, msg.param4, msg.param5, msg.param6, msg.param7)
        self._run(peer, msg, params)

    def command_int(self, peer, msg) -> None:
        # x, y are degE7 in a COMMAND_INT: positional commands get degrees, like COMMAND_LONG's param5/6. z is
        # passed on as it comes, whatever the frame says, as PX4's receiver does: MAVSDK sends DO_ORBIT's AMSL
        # altitude in a COMMAND_INT whose frame is its default, GLOBAL_RELATIVE_ALT_INT.
        if msg.command in POSITIONAL_COMMANDS:
            x = msg.x * 1e-7 if msg.x != INT32_MAX else math.nan
            y = msg.y * 1e-7 if msg.y != INT32_MAX else math.nan
        else:
            x, y = float(msg.x), float(msg.y)
        params = (msg.param1, msg.param2, msg.param3, msg.param4, x, y, msg.z)
        self._run(peer, msg, params)

    def _run(self, peer, msg, params: tuple) -> None:
        handler = self.table.get(msg.command)
        sourced = self.sourced.get(msg.command)
        if sourced is not None:
            handler = functools.partial(sourced, source=CommandSource(msg.get_srcSystem(), msg.get_srcComponent()))
        if handler is None:
            result = CommandResult.UNSUPPORTED
        else:
            try:
                result = handler(params)
            except (ValueError, OverflowError) as exc:  # a NaN or absurd number where one was required
                log.info("command %d refused: %s", msg.command, exc)
                result = CommandResult.DENIED
        self.before_ack()
        ack = mavlink.MAVLink_command_ack_message(
            msg.command, int(result), 0, 0, msg.get_srcSystem(), msg.get_srcComponent()
        )
        self.send(ack, peer)

    # ----- handlers
    def arm_disarm(self, p: tuple) -> CommandResult:
        if p[0] == 1:
            return self.vehicle.arm()
        if p[0] == 0:
            return self.vehicle.disarm(force=p[1] == FORCE_DISARM_MAGIC)
        return CommandResult.DENIED

    def do_set_mode(self, p: tuple) -> CommandResult:
        base_mode, main, sub = p[0], p[1], p[2]
        if not (math.isfinite(base_mode) and int(base_mode) & mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED):
            return CommandResult.DENIED  # only PX4 custom modes are meaningful here
        if not math.isfinite(main):
            return CommandResult.DENIED
        mode = FlightMode.from_main_sub(int(main), int(sub) if math.isfinite(sub) else 0)
        if mode is None:
            return CommandResult.UNSUPPORTED
        return self.vehicle.set_mode(mode)

    def set_mode_msg(self, peer, msg) -> None:
        """SET_MODE (#11), QGroundControl's way for PX4: no acknowledgement exists for it."""
        if msg.target_system != self.vehicle_sysid:
            return
        mode = FlightMode.from_custom_mode(msg.custom_mode)
        if mode is not None:
            self.vehicle.set_mode(mode)

    vehicle_sysid = 1

    def mission_start(self, p: tuple) -> CommandResult:
        first = int(p[0]) if math.isfinite(p[0]) and p[0] > 0 else None
        return self.vehicle.start_mission(first)

    def takeoff(self, p: tuple) -> CommandResult:
        altitude = p[6] if math.isfinite(p[6]) and p[6] > 0 else None
        if altitude is not None:
            altitude -= self.vehicle.home[2]  # param7 is AMSL; the navigator wants height above home
            if altitude <= 0:
                altitude = None
        return self.vehicle.takeoff(altitude)

    def reposition(self, p: tuple) -> CommandResult:
        return self.vehicle.reposition(p[4], p[5], p[6], math.radians(p[3]) if math.isfinite(p[3]) else math.nan)

    def orbit(self, p: tuple) -> CommandResult:
        """DO_ORBIT: radius, velocity, yaw behaviour, (orbits: not limited here), centre lat/lon, altitude AMSL."""
        return self.vehicle.orbit(p[0], p[1], p[2], p[4], p[5], p[6])

    def set_mission_current(self, p: tuple) -> CommandResult:
        if not math.isfinite(p[0]):
            return CommandResult.DENIED
        return CommandResult.ACCEPTED if self.vehicle.set_current_item(int(p[0])) else CommandResult.DENIED

    def battery_reset(self, p: tuple) -> CommandResult:
        """MAV_CMD_BATTERY_RESET: a new pack at param2 percent, for battery 1 (bit 0 of the mask param1)."""
        mask, percent = p[0], p[1]
        if not (math.isfinite(mask) and int(mask) & 1 and math.isfinite(percent) and 0 <= percent <= 100):
            return CommandResult.DENIED
        return self.vehicle.replace_battery(percent / 100.0)
