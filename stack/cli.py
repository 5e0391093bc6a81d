"""`buoy-gcs`: the ground station's command line (gcs.cli: `serve`, `report`) with `up`, the whole stack on this
machine: simulated vehicles, their offboard controllers and the service as supervised children (stack.up)."""

from __future__ import annotations

import argparse
import math
import os
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from gcs.cli import (
    add_ais_option,
    add_database_option,
    add_service_options,
    check_serve,
    option_help,
    run,
    settings_error,
    settings_from_args,
)
from gcs.cli import build_parser as gcs_parser
from gcs.settings import Settings
from gcs.vehicle.connection import parse_connection
from planner.scenario import Weather
from stack.options import CONTROLLERS, UpOptions
from stack.ports import BusyPortError, choose, service_port, vehicle_port

# `up` starts its own vehicle on this machine: by default on the port of the default vehicle connection.
DEFAULT_VEHICLE_PORT = parse_connection(Settings.default("vehicle_url")).port
MAX_VEHICLES = 64


def build_parser() -> argparse.ArgumentParser:
    return gcs_parser(add_up, prog="buoy-gcs")


def add_up(commands: Any) -> None:
    """The `up` command and its options, added to the ground station's subcommands."""
    up = commands.add_parser(
        "up",
        help="the main job: vehicle + offboard controller + service, supervised",
        description="Start sitl_quad, adrc_offboard and the service as supervised children "
        "(Ctrl-C or SIGTERM stops them all); the map page is at http://HOST:PORT/.",
    )
    pacing = up.add_mutually_exclusive_group()
    pacing.add_argument(
        "--lockstep",
        action="store_true",
        default=None,
        help="vehicle and controller in lockstep: deterministic, faster than real time (default)",
    )
    pacing.add_argument("--speed", type=float, help="pace the vehicle at N times real time instead of lockstep")
    # Named for what they are for, an operator watching: --speed paces the whole run (the demo too), these only
    # what is flown after the demo (the vehicles' SIM_SPEEDUP, stack.sim_speed)
    watch = up.add_mutually_exclusive_group()
    watch.add_argument(
        "--real-time",
        dest="watch_speed",
        action="store_const",
        const=1.0,
        help="once the demo has flown (at once without --demo), the vehicles fly at real time: missions started "
        "from the map page can be watched (SIM_SPEEDUP 1; the demo itself at full speed)",
    )
    watch.add_argument(
        "--watch-speed",
        dest="watch_speed",
        type=float,
        metavar="N",
        help="the same at N times real time (SIM_SPEEDUP N, 0 < N <= 1000)",
    )
    up.add_argument("--seed", type=int, default=0, help="the vehicle's wind, turbulence and noise seed")
    air = up.add_mutually_exclusive_group()
    air.add_argument(
        "--wind",
        type=_wind,
        metavar="SPEED[,FROM_DEG]",
        help="a steady wind in m/s, blowing from FROM_DEG, and nothing else (default: still air; with --demo the "
        "paper's weather: a 5 m/s crosswind across the longest leg, a 4 m/s gust halfway along it, turbulence)",
    )
    air.add_argument("--calm", action="store_true", help="still air, the demo too")
    up.add_argument(
        "--controller",
        choices=CONTROLLERS,
        default="adrc",
        help="adrc (default): the cascade dual ADRC, ADRC offboard outer loop over the vehicle's ADRC attitude "
        "loop (MC_ATT_CTRL=1); pid: the PID cascade (PID outer loop, MC_ATT_CTRL=0); px4: the vehicle's own "
        "position and attitude loops, no offboard process",
    )
    add_service_options(up)
    vehicle = up.add_mutually_exclusive_group()
    vehicle.add_argument(
        "--vehicle-port",
        type=int,  # None: the default, or the next free port above it when that is busy (stack.ports)
        help=f"UDP port the simulated vehicle listens on (default {DEFAULT_VEHICLE_PORT}, or the next free one "
        "when it is busy)",
    )
    vehicle.add_argument(
        "--vehicle",
        dest="vehicle_url",
        metavar="URL",
        help="fly a real (or any other) vehicle instead: start only the service and map page, connected by "
        "udpin://0.0.0.0:14550 (PX4, ArduPilot, radios), udpout://, tcp:// or serial:///dev/DEVICE[:BAUD]",
    )
    up.add_argument(
        "--vehicles",
        dest="fleet_size",  # not `vehicles`: that is the service's list of vehicle links (Settings.vehicles)
        type=int,
        default=1,
        metavar="N",
        help=f"simulate a fleet of N vehicles (system ids 1..N, ports from --vehicle-port up, each with its own "
        f"offboard controller, seed --seed + id - 1); 1 to {MAX_VEHICLES} (default 1)",
    )
    up.add_argument(
        "--depot",
        dest="depots",
        type=_depot,
        action="append",
        metavar="LAT,LON",
        help="a depot the fleet's vehicles stand at (repeatable: vehicle i at depot i mod the number given; "
        "vehicles sharing a depot stand 3 m apart); default: the service's home",
    )
    up.add_argument(
        "--data",
        dest="data_dir",
        type=Path,
        metavar="DIR",
        help=option_help("data directory (database, logs, parameters)", "data_dir"),
    )
    add_database_option(up, "the service's database (default in the data directory)")
    up.add_argument(
        "--world",
        type=Path,
        metavar="FILE",
        help="the buoys the simulated vehicles' cameras see: a GeoJSON world (each buoy's charted position, kind, "
        "light and swing radius, and faults: README, World files); with it each vehicle carries a camera on a "
        "gimbal (default: none; the demo's own world with --demo)",
    )
    add_ais_option(up)
    up.add_argument(
        "--world-ais-port",
        type=int,
        default=10110,
        metavar="PORT",
        help="the simulated world's AIS: its buoys with an mmsi report themselves (message 21) to the service on "
        "this UDP port of 127.0.0.1, besides any --ais (default 10110; 0: none)",
    )
    up.add_argument("--demo", action="store_true", help="fly the paper's reference scenario and print its report")
    up.add_argument("--demo-seed", type=int, default=1, help="which reference scenario the demo flies")
    up.add_argument("--exit-after-demo", action="store_true", help="stop the stack once the demo has flown")
    up.add_argument(
        "--compare",
        action="store_true",
        help="after the demo, restart the stack with the PID cascade, fly the demo again on the same seed and "
        "weather and print both side by side (and a figure of the tracking error around the gust)",
    )


