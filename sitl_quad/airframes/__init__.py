"""Airframe parameter files (JSON) shipped with the package; loaded by sitl_quad.airframe."""
