"""MAVSDK-Python's example `examples/geofence.py` (repository mavlink/MAVSDK-Python, commit 0a2890d7): the same
calls, arguments and waits; only the addresses come from argv (see example_steps.py). That version of the
example predates MAVSDK-Python 2's geofence API: the fence type is `FenceType.INCLUSION` (was
`Polygon.FenceType.INCLUSION`) and `upload_geofence` takes a `GeofenceData(polygons, circles)` (was a list of
polygons), as the installed 3.x requires.

Connect, read home, wait 1 s, upload an inclusion polygon of ±0.0001° around home.
"""

import asyncio

from example_steps import connect, wait_until_connected
from mavsdk.geofence import FenceType, GeofenceData, Point, Polygon


async def run():
    drone = await connect()
    await wait_until_connected(drone)

    print("Fetching home location coordinates...")
    async for terrain_info in drone.telemetry.home():
        latitude = terrain_info.latitude_deg
        longitude = terrain_info.longitude_deg
        break

    await asyncio.sleep(1)

    p1 = Point(latitude - 0.0001, longitude - 0.0001)
    p2 = Point(latitude + 0.0001, longitude - 0.0001)
    p3 = Point(latitude + 0.0001, longitude + 0.0001)
    p4 = Point(latitude - 0.0001, longitude + 0.0001)
    polygon = Polygon([p1, p2, p3, p4], FenceType.INCLUSION)

    print("Uploading geofence...")
    await drone.geofence.upload_geofence(GeofenceData(polygons=[polygon], circles=[]))

    print("Geofence uploaded!")


if __name__ == "__main__":
    asyncio.run(run())
