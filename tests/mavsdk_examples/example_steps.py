"""What the example programs beside this file share: where they connect, and the steps that several of
MAVSDK-Python's examples write out word for word (kept once here; each example calls them in its own order).

The examples hardcode the MAVLink address udp://:14540 and let `System()` start the bundled mavsdk_server on
gRPC port 50051. Both come from the command line here, so that tests running side by side never share a port:

    .venv-mavsdk3/bin/python tests/mavsdk_examples/<example>.py udp://:MAVLINK_PORT GRPC_PORT

That is the only change to the examples' calls, arguments and waits.
"""

import asyncio
import contextlib
import sys

from mavsdk import System
from mavsdk.offboard import OffboardError

DEFAULT_GRPC_PORT = 50051  # System()'s default, as the examples use it


async def connect() -> System:
    """The examples' `drone = System(); await drone.connect(system_address="udp://:14540")`, with argv's
    MAVLink address and gRPC port."""
    grpc_port = int(sys.argv[2]) if len(sys.argv) > 2 else DEFAULT_GRPC_PORT
    drone = System(port=grpc_port)
    await drone.connect(system_address=sys.argv[1])
    return drone


async def wait_until_connected(drone: System) -> None:
    print("Waiting for drone to connect...")
    async for state in drone.core.connection_state():
        if state.is_connected:
            print("-- Connected to drone!")
            break


async def wait_for_global_position(drone: System) -> None:
    """Until telemetry says both the global position estimate and home are good."""
    print("Waiting for drone to have a global position estimate...")
    async for health in drone.telemetry.health():
        if health.is_global_position_ok and health.is_home_position_ok:
            print("-- Global position estimate OK")
            break


async def observe_is_in_air(drone: System, running_tasks: list) -> None:
    """Return (after stopping running_tasks) once the vehicle has been in the air and is back on the ground."""
    was_in_air = False
    async for is_in_air in drone.telemetry.in_air():
        if is_in_air:
            was_in_air = is_in_air
        if was_in_air and not is_in_air:
            for task in running_tasks:
                task.cancel()
                with contextlib.suppress(asyncio.CancelledError):
                    await task
            await asyncio.get_event_loop().shutdown_asyncgens()
            return


async def start_offboard(drone: System) -> bool:
    """Start offboard mode; on failure print the error, disarm and say False (the example then returns)."""
    print("-- Starting offboard")
    try:
        await drone.offboard.start()
    except OffboardError as error:
        print(f"Starting offboard mode failed with error code: {error._result.result}")
        print("-- Disarming")
        await drone.action.disarm()
        return False
    return True


async def stop_offboard(drone: System) -> None:
    print("-- Stopping offboard")
    try:
        await drone.offboard.stop()
    except OffboardError as error:
        print(f"Stopping offboard mode failed with error code: {error._result.result}")