def _wind(text: str) -> tuple[float, float]:
    parts = text.split(",")
    try:
        values = [float(p) for p in parts]
    except ValueError:
        values = []
    if len(values) not in (1, 2) or not all(map(math.isfinite, values)) or not 0 <= values[0] <= 40:
        raise argparse.ArgumentTypeError(f"expected SPEED[,FROM_DEG] with 0 <= SPEED <= 40 m/s, got {text!r}")
    return values[0], values[1] if len(values) == 2 else 0.0


def _depot(text: str) -> tuple[float, float]:
    parts = text.split(",")
    try:
        lat, lon = (float(p) for p in parts)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected LAT,LON in degrees, got {text!r}") from None
    if not (math.isfinite(lat) and math.isfinite(lon) and -90 <= lat <= 90 and -180 <= lon <= 180):
        raise argparse.ArgumentTypeError(f"depot {text!r} is outside lat [-90, 90] / lon [-180, 180]")
    return lat, lon


def requested_weather(args: argparse.Namespace) -> Weather | None:
    """The air `up` asks of the vehicle: None for the default (the demo's paper weather, else still air)."""
    if args.calm:
        return Weather()
    if args.wind is not None:
        speed, from_deg = args.wind
        return Weather(wind_m_s=speed, wind_from_deg=from_deg)
    return None


