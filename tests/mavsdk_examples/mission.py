"""MAVSDK-Python's example `examples/mission.py` (repository mavlink/MAVSDK-Python, commit 4fab80e4): the same
calls, arguments and waits; only the addresses come from argv (see example_steps.py). The example writes its
three MissionItems out one by one; here they differ only in their place (WAYPOINTS).

Connect, print the mission progress as it changes, upload three waypoints 25 m up at 10 m/s with return to
launch after the mission, wait for a global position and home, arm, start the mission, and return once the
vehicle has been in the air and is on the ground again.
"""

import asyncio

from example_steps import connect, observe_is_in_air, wait_for_global_position, wait_until_connected
from mavsdk.mission import MissionItem, MissionPlan

WAYPOINTS = (  # the example's (latitude, longitude)
    (47.398039859999997, 8.5455725400000002),
    (47.398036222362471, 8.5450146439425509),
    (47.397825620791885, 8.5450092830163271),
)


async def run():
    drone = await connect()
    await wait_until_connected(drone)

    print_mission_progress_task = asyncio.ensure_future(print_mission_progress(drone))

    running_tasks = [print_mission_progress_task]
    termination_task = asyncio.ensure_future(observe_is_in_air(drone, running_tasks))

    nan = float("nan")
    mission_items = [
        MissionItem(
            latitude,
            longitude,
            25,
            10,
            True,
            nan,
            nan,
            MissionItem.CameraAction.NONE,
            nan,
            nan,
            nan,
            nan,
            nan,
            MissionItem.VehicleAction.NONE,
        )
        for latitude, longitude in WAYPOINTS
    ]
    mission_plan = MissionPlan(mission_items)

    await drone.mission.set_return_to_launch_after_mission(True)

    print("-- Uploading mission")
    await drone.mission.upload_mission(mission_plan)

    await wait_for_global_position(drone)

    print("-- Arming")
    await drone.action.arm()

    print("-- Starting mission")
    await drone.mission.start_mission()

    await termination_task


async def print_mission_progress(drone):
    async for mission_progress in drone.mission.mission_progress():
        print(f"Mission progress: {mission_progress.current}/{mission_progress.total}")


if __name__ == "__main__":
    asyncio.run(run())
