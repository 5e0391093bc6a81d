"""MAVSDK-Python's example `examples/firmware_version.py` (repository mavlink/MAVSDK-Python, commit 4fab80e4):
the same calls; only the addresses come from argv (see example_steps.py).

Connect, then print the autopilot's version information (Info.get_version, from AUTOPILOT_VERSION).
"""

import asyncio

from example_steps import connect, wait_until_connected


async def run():
    drone = await connect()
    await wait_until_connected(drone)

    info = await drone.info.get_version()
    print(info)


if __name__ == "__main__":
    asyncio.run(run())
