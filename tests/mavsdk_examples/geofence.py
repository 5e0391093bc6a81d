"""MAVSDK-Python's example `examples/geofence.py` (repository mavlink/MAVSDK-Python, commit 4fab80e4): the same
calls, arguments and waits; only the addresses come from argv (see example_steps.py).

Connect, read home, wait 1 s, upload an inclusion polygon of ±0.0001° around home together with the example's
"no circle": an inclusion circle of radius 0 at latitude 0, longitude 0 (MAVSDK's GeofenceData takes polygons
and circles; the example fills the circles with that one rather than leave them empty). PX4 accepts the list and
discards the circle as it loads the fence ("Geofence invalid, doesn't contain Home position").
"""

import asyncio

from example_steps import connect, wait_until_connected
from mavsdk.geofence import Circle, FenceType, GeofenceData, Point, Polygon


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
    no_circle = Circle(Point(0, 0), 0, FenceType.INCLUSION)

    print("Uploading geofence...")
    await drone.geofence.upload_geofence(GeofenceData([polygon], [no_circle]))

    print("Geofence uploaded!")


if __name__ == "__main__":
    asyncio.run(run())
