"""MAVSDK-Python's example `examples/do_orbit.py` (repository mavlink/MAVSDK-Python, commit 4fab80e4): the same
calls, arguments and waits; only the addresses come from argv (see example_steps.py).

Connect, wait for a global position and home, note the current AMSL altitude, arm, take off, wait 10 s, orbit
47.398036, 8.545015 with a 10 m radius at 2 m/s, 10 m above the start, facing the centre, for 60 s, then return
to launch (the example returns right after the RTL command).
"""

import asyncio

from example_steps import connect, wait_for_global_position, wait_until_connected
from mavsdk.action import OrbitYawBehavior


async def run():
    drone = await connect()
    await wait_until_connected(drone)
    await wait_for_global_position(drone)

    position = await drone.telemetry.position().__aiter__().__anext__()
    orbit_height = position.absolute_altitude_m + 10
    yaw_behavior = OrbitYawBehavior.HOLD_FRONT_TO_CIRCLE_CENTER

    print("-- Arming")
    await drone.action.arm()

    print("--- Taking Off")
    await drone.action.takeoff()
    await asyncio.sleep(10)

    print("Do orbit at 10m height from the ground")
    await drone.action.do_orbit(
        radius_m=10,
        velocity_ms=2,
        yaw_behavior=yaw_behavior,
        latitude_deg=47.398036222362471,
        longitude_deg=8.5450146439425509,
        absolute_altitude_m=orbit_height,
    )
    await asyncio.sleep(60)

    await drone.action.return_to_launch()
    print("--- Landing")


if __name__ == "__main__":
    asyncio.run(run())
