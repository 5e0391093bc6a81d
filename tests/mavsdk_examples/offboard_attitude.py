"""MAVSDK-Python's example `examples/offboard_attitude.py` (repository mavlink/MAVSDK-Python, commit 4fab80e4):
the same calls, arguments and waits; only the addresses come from argv (see example_steps.py).

Connect, wait for a global position and home, arm, set a level attitude at zero thrust, start offboard, then
2 s each: level at 70 % thrust, roll 30° at 60 %, roll -30° at 60 %, level at 60 %; stop offboard and land
(the example returns right after the land command).
"""

import asyncio

from example_steps import connect, start_offboard, stop_offboard, wait_for_global_position, wait_until_connected
from mavsdk.offboard import Attitude


async def run():
    drone = await connect()
    await wait_until_connected(drone)
    await wait_for_global_position(drone)

    print("-- Arming")
    await drone.action.arm()

    print("-- Setting initial setpoint")
    await drone.offboard.set_attitude(Attitude(0.0, 0.0, 0.0, 0.0))

    if not await start_offboard(drone):
        return

    print("-- Go up at 70% thrust")
    await drone.offboard.set_attitude(Attitude(0.0, 0.0, 0.0, 0.7))
    await asyncio.sleep(2)

    print("-- Roll 30 at 60% thrust")
    await drone.offboard.set_attitude(Attitude(30.0, 0.0, 0.0, 0.6))
    await asyncio.sleep(2)

    print("-- Roll -30 at 60% thrust")
    await drone.offboard.set_attitude(Attitude(-30.0, 0.0, 0.0, 0.6))
    await asyncio.sleep(2)

    print("-- Hover at 60% thrust")
    await drone.offboard.set_attitude(Attitude(0.0, 0.0, 0.0, 0.6))
    await asyncio.sleep(2)

    await stop_offboard(drone)

    await drone.action.land()


if __name__ == "__main__":
    asyncio.run(run())
