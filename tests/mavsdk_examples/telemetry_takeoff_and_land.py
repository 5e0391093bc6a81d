"""MAVSDK-Python's example `examples/telemetry_takeoff_and_land.py` (repository mavlink/MAVSDK-Python, commit
4fab80e4): the same calls, arguments and waits; only the addresses come from argv (see example_steps.py).

Connect; print the altitude and the flight mode whenever they change; wait for a global position and home;
arm, set the takeoff altitude to 10 m, take off, hover 10 s, land, and return once the vehicle has been in the
air and is on the ground again.
"""

import asyncio

from example_steps import connect, observe_is_in_air, wait_for_global_position, wait_until_connected


async def run():
    drone = await connect()
    await wait_until_connected(drone)

    print_altitude_task = asyncio.ensure_future(print_altitude(drone))
    print_flight_mode_task = asyncio.ensure_future(print_flight_mode(drone))

    running_tasks = [print_altitude_task, print_flight_mode_task]
    termination_task = asyncio.ensure_future(observe_is_in_air(drone, running_tasks))

    await wait_for_global_position(drone)

    print("-- Arming")
    await drone.action.arm()

    print("-- Taking off")
    await drone.action.set_takeoff_altitude(10.0)
    await drone.action.takeoff()

    await asyncio.sleep(10)

    print("-- Landing")
    await drone.action.land()

    # Returns once the vehicle is on the ground again (instead of right after the land command).
    await termination_task


async def print_altitude(drone):
    previous_altitude = None
    async for position in drone.telemetry.position():
        altitude = round(position.relative_altitude_m)
        if altitude != previous_altitude:
            previous_altitude = altitude
            print(f"Altitude: {altitude}")


async def print_flight_mode(drone):
    previous_flight_mode = None
    async for flight_mode in drone.telemetry.flight_mode():
        if flight_mode != previous_flight_mode:
            previous_flight_mode = flight_mode
            print(f"Flight mode: {flight_mode}")


if __name__ == "__main__":
    asyncio.run(run())
