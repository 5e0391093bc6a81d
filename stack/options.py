"""What `buoy-gcs up` is asked to start: the options, and the loops each controller flies with.

The controller chooses the loops that fly (`LOOPS`): `adrc` (default) is the paper's cascade dual ADRC, the
ADRC offboard outer loop (adrc_offboard) over the vehicle's ADRC attitude loop (MC_ATT_CTRL=1); `pid` the same
cascade with PID in both places; `px4` the vehicle's own PX4-style position and attitude loops, no offboard
process.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from gcs.settings import Settings
from planner.scenario import Weather

CONTROLLERS = ("adrc", "pid", "px4")
# controller -> (outer loop, inner loop), as the demo reports them
LOOPS = {
    "adrc": ("ADRC offboard process (adrc_offboard --controller adrc)", "ADRC attitude loop (MC_ATT_CTRL=1)"),
    "pid": ("PID offboard process (adrc_offboard --controller pid)", "PID attitude loop (MC_ATT_CTRL=0)"),
    "px4": ("the vehicle's built-in PX4-style position loop", "PID attitude loop (MC_ATT_CTRL=0)"),
}
ATTITUDE_LOOP = {"adrc": 1, "pid": 0, "px4": 0}  # the vehicle's MC_ATT_CTRL
CASCADE_NAMES = {"adrc": "cascade dual ADRC", "pid": "PID cascade", "px4": "vehicle's own loops"}


@dataclass
class UpOptions:
    # the service's settings: its host, port and token; the vehicle's UDP port (vehicle_url's); the data
    # directory (database, logs, the vehicle's parameters); the MAVLink signing key shared by all three children
    settings: Settings = field(default_factory=Settings)
    lockstep: bool = True
    speed: float = 1.0
    seed: int = 0
    weather: Weather | None = None  # None: the paper's weather on the demo's route with `demo`, still air without
    controller: str = "adrc"  # one of CONTROLLERS
    simulate: bool = True  # False: settings.vehicle_url is a real vehicle; only the service is started
    demo: bool = False
    demo_seed: int = 1  # which reference scenario to fly
    exit_after_demo: bool = False
    compare: bool = False  # after the demo, fly it again with the PID cascade and print both
    vehicles: int = 1  # simulated vehicles, system ids 1..N, on ports vehicle_port .. vehicle_port + N - 1
    depots: tuple[tuple[float, float], ...] = ()  # (lat, lon) each; vehicle i at depot i mod len (none: home)
    # the buoys the simulated vehicles' cameras see (uavcore.buoy_world's GeoJSON; None: no camera, unless the demo's)
    world: Path | None = None
    # the simulated world's AIS: the first vehicle's world reports its buoys that have an mmsi (AIS message 21) to
    # the service on this UDP port of 127.0.0.1, which listens there besides its own --ais sources; 0: none
    world_ais_port: int = 10110
    # the simulated vehicles' SIM_SPEEDUP once the demo has flown, or at once without one (--real-time: 1): the
    # missions an operator flies from the map page then go at N times real time; None: as fast as they go
    watch_speed: float | None = None

    @property
    def base_url(self) -> str:
        return f"http://{self.settings.host}:{self.settings.port}"
