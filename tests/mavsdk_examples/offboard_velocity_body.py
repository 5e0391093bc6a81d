"""MAVSDK-Python's example `examples/offboard_velocity_body.py` (repository mavlink/MAVSDK-Python, commit
4fab80e4): the same calls, arguments and waits; only the addresses come from argv (see example_steps.py).

Connect, wait for a global position and home, arm, set a zero body velocity setpoint, start offboard, then
(forward, right, down m/s, yaw rate °/s): climb 1 turning at 60 (5 s), turn back at -60 (5 s), wait (2 s),
a circle at 5 forward turning at 30 (15 s), wait (5 s), a circle sideways at 5 left turning at 30 (15 s),
wait (8 s), and stop offboard.
"""

import asyncio

from example_steps import connect, start_offboard, stop_offboard, wait_for_global_position, wait_until_connected
from mavsdk.offboard import VelocityBodyYawspeed


async def run():
    drone = await connect()
    await wait_until_connected(drone)
    await wait_for_global_position(drone)

    print("-- Arming")
    await drone.action.arm()

    print("-- Setting initial setpoint")
    await drone.offboard.set_velocity_body(VelocityBodyYawspeed(0.0, 0.0, 0.0, 0.0))

    if not await start_offboard(drone):
        return

    print("-- Turn clock-wise and climb")
    await drone.offboard.set_velocity_body(VelocityBodyYawspeed(0.0, 0.0, -1.0, 60.0))
    await asyncio.sleep(5)

    print("-- Turn back anti-clockwise")
    await drone.offboard.set_velocity_body(VelocityBodyYawspeed(0.0, 0.0, 0.0, -60.0))
    await asyncio.sleep(5)

    print("-- Wait for a bit")
    await drone.offboard.set_velocity_body(VelocityBodyYawspeed(0.0, 0.0, 0.0, 0.0))
    await asyncio.sleep(2)

    print("-- Fly a circle")
    await drone.offboard.set_velocity_body(VelocityBodyYawspeed(5.0, 0.0, 0.0, 30.0))
    await asyncio.sleep(15)

    print("-- Wait for a bit")
    await drone.offboard.set_velocity_body(VelocityBodyYawspeed(0.0, 0.0, 0.0, 0.0))
    await asyncio.sleep(5)

    print("-- Fly a circle sideways")
    await drone.offboard.set_velocity_body(VelocityBodyYawspeed(0.0, -5.0, 0.0, 30.0))
    await asyncio.sleep(15)

    print("-- Wait for a bit")
    await drone.offboard.set_velocity_body(VelocityBodyYawspeed(0.0, 0.0, 0.0, 0.0))
    await asyncio.sleep(8)

    await stop_offboard(drone)


if __name__ == "__main__":
    asyncio.run(run())
