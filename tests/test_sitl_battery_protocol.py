"""The battery over MAVLink: the real vehicle process (`python -m sitl_quad`) and a pymavlink ground station.

One flight at 20x on a pack started at 20 % with raised thresholds (low 19 %, critical 18 %) and
COM_LOW_BAT_ACT 3, so the warnings and the return happen within a minute of simulated time: BATTERY_STATUS and
SYS_STATUS move as it flies, the low and critical texts arrive and the mission turns into a return; a swap is
refused in flight and armed, accepted landed and disarmed, and arming is refused on the spent pack until then.
"""

from __future__ import annotations

import time

import pytest
from sitl_process import WAIT_S, GroundStation, mission_item

from uavcore.geodesy import DEFAULT_HOME, LocalFrame
from uavcore.mavlink import mavlink
from uavcore.modes import FlightMode

pytestmark = pytest.mark.integration

MAV_CMD_BATTERY_RESET = 42651  # ardupilotmega.xml: param1 battery mask, param2 percentage
BATTERY_1 = 1
ARM = mavlink.MAV_CMD_COMPONENT_ARM_DISARM
ACCEPTED, DENIED = mavlink.MAV_RESULT_ACCEPTED, mavlink.MAV_RESULT_DENIED
TEMPORARILY_REJECTED = mavlink.MAV_RESULT_TEMPORARILY_REJECTED
VEHICLE_ARGS = (
    "--battery-percent",
    "20",
    *("--param", "BAT_LOW_THR=0.19"),
    *("--param", "BAT_CRIT_THR=0.18"),
    *("--param", "COM_LOW_BAT_ACT=3"),
)


def out_and_back_mission() -> list:
    """Take off to 10 m and fly 400 m north: still out there when the charge reaches the critical level."""
    lat, lon, _ = LocalFrame(*DEFAULT_HOME).from_ned(400.0, 0.0, 0.0)
    return [
        mission_item(0, mavlink.MAV_CMD_NAV_TAKEOFF, DEFAULT_HOME[0], DEFAULT_HOME[1], 10.0),
        mission_item(1, mavlink.MAV_CMD_NAV_WAYPOINT, float(lat), float(lon), 10.0),
    ]


def armed(m) -> bool:
    return bool(m.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED)


class NotingStation(GroundStation):
    """A ground station that keeps every STATUSTEXT and every mode a HEARTBEAT showed, whatever it was waiting
    for: at 20x a warning can arrive while the test waits for a command's acknowledgement."""

    def __init__(self, port: int) -> None:
        super().__init__(port)
        self.texts: list[tuple[int, str]] = []  # (severity, text)
        self.modes: list[FlightMode | None] = []

    def recv(self, kinds, timeout=5.0, condition=None):
        wanted = {kinds} if isinstance(kinds, str) else set(kinds)

        def note(m) -> bool:
            if m.get_type() == "STATUSTEXT":
                self.texts.append((m.severity, m.text))
            elif m.get_type() == "HEARTBEAT" and m.get_srcComponent() == 1:
                self.modes.append(FlightMode.from_custom_mode(m.custom_mode))
            return m.get_type() in wanted and (condition is None or condition(m))

        return super().recv(sorted(wanted | {"STATUSTEXT", "HEARTBEAT"}), timeout, note)

    def text_starting(self, prefix: str, timeout: float) -> tuple[int, str] | None:
        """The first STATUSTEXT (severity, text) seen starting with prefix, waiting up to timeout for it."""
        deadline = time.monotonic() + timeout
        while True:
            found = next((t for t in self.texts if t[1].startswith(prefix)), None)
            if found is not None or time.monotonic() > deadline:
                return found
            self.recv("STATUSTEXT", timeout=0.5)

    def saw_mode(self, mode: FlightMode, timeout: float) -> bool:
        deadline = time.monotonic() + timeout
        while mode not in self.modes and time.monotonic() < deadline:
            self.recv("HEARTBEAT", timeout=0.5)
        return mode in self.modes


