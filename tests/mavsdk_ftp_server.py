"""A MAVLink FTP server nobody here wrote: MAVSDK 4's FtpServer plugin, for testing the ground station's client.

MAVSDK (the native `mavsdk` 4 package) answers the protocol itself; this file only gives it a directory. The
autopilot component (1) sends the heartbeat the ground station discovers the vehicle by; `--component 100` puts
the FtpServer on a camera component of the same system instead (MAVSDK sends that component's heartbeat too).

    python tests/mavsdk_ftp_server.py --connect udpout://127.0.0.1:PORT --root DIR [--component 100]

It prints "ready" once serving and runs until SIGTERM.
"""

from __future__ import annotations

import argparse
import signal
import threading

from mavsdk import ComponentType, Configuration, Mavsdk
from mavsdk.plugins.ftp_server import FtpServer

COMPONENT_TYPES = {1: ComponentType.AUTOPILOT, 100: ComponentType.CAMERA}


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--connect", required=True, help="MAVSDK connection URL, e.g. udpout://127.0.0.1:14550")
    parser.add_argument("--root", required=True, help="the directory served")
    parser.add_argument("--component", type=int, choices=sorted(COMPONENT_TYPES), default=1)
    args = parser.parse_args()

    mavsdk = Mavsdk(Configuration.create_with_component_type(ComponentType.AUTOPILOT))
    result = mavsdk.add_any_connection(args.connect)
    print(f"connection {args.connect}: {result}", flush=True)
    component = mavsdk.server_component_by_type(COMPONENT_TYPES[args.component])
    ftp = FtpServer(component)
    ftp.set_root_dir(args.root)

    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    signal.signal(signal.SIGINT, lambda *_: stop.set())
    print("ready", flush=True)
    stop.wait()
    mavsdk.destroy()


if __name__ == "__main__":
    main()