def up(args: argparse.Namespace) -> int:
    if args.speed is not None and not (math.isfinite(args.speed) and 0 < args.speed <= 1000):
        print("buoy-gcs: --speed must be in (0, 1000]", file=sys.stderr)
        return 2
    if (problem := watch_problem(args)) is not None:
        print(f"buoy-gcs: {problem}", file=sys.stderr)
        return 2
    first_port = DEFAULT_VEHICLE_PORT if args.vehicle_port is None else args.vehicle_port
    if not 0 < first_port < 65536:
        print(f"buoy-gcs: --vehicle-port {first_port} is not a port", file=sys.stderr)
        return 2
    external = args.vehicle_url is not None
    if not 1 <= args.fleet_size <= MAX_VEHICLES:
        print(f"buoy-gcs: --vehicles must be 1 to {MAX_VEHICLES}", file=sys.stderr)
        return 2
    if external and (args.fleet_size > 1 or args.depots):
        print("buoy-gcs: --vehicles and --depot simulate vehicles; they do not go with --vehicle", file=sys.stderr)
        return 2
    if first_port + args.fleet_size - 1 >= 65536:
        print(f"buoy-gcs: {args.fleet_size} vehicles from port {first_port} run past port 65535", file=sys.stderr)
        return 2
    if args.compare and not args.demo:
        print("buoy-gcs: --compare compares two demo flights; it needs --demo", file=sys.stderr)
        return 2
    if not 0 <= args.world_ais_port < 65536:
        print(f"buoy-gcs: --world-ais-port {args.world_ais_port} is not a port (0: none)", file=sys.stderr)
        return 2
    if args.world is not None and (external or not args.world.is_file()):
        why = "simulated vehicles see it; it does not go with --vehicle" if external else "no such file"
        print(f"buoy-gcs: --world {args.world}: {why}", file=sys.stderr)
        return 2
    if external and args.demo:
        print("buoy-gcs: --demo flies the simulated reference scenario; it does not go with --vehicle", file=sys.stderr)
        return 2
    # without --vehicle the service talks to the vehicle `up` starts, whatever $BUOY_GCS_VEHICLE_URL names
    vehicle_url = args.vehicle_url if external else f"udpout:127.0.0.1:{first_port}"
    settings = settings_from_args(args, vehicle_url=vehicle_url)
    try:  # first: each child finds a busy port only once its kernels have loaded, check_serve loads the storage
        settings = free_ports(args, settings, say)
    except BusyPortError as error:
        print(f"buoy-gcs: {error}", file=sys.stderr)
        return 2
    if (problem := check_serve(settings)) is not None:
        print(f"buoy-gcs: {problem}", file=sys.stderr)
        return 2
    options = UpOptions(
        settings=settings,
        lockstep=args.speed is None,
        speed=args.speed or 1.0,
        seed=args.seed,
        weather=requested_weather(args),
        controller=args.controller,
        simulate=not external,
        demo=args.demo,
        demo_seed=args.demo_seed,
        exit_after_demo=args.exit_after_demo,
        compare=args.compare,
        vehicles=args.fleet_size,
        depots=tuple(args.depots or ()),
        world=args.world,
        world_ais_port=args.world_ais_port,
        watch_speed=args.watch_speed,
    )
    # not at the top: it loads the planner and the storage, which `serve` and `report` do not need, and which
    # would delay the answer on the ports by seconds
    from stack.up import run_up

    return run_up(options, say=say)


def watch_problem(args: argparse.Namespace) -> str | None:
    """What is wrong with --real-time / --watch-speed N here, or None."""
    speed = args.watch_speed
    if speed is None:
        return None
    if not (math.isfinite(speed) and 0 < speed <= 1000):
        return "--watch-speed must be in (0, 1000]"
    if args.vehicle_url is not None:
        return "--real-time and --watch-speed pace simulated vehicles; they do not go with --vehicle"
    if args.exit_after_demo:
        return "--real-time and --watch-speed pace the missions flown after the demo; --exit-after-demo flies none"
    return None


def say(text: str) -> None:
    print(text, flush=True)


def free_ports(args: argparse.Namespace, settings: Settings, say: Callable[[str], None]) -> Settings:
    """The settings on ports that are free now: the service's HTTP port, and the simulated vehicles' first UDP
    port (their links follow it); a busy default is moved up (said by `say`), a busy port the user gave (by an
    option, or the environment for --port) raises BusyPortError."""
    http = service_port(settings.host)
    given_http = args.port is not None or Settings.env_name("port") in os.environ
    overrides: dict[str, object] = {"port": choose(http, settings.port, 1, given_http, say)}
    overrides["vehicle_url"] = settings.vehicle_url
    if args.vehicle_url is None:
        vehicles = vehicle_port(args.fleet_size)
        first = parse_connection(settings.vehicle_url).port
        first = choose(vehicles, first, args.fleet_size, args.vehicle_port is not None, say)
        overrides["vehicle_url"] = f"udpout:127.0.0.1:{first}"
    return settings_from_args(args, **overrides)


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if args.command != "up":
        return run(args)
    try:
        return up(args)
    except ValidationError as error:  # an option or a BUOY_GCS_ variable of the wrong type
        print(f"buoy-gcs: {settings_error(error)}", file=sys.stderr)
        return 2
