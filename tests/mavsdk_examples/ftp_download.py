"""MAVSDK-Python's Ftp plugin downloading one file from the vehicle: connect as the examples beside this file do
(example_steps.py), point the plugin at a component, download.

    .venv-mavsdk3/bin/python tests/mavsdk_examples/ftp_download.py udp://:PORT GRPC_PORT COMPID PATH LOCAL_DIR MODE

MODE "burst" downloads by BurstReadFile, anything else by ReadFile. Prints "downloaded N bytes" once the file is
in LOCAL_DIR, or "FtpError: <result>" and exits 1.
"""

import asyncio
import sys

from example_steps import connect, wait_until_connected
from mavsdk.ftp import FtpError


async def run() -> int:
    component, remote_path, local_dir, burst = int(sys.argv[3]), sys.argv[4], sys.argv[5], sys.argv[6] == "burst"
    drone = await connect()
    await wait_until_connected(drone)
    await drone.ftp.set_target_compid(component)
    last = None
    try:
        async for progress in drone.ftp.download(remote_path, local_dir, burst):
            last = progress
    except FtpError as error:
        print(f"FtpError: {error._result.result}", flush=True)
        return 1
    print(f"downloaded {last.bytes_transferred if last else 0} bytes", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(asyncio.run(run()))
