"""The vehicle's MAVLink side: one module per capability, like MAVSDK's plugins.

link (UDP peers, parsing, routing), heartbeat, parameters, commands, mission, telemetry, offboard.
The physics and the autopilot functions know nothing of this package.
"""

import os

# pymavlink picks its wire protocol at import time: speak MAVLink 2 everywhere.
os.environ.setdefault("MAVLINK20", "1")

from pymavlink.dialects.v20 import common as mavlink

__all__ = ["mavlink"]
