"""MAVSDK-Python's example `examples/mission_import.py` (repository mavlink/MAVSDK-Python, commit 4fab80e4):
the same calls, arguments and waits; only the addresses come from argv (see example_steps.py).

Connect, import the QGroundControl plan "example-mission.plan" from the working directory (the test runs this
in tests/data, which holds one), upload its mission items, then its rally points.
"""

import asyncio

from example_steps import connect, wait_until_connected


async def run():
    drone = await connect()
    await wait_until_connected(drone)

    out = await drone.mission_raw.import_qgroundcontrol_mission("example-mission.plan")

    print(f"{len(out.mission_items)} mission items and {len(out.rally_items)} rally items imported.")

    await drone.mission_raw.upload_mission(out.mission_items)
    await drone.mission_raw.upload_rally_points(out.rally_items)

    print("Mission uploaded")


if __name__ == "__main__":
    asyncio.run(run())
