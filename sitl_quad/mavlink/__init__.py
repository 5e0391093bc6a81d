"""The vehicle's MAVLink side: one module per capability, like MAVSDK's plugins.

link (UDP peers, parsing, routing), heartbeat, parameters, commands, mission, telemetry, offboard, ftp; the payload
(payload): gimbal (the manager), camera (component 100) and camera_frames (its frames made into files).
The physics and the autopilot functions know nothing of this package. The codec itself (dialect, framing,
signing, ids) is `uavcore.mavlink`, shared with every other process.
"""
