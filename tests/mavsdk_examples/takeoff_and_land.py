"""MAVSDK-Python's example `examples/takeoff_and_land.py` (repository mavlink/MAVSDK-Python, commit 4fab80e4):
the same calls, arguments and waits; only the addresses come from argv (see example_steps.py).

Connect, wait for a global position and home, arm, take off, hover 10 s, land; status texts are printed as
they come. The example returns right after the land command: it does not wait for the touchdown.
"""

import asyncio

from example_steps import connect, wait_for_global_position, wait_until_connected


async def run():
    drone = await connect()

    status_text_task = asyncio.ensure_future(print_status_text(drone))

    await wait_until_connected(drone)
    await wait_for_global_position(drone)

    print("-- Arming")
    await drone.action.arm()

    print("-- Taking off")
    await drone.action.takeoff()

    await asyncio.sleep(10)

    print("-- Landing")
    await drone.action.land()

    status_text_task.cancel()


async def print_status_text(drone):
    try:
        async for status_text in drone.telemetry.status_text():
            print(f"Status: {status_text.type}: {status_text.text}")
    except asyncio.CancelledError:
        return


if __name__ == "__main__":
    asyncio.run(run())
