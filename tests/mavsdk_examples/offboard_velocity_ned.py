"""MAVSDK-Python's example `examples/offboard_velocity_ned.py` (repository mavlink/MAVSDK-Python, commit
4fab80e4): the same calls, arguments and waits; only the addresses come from argv (see example_steps.py).

Connect, wait for a global position and home, arm, set a zero NED velocity setpoint, start offboard, then
(NED m/s, yaw °): up 2 (4 s), north 2 facing east (4 s), south 2 facing west (4 s), west 2 facing east (4 s),
east 2 (4 s), stop and face south (2 s), down 1 facing north (4 s), and stop offboard.
"""

import asyncio

from example_steps import connect, start_offboard, stop_offboard, wait_for_global_position, wait_until_connected
from mavsdk.offboard import VelocityNedYaw


async def run():
    drone = await connect()
    await wait_until_connected(drone)
    await wait_for_global_position(drone)

    print("-- Arming")
    await drone.action.arm()

    print("-- Setting initial setpoint")
    await drone.offboard.set_velocity_ned(VelocityNedYaw(0.0, 0.0, 0.0, 0.0))

    if not await start_offboard(drone):
        return

    print("-- Go up 2 m/s")
    await drone.offboard.set_velocity_ned(VelocityNedYaw(0.0, 0.0, -2.0, 0.0))
    await asyncio.sleep(4)

    print("-- Go North 2 m/s, turn to face East")
    await drone.offboard.set_velocity_ned(VelocityNedYaw(2.0, 0.0, 0.0, 90.0))
    await asyncio.sleep(4)

    print("-- Go South 2 m/s, turn to face West")
    await drone.offboard.set_velocity_ned(VelocityNedYaw(-2.0, 0.0, 0.0, 270.0))
    await asyncio.sleep(4)

    print("-- Go West 2 m/s, turn to face East")
    await drone.offboard.set_velocity_ned(VelocityNedYaw(0.0, -2.0, 0.0, 90.0))
    await asyncio.sleep(4)

    print("-- Go East 2 m/s")
    await drone.offboard.set_velocity_ned(VelocityNedYaw(0.0, 2.0, 0.0, 90.0))
    await asyncio.sleep(4)

    print("-- Turn to face South")
    await drone.offboard.set_velocity_ned(VelocityNedYaw(0.0, 0.0, 0.0, 180.0))
    await asyncio.sleep(2)

    print("-- Go down 1 m/s, turn to face North")
    await drone.offboard.set_velocity_ned(VelocityNedYaw(0.0, 0.0, 1.0, 0.0))
    await asyncio.sleep(4)

    await stop_offboard(drone)


if __name__ == "__main__":
    asyncio.run(run())
