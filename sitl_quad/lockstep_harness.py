"""The UDP lockstep flight without sockets: a `Vehicle` and an outer-loop controller in one process.

Each `LockstepHarness.step()` does what `python -m sitl_quad --lockstep` and `python -m adrc_offboard` do
for one outer-loop tick, with the same code on both sides:

1. `vehicle.tick()` (sitl_quad.vehicle);
2. the vehicle's per-tick onboard stream (HEARTBEAT, EXTENDED_SYS_STATE, LOCAL_POSITION_NED,
   ATTITUDE_QUATERNION, POSITION_TARGET_LOCAL_NED, built by sitl_quad.mavlink.telemetry) is packed to
   MAVLink 2 bytes and parsed back, so the controller sees the same float32-rounded numbers it would
   receive over UDP;
3. the offboard node's own `OffboardProtocol` (adrc_offboard.node) handles them: it asks for OFFBOARD when
   the vehicle is armed in mission mode, resets the controller while it is not in control or still on the
   ground, and answers with a SET_ATTITUDE_TARGET stamped with the tick's time_boot_ms;
4. its replies are packed and parsed again and handed to the vehicle's own MAVLink handlers
   (sitl_quad.mavlink.commands for DO_SET_MODE, sitl_quad.mavlink.offboard for SET_ATTITUDE_TARGET), which
   the lockstep server runs before it starts the next tick.

What is left out never reaches the flight's decisions: the 1 Hz wall-clock heartbeats (the per-tick one
carries the same mode and arming), the slower ground-station streams, command acknowledgements and the
node's DEBUG_VECT. Without a controller the harness just ticks the vehicle, as the lockstep server does when
no offboard peer streams: the vehicle's built-in PID cascade flies ("PX4 defaults").

A harness may carry the server's payload (`carry_payload`: the camera on its gimbal, sitl_quad.mavlink.payload):
it runs the mission's camera and gimbal items and captures after each tick as the lockstep server does,
rendering and writing each frame before the next tick; what the payload would send is dropped (its
CAMERA_IMAGE_CAPTURED messages stay readable in `payload.camera.captured`).

Ground-station actions (`upload_mission`, `arm`, `start_mission`) take effect between two ticks, as a
command arriving while the lockstep server waits does; missions go through a MISSION_ITEM_INT round trip.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from types import SimpleNamespace

from adrc_offboard.node import OffboardProtocol
from sitl_quad.camera import DEFAULT_SPEC, CameraSpec, Environment
from sitl_quad.mavlink.commands import Commands
from sitl_quad.mavlink.heartbeat import heartbeat_message
from sitl_quad.mavlink.offboard import Offboard
from sitl_quad.mavlink.payload import Payload
from sitl_quad.mavlink.telemetry import ONBOARD_STREAMS, Telemetry
from sitl_quad.vehicle import CommandResult, TickRecord, Vehicle, VehicleEvent
from uavcore.buoy_world import World
from uavcore.control import OuterLoopController
from uavcore.mavlink import item_from_message, item_message, mavlink
from uavcore.mission import MissionItem

VEHICLE_IDS = (1, 1)
OFFBOARD_IDS = (1, 191)  # MAV_COMP_ID_ONBOARD_COMPUTER, as adrc_offboard
GCS_IDS = (255, 190)


class HarnessError(RuntimeError):
    """A ground-station action the vehicle refused, or a flight that did not finish in time."""


class _WireCodec:
    """Packs messages as one peer would and parses them as the other: MAVLink 2 bytes in between."""

    def __init__(self, sysid: int, compid: int) -> None:
        self._encoder = mavlink.MAVLink(None, srcSystem=sysid, srcComponent=compid)
        self._decoder = mavlink.MAVLink(None)

    def __call__(self, messages: list) -> list:
        data = bytearray()
        for msg in messages:
            data += msg.pack(self._encoder)
            self._encoder.seq = (self._encoder.seq + 1) % 256
        return self._decoder.parse_buffer(bytes(data)) or []


class LockstepHarness:
    """One vehicle, optionally one outer-loop controller behind the offboard node's protocol."""

    def __init__(
        self,
        vehicle: Vehicle,
        controller: OuterLoopController | None = None,
        engage: bool = True,
        outer_rate_hz: float = 50.0,
    ) -> None:
        self.vehicle = vehicle
        self.controller = controller
        self.node = None if controller is None else OffboardProtocol(controller, outer_rate_hz, engage)
        self._telemetry = Telemetry(vehicle, SimpleNamespace(send=_discard, stats=None))
        self._commands = Commands(vehicle, _discard)
        self._offboard = Offboard(vehicle)
        self._to_node = _WireCodec(*VEHICLE_IDS)
        self._to_vehicle = _WireCodec(*OFFBOARD_IDS)
        self._from_gcs = _WireCodec(*GCS_IDS)
        self.payload: Payload | None = None
        self.last_events: list[VehicleEvent] = []  # what the last tick would have published

    def carry_payload(
        self,
        image_dir: Path,
        world: World | None = None,
        current: Environment | None = None,
        spec: CameraSpec = DEFAULT_SPEC,
    ) -> Payload:
        """Give the vehicle the server's camera on its gimbal (module docstring); `image_dir` must exist."""
        link = SimpleNamespace(
            sysid=VEHICLE_IDS[0],
            compid=VEHICLE_IDS[1],
            send=_discard,
            send_batch=_discard,
            live_peers=list,
            add_component=_discard,
        )
        self.payload = Payload(self.vehicle, link, self._commands, image_dir, world, current, spec=spec)
        return self.payload

    # ----- ground-station actions, between ticks
    def upload_mission(self, items: list[MissionItem]) -> None:
        """Store a mission as the vehicle's mission protocol would after a MISSION_ITEM_INT upload."""
        messages = [item_message(it, *VEHICLE_IDS) for it in items]
        self.vehicle.set_mission([item_from_message(m) for m in self._from_gcs(messages)])

    def arm(self) -> None:
        _require(self.vehicle.arm(), "arm")

    def start_mission(self) -> None:
        _require(self.vehicle.start_mission(), "start the mission")

    # ----- the lockstep tick
    def step(self) -> TickRecord:
        """One outer-loop tick and the offboard exchange that answers it (applied during the next tick)."""
        record = self.tick()
        self.exchange()
        return record

    def tick(self) -> TickRecord:
        """The vehicle's tick alone: where the lockstep server writes its flight-log row."""
        record = self.vehicle.tick()
        # what the server would publish: only the payload's mission items are acted on here
        self.last_events, self.vehicle.events = self.vehicle.events, []
        if self.payload is not None:
            for event in self.last_events:
                if event.kind == "payload_item":
                    self.payload.run_mission_item(event.seq)
            self.payload.tick()
        return record

    def exchange(self) -> None:
        """The tick's state to the offboard node and its answer back to the vehicle."""
        if self.node is None:
            return
        # the batch Telemetry.publish_due sends onboard peers every tick, in its order
        stream = [
            heartbeat_message(self.vehicle),
            self._telemetry.extended_sys_state(),
            *(self._telemetry.builders[n]() for n in ONBOARD_STREAMS),
        ]
        replies = []
        for msg in self._to_node(stream):
            replies += self.node.handle(msg)
        for msg in self._to_vehicle(replies):
            kind = msg.get_type()
            if kind == "COMMAND_LONG":
                self._commands.command_long(None, msg)
            elif kind == "SET_ATTITUDE_TARGET":
                self._offboard.on_attitude_target(None, msg)

    def fly_mission(
        self,
        items: list[MissionItem],
        idle_ticks: int = 25,
        timeout_s: float = 900.0,
        on_tick: Callable[[TickRecord], None] | None = None,
    ) -> int:
        """Upload, arm, idle `idle_ticks` on the ground, start, and step until the vehicle has landed and
        disarmed. Calls on_tick(record) after every tick from the start, before the offboard exchange (where
        the lockstep server logs: the controller still holds its answer to the previous tick); returns the
        number of ticks flown."""
        self.upload_mission(items)
        self.arm()
        for _ in range(idle_ticks):
            self.step()
        self.start_mission()
        ticks, limit = 0, round(timeout_s / self.vehicle.outer_dt)
        while ticks < limit:
            record = self.tick()
            ticks += 1
            if on_tick is not None:
                on_tick(record)
            self.exchange()
            if not self.vehicle.armed:
                return ticks
        raise HarnessError(f"the mission did not end within {timeout_s:g} s of simulated time")


def _discard(*_args, **_kwargs) -> None:
    """A send() that drops what the vehicle's handlers would transmit (acknowledgements)."""


def _require(result: CommandResult, action: str) -> None:
    if result != CommandResult.ACCEPTED:
        raise HarnessError(f"the vehicle refused to {action}: {result.name}")
