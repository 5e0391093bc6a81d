"""Compile (or load from numba's on-disk cache) every kernel the vehicle flies with.

The vehicle runs `warm_up` before it listens (sitl_quad.cli), so no ground station waits on a compile at its first
armed tick. `make` runs `python -m sitl_quad.warmup` once after installing, so that vehicles started later load
the kernels from the cache instead of each compiling them: several vehicles started at once on a busy 2-core
machine (a test suite's workers) each took over a minute to compile the same kernels before they listened.
"""

from __future__ import annotations

import copy
import dataclasses
import time

from sitl_quad.attitude_loops import attitude_loops
from sitl_quad.config import AttitudeControllerKind, ControlConfig, VehicleConfig
from sitl_quad.vehicle import Vehicle
from sitl_quad.wind import WindConfig
from uavcore.geodesy import DEFAULT_HOME

# Air with every part of the wind model in it (mean wind, gust, turbulence), so their kernels are compiled too;
# a scratch vehicle's air changes nothing of the vehicle that flies afterwards.
SCRATCH_AIR = WindConfig(speed_m_s=3.0, gust_amplitude_m_s=1.0, turbulence_w20_m_s=1.0)


def warm_up(
    config: VehicleConfig | None = None,
    home: tuple[float, float, float] = DEFAULT_HOME,
    outer_rate_hz: float = 50.0,
) -> float:
    """Fly a throwaway copy of the vehicle for two seconds with each attitude loop MC_ATT_CTRL can select (a
    parameter may switch loops later) in gusty, turbulent air. Returns the seconds it took."""
    started = time.perf_counter()
    for kind in AttitudeControllerKind:
        scratch_config = copy.deepcopy(config or VehicleConfig())
        scratch_config.control = ControlConfig(attitude_controller=kind)
        scratch_config.wind = dataclasses.replace(SCRATCH_AIR)
        scratch = Vehicle(
            scratch_config, home=home, seed=0, outer_rate_hz=outer_rate_hz, attitude_loops=attitude_loops()
        )
        scratch.arm()
        scratch.takeoff(2.0)
        for _ in range(round(2.0 * outer_rate_hz)):  # spool-up, then climbing under the onboard loops
            scratch.tick()
    return time.perf_counter() - started


if __name__ == "__main__":
    print(f"vehicle kernels compiled or loaded in {warm_up():.1f} s")