def test_battery_status_warnings_return_and_swap_over_udp(start_sitl):
    vehicle = start_sitl(speed=20, extra_args=VEHICLE_ARGS)
    gcs = NotingStation(vehicle.port)
    try:
        gcs.connect()
        before = gcs.recv("BATTERY_STATUS", timeout=WAIT_S)
        assert before.battery_remaining == 20 and before.current_consumed == 0
        assert before.charge_state == mavlink.MAV_BATTERY_CHARGE_STATE_OK
        assert before.type == mavlink.MAV_BATTERY_TYPE_LIPO and before.voltages[4] == 65535  # a 4S pack

        assert gcs.upload_mission(out_and_back_mission()).type == mavlink.MAV_MISSION_ACCEPTED
        assert gcs.command(ARM, 1).result == ACCEPTED
        assert gcs.command(MAV_CMD_BATTERY_RESET, BATTERY_1, 100).result == DENIED  # armed
        assert gcs.command(mavlink.MAV_CMD_MISSION_START).result == ACCEPTED
        flying = gcs.recv("EXTENDED_SYS_STATE", timeout=WAIT_S, condition=lambda m: m.landed_state == 2)
        assert flying is not None
        assert gcs.command(MAV_CMD_BATTERY_RESET, BATTERY_1, 100).result == TEMPORARILY_REJECTED

        drawing = gcs.recv("BATTERY_STATUS", timeout=WAIT_S, condition=lambda m: m.current_consumed > 0)
        assert drawing is not None and drawing.current_battery > 500  # > 5 A in the air
        assert sum(drawing.voltages[:4]) < sum(before.voltages[:4])  # the pack sags under load
        status = gcs.recv("SYS_STATUS", timeout=WAIT_S)
        assert 12000 < status.voltage_battery < 17000 and status.current_battery > 500
        assert status.battery_remaining <= 20

        low = gcs.text_starting("Low battery level", timeout=2 * WAIT_S)
        assert low == (mavlink.MAV_SEVERITY_CRITICAL, "Low battery level! Return advised")
        critical = gcs.text_starting("Critical battery level", timeout=2 * WAIT_S)
        assert critical == (mavlink.MAV_SEVERITY_CRITICAL, "Critical battery level! Executing RTL")
        assert gcs.saw_mode(FlightMode.AUTO_RTL, timeout=WAIT_S)
        assert FlightMode.AUTO_MISSION in gcs.modes[: gcs.modes.index(FlightMode.AUTO_RTL)]
        state = gcs.recv("BATTERY_STATUS", timeout=WAIT_S)
        assert state.charge_state == mavlink.MAV_BATTERY_CHARGE_STATE_CRITICAL and state.battery_remaining <= 18

        landed = gcs.wait_heartbeat(lambda m: not armed(m), timeout=4 * WAIT_S)  # home, landed, disarmed
        assert landed is not None
        # as PX4, the disarm went back to the user's mode (Mission), out of the failsafe's Return
        back = gcs.wait_heartbeat(lambda m: FlightMode.from_custom_mode(m.custom_mode) != FlightMode.AUTO_RTL)
        assert back is not None and FlightMode.from_custom_mode(back.custom_mode) == FlightMode.AUTO_MISSION
        assert gcs.command(ARM, 1).result == DENIED  # below BAT_CRIT_THR
        assert gcs.text_starting("Arming denied: battery", timeout=WAIT_S) is not None
        assert gcs.command(MAV_CMD_BATTERY_RESET, 0, 100).result == DENIED  # no battery 1 in the mask
        assert gcs.command(MAV_CMD_BATTERY_RESET, BATTERY_1, 100).result == ACCEPTED
        fresh = gcs.recv("BATTERY_STATUS", timeout=WAIT_S, condition=lambda m: m.battery_remaining == 100)
        assert fresh is not None and fresh.current_consumed == 0
        assert fresh.charge_state == mavlink.MAV_BATTERY_CHARGE_STATE_OK
        # the fresh pack arms; in Hold, since arming in Mission would fly the mission again (and be off the ground
        # before a loaded machine's disarm arrives)
        hold = FlightMode.AUTO_LOITER
        assert gcs.set_mode(hold.value[0], hold.value[1]).result == ACCEPTED
        assert gcs.command(ARM, 1).result == ACCEPTED
        assert gcs.command(ARM, 0).result == ACCEPTED
    finally:
        gcs.close()
