"""MAVSDK-Python's example `examples/offboard_position_ned.py` (repository mavlink/MAVSDK-Python, commit
4fab80e4): the same calls, arguments and waits; only the addresses come from argv (see example_steps.py).

Connect, wait for a global position and home, arm, set the NED position setpoint 0/0/0 yaw 0, start offboard,
then go to 0/0/-5 (10 s), 5/0/-5 facing east (10 s), 5/10/-5 (15 s), 0/10/0 facing south (10 s), and stop
offboard. The example logs at INFO level, so mavsdk_server's messages show.
"""

import asyncio
import logging

from example_steps import connect, start_offboard, stop_offboard, wait_for_global_position, wait_until_connected
from mavsdk.offboard import PositionNedYaw

logging.basicConfig(level=logging.INFO)


async def run():
    drone = await connect()
    await wait_until_connected(drone)
    await wait_for_global_position(drone)

    print("-- Arming")
    await drone.action.arm()

    print("-- Setting initial setpoint")
    await drone.offboard.set_position_ned(PositionNedYaw(0.0, 0.0, 0.0, 0.0))

    if not await start_offboard(drone):
        return

    print("-- Go 0m North, 0m East, -5m Down within local coordinate system")
    await drone.offboard.set_position_ned(PositionNedYaw(0.0, 0.0, -5.0, 0.0))
    await asyncio.sleep(10)

    print("-- Go 5m North, 0m East, -5m Down within local coordinate system, turn to face East")
    await drone.offboard.set_position_ned(PositionNedYaw(5.0, 0.0, -5.0, 90.0))
    await asyncio.sleep(10)

    print("-- Go 5m North, 10m East, -5m Down within local coordinate system")
    await drone.offboard.set_position_ned(PositionNedYaw(5.0, 10.0, -5.0, 90.0))
    await asyncio.sleep(15)

    print("-- Go 0m North, 10m East, 0m Down within local coordinate system, turn to face South")
    await drone.offboard.set_position_ned(PositionNedYaw(0.0, 10.0, 0.0, 180.0))
    await asyncio.sleep(10)

    await stop_offboard(drone)


if __name__ == "__main__":
    asyncio.run(run())
