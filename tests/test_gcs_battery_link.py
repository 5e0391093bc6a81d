"""The ground station's link reads the battery, swaps it and reads parameters, against the real vehicle process.

`python -m sitl_quad` on loopback UDP and a `LinkManager` connected to it, as the service runs them: the first
battery's state folded into `VehicleStatus` from BATTERY_STATUS, MAV_CMD_BATTERY_RESET accepted on the ground
and refused in the air with the link's typed error, and parameters read by name with PX4's bytewise integers.
ArduPilot's side (its battery in SYS_STATUS, integers cast to float) is a small scripted autopilot on real UDP:
no ArduPilot SITL can be installed here.
"""

from __future__ import annotations

import asyncio
import contextlib
import socket
import threading
import time
from collections.abc import AsyncIterator, Callable

import pytest
from sitl_process import WAIT_S

from bench.processes import free_udp_port
from gcs.vehicle.link import CommandDeniedError, LinkManager
from gcs.vehicle.parameters import ParameterError
from uavcore.mavlink import Encoder, mavlink, new_parser, parse_datagram

pytestmark = pytest.mark.integration

REFUSED = (mavlink.MAV_RESULT_DENIED, mavlink.MAV_RESULT_TEMPORARILY_REJECTED)  # armed; flying
CELLS = 4  # the default pack: 4S
BATTERY_FIELDS = (
    "battery_remaining_pct",
    "battery_voltage_v",
    "battery_current_a",
    "battery_consumed_wh",
    "battery_charge_state",
    "battery_critical",
)


async def until(condition: Callable[[], bool], what: str, timeout_s: float = WAIT_S) -> None:
    """Poll condition every 50 ms; fail naming `what` if it is still false after timeout_s (wall clock)."""
    deadline = time.monotonic() + timeout_s
    while not condition():
        assert time.monotonic() < deadline, f"{what} not seen within {timeout_s:g} s"
        await asyncio.sleep(0.05)


@contextlib.asynccontextmanager
async def connected_link(port: int) -> AsyncIterator[LinkManager]:
    """A started LinkManager to the vehicle's UDP port, connected and with a BATTERY_STATUS in, stopped at exit."""
    link = LinkManager(f"udpout://127.0.0.1:{port}", heartbeat_timeout_s=5.0)
    await link.start()
    try:
        assert await link.wait_connected(WAIT_S), "no heartbeat from the vehicle"
        await until(lambda: link.status.battery_status_seen, "BATTERY_STATUS")
        yield link
    finally:
        await link.stop()


def test_battery_state_swap_on_the_ground_and_refusal_in_flight(start_sitl):
    """A half-charged pack is reported (with the default pack's parameters), swapped for a full one on the
    ground, then drained in flight, where a swap is refused."""
    vehicle = start_sitl(extra_args=("--battery-percent", "50"))

    async def scenario() -> None:
        async with connected_link(vehicle.port) as link:
            s = link.status
            assert s.battery_remaining_pct == 50.0
            assert 3.3 * CELLS < s.battery_voltage_v < 4.2 * CELLS  # a 4S LiPo at rest, half charged
            assert s.battery_current_a == 0.0 and s.battery_consumed_wh == 0.0  # disarmed: nothing drawn
            assert s.battery_charge_state == mavlink.MAV_BATTERY_CHARGE_STATE_OK and not s.battery_critical
            shown = s.as_dict()
            assert all(name in shown for name in BATTERY_FIELDS) and shown["battery_remaining_pct"] == 50.0
            # the default pack as the simulator documents it: 4S, 4000 mAh, low warning at 15 %
            values = await link.read_parameters(["BAT1_N_CELLS", "BAT1_CAPACITY", "BAT_LOW_THR"])
            assert values == {"BAT1_N_CELLS": CELLS, "BAT1_CAPACITY": 4000.0, "BAT_LOW_THR": pytest.approx(0.15)}

            await link.reset_battery()  # landed and disarmed: a fresh pack
            await until(lambda: s.battery_remaining_pct == 100.0, "the battery at 100 % after the swap")
            full_v = s.battery_voltage_v
            assert full_v > 4.1 * CELLS

            await link.arm()
            await link.takeoff(5.0)  # AMSL; home is at 0 m
            await until(lambda: (s.alt_m or 0.0) > 1.0, "the vehicle climbing")
            await until(lambda: (s.battery_consumed_wh or 0.0) > 0.0, "energy drawn in flight")
            drawn = s.battery_consumed_wh
            await until(lambda: s.battery_consumed_wh > drawn, "the energy drawn rising")
            assert s.battery_current_a > 5.0  # a 1.3 kg quadrotor hovers on tens of amperes at 15 V
            assert s.battery_remaining_pct <= 100.0 and s.battery_voltage_v < full_v  # sagging under load

            with pytest.raises(CommandDeniedError) as refused:
                await link.reset_battery()
            assert refused.value.result in REFUSED
            assert s.battery_consumed_wh >= drawn  # the pack in use is still the one counted

    asyncio.run(scenario())


