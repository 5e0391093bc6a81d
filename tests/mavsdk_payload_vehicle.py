"""The MAVSDK server-plugin autopilot (tests/mavsdk_server_vehicle.py) with what PX4's navigator does with a
mission's payload items, for a MAVLink camera of its system:

- IMAGE_START_CAPTURE / IMAGE_STOP_CAPTURE items are re-emitted as COMMAND_LONG from the autopilot to component 0
  of its own system (every component: the camera takes them), their params as the item has them, as PX4 does
  ("the commands are sent using the autopilot's system ID and a component ID of 0", PX4's camera docs);
- as gimbal manager it aims the gimbal: from a DO_SET_ROI_LOCATION item (frame GLOBAL_RELATIVE_ALT: z above
  home) until DO_SET_ROI_NONE it sends GIMBAL_DEVICE_SET_ATTITUDE to the gimbal device (MAV_COMP_ID_GIMBAL, 154)
  each tick: the line of sight from the vehicle to the ROI, earth frame (flags ROLL_LOCK | PITCH_LOCK |
  YAW_LOCK), q = camera FRD -> NED; at DO_SET_ROI_NONE once neutral (level, along the heading). The device
  follows at once. (Nothing is sent before the mission's first ROI: MAVSDK routes a message for system 1 only
  once it has heard a component of it, the camera.)

MAVSDK's MavlinkDirectServer sends these from the autopilot's own component (1/1). Each COMMAND_ACK the camera
sends back is printed. Same command line as mavsdk_server_vehicle.py.
"""

from __future__ import annotations

import json
import math

from mavsdk.plugins.mavlink_direct_server import MavlinkDirectServer, MavlinkMessage
from mavsdk_server_vehicle import MavsdkServerVehicle, main

from sitl_quad.gimbal import aim_angles
from uavcore.mavlink import mavlink
from uavcore.mission import MavCmd, MissionItem
from uavcore.rotation import quat_from_euler

GIMBAL_COMPID = mavlink.MAV_COMP_ID_GIMBAL  # 154
EARTH_FRAME = (
    mavlink.GIMBAL_DEVICE_FLAGS_ROLL_LOCK
    | mavlink.GIMBAL_DEVICE_FLAGS_PITCH_LOCK
    | mavlink.GIMBAL_DEVICE_FLAGS_YAW_LOCK
)
CAMERA_ITEMS = (MavCmd.IMAGE_START_CAPTURE, MavCmd.IMAGE_STOP_CAPTURE)


class MavsdkPayloadVehicle(MavsdkServerVehicle):
    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.roi_ned: tuple[float, float, float] | None = None  # only the loop (main thread) touches it
        self.direct = MavlinkDirectServer(self.mavsdk.server_component())
        self.direct.subscribe_message("COMMAND_ACK", self._on_ack)

    def _on_ack(self, message: MavlinkMessage, _user_data) -> None:
        fields = json.loads(message.fields_json)
        if (message.target_system_id, message.target_component_id) == (1, 1) and fields["command"] > 0:
            print(f"ack from {message.system_id}/{message.component_id}: {fields['command']} -> "
                  f"{fields['result']}", flush=True)  # fmt: skip

    def fly_item(self, item: MissionItem, dt: float) -> bool:
        if item.command in CAMERA_ITEMS:
            self.command_camera(item)
            return True
        if item.command == MavCmd.DO_SET_ROI_LOCATION:
            self.roi_ned = tuple(self.frame.to_ned(item.lat, item.lon, self.home[2] + item.z))  # type: ignore[assignment]
            return True
        if item.command == MavCmd.DO_SET_ROI_NONE:
            self.roi_ned = None
            self.aim_gimbal(0.0, math.radians(self.heading_deg))  # neutral: level, along the heading
            return True
        return super().fly_item(item, dt)

    def command_camera(self, item: MissionItem) -> None:
        values = (item.param1, item.param2, item.param3, item.param4, float(item.x), float(item.y), item.z)
        params = {f"param{i}": 0.0 if math.isnan(v) else v for i, v in enumerate(values, 1)}  # the item's params
        fields = {"target_system": 1, "target_component": 0, "command": item.command, "confirmation": 0} | params
        self.send("COMMAND_LONG", 0, fields)
        print(f"mission item {item.seq}: COMMAND_LONG {item.command} {params} to 1/0", flush=True)

    def publish_fast(self) -> None:
        super().publish_fast()
        if self.roi_ned is not None:
            self.aim_gimbal(*aim_angles((self.north, self.east, self.down), self.roi_ned))

    def aim_gimbal(self, pitch: float, yaw: float) -> None:
        q = [float(c) for c in quat_from_euler(0.0, pitch, yaw)]
        unset = math.nan  # the device's rates: not commanded
        fields = {"target_system": 1, "target_component": GIMBAL_COMPID, "flags": EARTH_FRAME, "q": q,
                  "angular_velocity_x": unset, "angular_velocity_y": unset, "angular_velocity_z": unset}  # fmt: skip
        self.send("GIMBAL_DEVICE_SET_ATTITUDE", GIMBAL_COMPID, fields)

    def send(self, name: str, target_component: int, fields: dict) -> None:
        text = json.dumps(fields).replace("NaN", "null")  # JSON has no NaN; MAVSDK reads null as NaN for floats
        self.direct.send_message(MavlinkMessage(name, 1, 1, 1, target_component, text))


if __name__ == "__main__":
    raise SystemExit(main(vehicle_type=MavsdkPayloadVehicle))
