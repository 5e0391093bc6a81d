"""The vehicle's payload: the camera (component 100, sitl_quad.mavlink.camera) on its gimbal, whose manager is the
autopilot's (sitl_quad.mavlink.gimbal). One object for the vehicle server and the in-process lockstep harness, so
both run a mission's camera and gimbal items, and move and capture after each tick, by the same code.
"""

from __future__ import annotations

from pathlib import Path

from sitl_quad.camera import DEFAULT_SPEC, CameraSpec, Environment
from sitl_quad.mavlink.camera import CameraComponent
from sitl_quad.mavlink.commands import Commands
from sitl_quad.mavlink.gimbal import GimbalManager
from sitl_quad.vehicle import Vehicle
from uavcore.buoy_world import World


class Payload:
    def __init__(
        self,
        vehicle: Vehicle,
        link,
        commands: Commands,
        image_dir: Path,
        world: World | None = None,
        current: Environment | None = None,
        spec: CameraSpec = DEFAULT_SPEC,
        boot_unix_us: int | None = None,
        frames_in_loop: bool = True,
    ) -> None:
        """The gimbal manager registers its commands with `commands`; the camera writes into `image_dir`, making
        its frames in the loop (lockstep) or in a worker process (paced: sitl_quad.mavlink.camera_frames)."""
        self.vehicle = vehicle
        self.gimbal = GimbalManager(vehicle, link, commands)
        self.camera = CameraComponent(
            vehicle, link, self.gimbal.gimbal, image_dir, world, current, spec=spec, boot_unix_us=boot_unix_us,
            frames_in_loop=frames_in_loop,
        )  # fmt: skip

    def run_mission_item(self, seq: int) -> None:
        """A camera or gimbal mission item the navigator reached (PX4 re-issues them as commands)."""
        if not 0 <= seq < len(self.vehicle.mission):
            return
        item = self.vehicle.mission[seq]
        if not self.gimbal.run_mission_item(item):
            self.camera.run_mission_item(item)

    def tick(self) -> None:
        """After each tick (and its mission items): the gimbal moves, the camera takes what is due at this instant
        (before simulated time goes on, so lockstep captures exactly there), the gimbal's status streams."""
        self.gimbal.update()
        self.camera.capture_due()
        self.gimbal.publish_due()

    def close(self) -> None:
        """The frames still being made are written and reported, the camera's worker stopped."""
        self.camera.close()