def test_parameters_read_by_name_with_integers_decoded(start_sitl):
    """PX4 sends INT32 parameters bytewise: BAT1_N_CELLS must read 4, not 5.6e-45; a value set on the vehicle's
    command line is what is read back; a name the vehicle does not know is a ParameterError naming it."""
    vehicle = start_sitl(extra_args=("--param", "BAT1_CAPACITY=1000"))

    async def scenario() -> None:
        async with connected_link(vehicle.port) as link:
            values = await link.read_parameters(["BAT1_N_CELLS", "BAT1_CAPACITY", "BAT_LOW_THR"])
            assert values == {"BAT1_N_CELLS": 4.0, "BAT1_CAPACITY": 1000.0, "BAT_LOW_THR": pytest.approx(0.15)}

            with pytest.raises(ParameterError) as unknown:
                await link.read_parameters(["BAT1_N_CELLS", "NO_SUCH_PARAM"], timeout_s=1.5)
            assert unknown.value.names == ("NO_SUCH_PARAM",) and "NO_SUCH_PARAM" in str(unknown.value)

    asyncio.run(scenario())


ARDUPILOT_PARAMS = {  # name: (MAV_PARAM_TYPE, value)
    "BATT_CAPACITY": (mavlink.MAV_PARAM_TYPE_INT32, 5200),
    "BATT_MONITOR": (mavlink.MAV_PARAM_TYPE_INT8, 4),
    "BATT_LOW_VOLT": (mavlink.MAV_PARAM_TYPE_REAL32, 14.4),
}


class ArduPilotParameters(threading.Thread):
    """Just enough ArduCopter on the link's udpin port: a heartbeat and SYS_STATUS (its battery, no BATTERY_STATUS)
    every 0.1 s, and a PARAM_VALUE for each PARAM_REQUEST_READ of a name it has, the value cast to a float
    whatever its type, as ArduPilot's GCS_Param.cpp sends it."""

    def __init__(self, link_port: int) -> None:
        super().__init__(daemon=True)
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(0.1)
        self.link = ("127.0.0.1", link_port)
        self.encoder, self.parser = Encoder(1, 1), new_parser(1, 1)
        self.running = True

    def send(self, message) -> None:
        self.sock.sendto(self.encoder.pack(message), self.link)

    def run(self) -> None:
        while self.running:
            self.send(
                mavlink.MAVLink_heartbeat_message(
                    mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0, mavlink.MAV_STATE_STANDBY, 3
                )
            )
            self.send(self.encoder.mav.sys_status_encode(0, 0, 0, 0, 15200, 1234, 76, 0, 0, 0, 0, 0, 0))
            try:
                data = self.sock.recv(65535)
            except OSError:
                continue
            for message in parse_datagram(self.parser, data):
                if message.get_type() == "PARAM_REQUEST_READ" and message.param_id in ARDUPILOT_PARAMS:
                    param_type, value = ARDUPILOT_PARAMS[message.param_id]
                    index = list(ARDUPILOT_PARAMS).index(message.param_id)
                    self.send(
                        mavlink.MAVLink_param_value_message(
                            message.param_id.encode(), float(value), param_type, len(ARDUPILOT_PARAMS), index
                        )
                    )

    def stop(self) -> None:
        self.running = False
        self.join(timeout=5)
        self.sock.close()


def test_ardupilot_battery_from_sys_status_and_integer_parameters_cast():
    port = free_udp_port()
    autopilot = ArduPilotParameters(port)

    async def scenario() -> None:
        link = LinkManager(f"udpin://127.0.0.1:{port}", heartbeat_timeout_s=5.0)
        await link.start()
        autopilot.start()
        try:
            assert await link.wait_connected(WAIT_S) and link.status.autopilot == "ARDUPILOTMEGA"
            s = link.status
            await until(lambda: s.battery_voltage_v is not None, "SYS_STATUS's battery")
            assert (s.battery_remaining_pct, s.battery_voltage_v, s.battery_current_a) == (76.0, 15.2, 12.34)
            assert s.battery_consumed_wh is None and s.battery_charge_state is None and not s.battery_critical
            values = await link.read_parameters(["BATT_CAPACITY", "BATT_MONITOR", "BATT_LOW_VOLT"])
            assert values == {"BATT_CAPACITY": 5200.0, "BATT_MONITOR": 4.0, "BATT_LOW_VOLT": pytest.approx(14.4)}
        finally:
            await link.stop()

    try:
        asyncio.run(scenario())
    finally:
        autopilot.stop()
