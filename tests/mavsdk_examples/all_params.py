"""MAVSDK-Python's example `examples/all_params.py` (repository mavlink/MAVSDK-Python, commit 4fab80e4): the
same calls; only the addresses come from argv (see example_steps.py).

Connect and print every parameter, the int ones, then the float ones, as "NAME: VALUE".
"""

import asyncio

from example_steps import connect


async def run():
    drone = await connect()

    all_params = await drone.param.get_all_params()

    for param in all_params.int_params:
        print(f"{param.name}: {param.value}")

    for param in all_params.float_params:
        print(f"{param.name}: {param.value}")


asyncio.run(run())
