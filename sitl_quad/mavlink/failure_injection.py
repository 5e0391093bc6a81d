"""MAV_CMD_INJECT_FAILURE over MAVLink (MAVSDK's Failure plugin, PX4's `failure` shell command), and the data link
as the vehicle hears it: no ground-station HEARTBEAT for COM_DL_LOSS_T -> NAV_DLL_ACT (PX4's commander).

What a failure does is the vehicle's business (sitl_quad.failure_injection, sitl_quad.vehicle); this module only
carries the command and, for FAILURE_UNIT_SYSTEM_MAVLINK_SIGNAL, silences the link: from the loop pass after the
COMMAND_ACK (so the injecting client learns it was accepted), nothing is sent and every message is ignored except
MAV_CMD_INJECT_FAILURE(MAVLINK_SIGNAL, OK), which stands in for PX4's shell (`failure mavlink_signal ok`) since
this vehicle has no other console. Ground-station silence is measured on the wall clock, as heartbeats are sent
on it whatever the simulation's speed.
"""

from __future__ import annotations

import time

from sitl_quad.failure_injection import FailureType, FailureUnit
from sitl_quad.mavlink.commands import Commands
from sitl_quad.mavlink.link import UdpLink
from sitl_quad.vehicle import CommandResult, Vehicle
from uavcore.mavlink import mavlink


def restores_signal(msg) -> bool:
    """The one message a failed MAVLink signal still hears: the command that restores it."""
    return (
        msg.get_type() in ("COMMAND_LONG", "COMMAND_INT")
        and msg.command == mavlink.MAV_CMD_INJECT_FAILURE
        and int(msg.param1) == FailureUnit.SYSTEM_MAVLINK_SIGNAL
        and int(msg.param2) == FailureType.OK
    )


class FailureInjection:
    def __init__(self, vehicle: Vehicle, link: UdpLink, commands: Commands) -> None:
        self.vehicle = vehicle
        self.link = link
        commands.register(mavlink.MAV_CMD_INJECT_FAILURE, self.inject)
        self._last_gcs_heartbeat: float | None = None  # wall clock; None until a ground station has been heard
        self._loss_reported = False

    def inject(self, p: tuple) -> CommandResult:
        """The vehicle's answer; a restored signal speaks at once, so this very COMMAND_ACK is heard (a failed one
        falls silent at the next loop pass, after its ACK)."""
        result = self.vehicle.inject_failure(p[0], p[1], p[2])
        if not self.vehicle.failures.mavlink_off:
            self.link.signal_failed = None
        return result

    def handlers(self) -> dict:
        return {"HEARTBEAT": self.heartbeat}

    def heartbeat(self, peer, msg) -> None:
        if msg.type == mavlink.MAV_TYPE_GCS:
            self._last_gcs_heartbeat = time.monotonic()
            self._loss_reported = False

    def poll(self, now: float) -> None:
        """Each loop pass (wall clock): follow the MAVLink signal failure; act on a ground station gone quiet."""
        failed = self.vehicle.failures.mavlink_off
        if failed != (self.link.signal_failed is not None):
            self.link.signal_failed = restores_signal if failed else None
        if self._last_gcs_heartbeat is None or self._loss_reported:
            return
        silent_s = now - self._last_gcs_heartbeat
        if silent_s >= self.vehicle.config.failsafe.data_link_loss_timeout_s:
            self._loss_reported = True
            self.vehicle.data_link_lost(silent_s)
