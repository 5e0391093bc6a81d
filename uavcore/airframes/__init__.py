"""Airframe parameter files (JSON) shipped with the package; loaded by uavcore.airframe."""
