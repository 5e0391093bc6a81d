"""MAVSDK-Python's example `examples/goto.py` (repository mavlink/MAVSDK-Python, commit 4fab80e4): the same
calls, arguments and waits; only the addresses come from argv (see example_steps.py).

Connect, wait for a global position and home, read home's AMSL altitude, arm, take off, and 1 s later go to
47.397606, 8.543060 at 20 m above home, then stay connected until Ctrl-C (the example never returns by itself).
"""

import asyncio

from example_steps import connect, wait_for_global_position, wait_until_connected


async def run():
    drone = await connect()
    await wait_until_connected(drone)
    await wait_for_global_position(drone)

    print("Fetching amsl altitude at home location....")
    async for terrain_info in drone.telemetry.home():
        absolute_altitude = terrain_info.absolute_altitude_m
        break

    print("-- Arming")
    await drone.action.arm()

    print("-- Taking off")
    await drone.action.takeoff()

    await asyncio.sleep(1)
    flying_alt = absolute_altitude + 20.0  # 20 m above home: goto_location takes an AMSL altitude
    await drone.action.goto_location(47.397606, 8.543060, flying_alt, 0)

    while True:
        print("Staying connected, press Ctrl-C to exit")
        await asyncio.sleep(1)


if __name__ == "__main__":
    asyncio.run(run())
