"""The vehicle side: a MAVLink link to any PX4 or ArduPilot vehicle (connection strings, commands, mission and
parameter protocols)."""
