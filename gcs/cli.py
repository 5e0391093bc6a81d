"""Command line: `python -m gcs serve` (the service and map page), `python -m gcs up` (the whole stack)."""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from pydantic import ValidationError

from gcs.connection import ConnectionStringError, parse_connection
from gcs.settings import DB_FILENAME, Settings
from gcs.storage import StorageError, is_postgres_url, open_storage
from planner.scenario import Weather

# `up` starts its own vehicle on this machine: by default on the port of the default vehicle connection.
DEFAULT_VEHICLE_PORT = parse_connection(Settings.default("vehicle_url")).port
MAX_VEHICLES = 64


def _help(text: str, field: str, default: object = None) -> str:
    """An option's help naming its default (the settings' own) and the environment variable that sets it."""
    shown = Settings.default(field) if default is None else default
    return f"{text} (default {shown}, or ${Settings.env_name(field)})"


def _add_service_options(parser: argparse.ArgumentParser) -> None:
    """The options `serve` and `up` share. Each defaults to None: "the settings' value" (environment, else
    Settings' default), so a default is written only in gcs.settings."""
    parser.add_argument("--host", help=_help("address to bind", "host"))
    parser.add_argument("--port", type=int, help=_help("HTTP port of the service and map page", "port"))
    parser.add_argument("--token", help=_help("API token for mutating endpoints and /ws", "token", "none"))
    parser.add_argument(
        "--cors-origin",
        dest="cors_origins",
        action="append",
        metavar="ORIGIN",
        help=_help("let pages of this origin (https://host[:port]) call the API; repeatable", "cors_origins", "none"),
    )
    parser.add_argument(
        "--signing-key",
        metavar="KEY",
        help=_help("MAVLink 2 signing key (64 hex digits, or a passphrase), as the vehicle's", "signing_key", "none"),
    )


def _add_database_option(parser: argparse.ArgumentParser, what: str) -> None:
    """--db: a SQLite file or a PostgreSQL URL (settings_from_args sorts it into db_path or db)."""
    db_default = f"{Settings.default('data_dir')}/{DB_FILENAME}"
    parser.add_argument(
        "--db",
        dest="database",
        metavar="FILE|URL",
        help=f"{what}: a SQLite file (default {db_default}, or ${Settings.env_name('db_path')}) or a PostgreSQL "
        f"database, postgresql://USER[:PASSWORD]@HOST:PORT/NAME (or ${Settings.env_name('db')})",
    )


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="buoy-gcs", description="Ground-control mission service for buoy inspection")
    commands = parser.add_subparsers(dest="command", required=True)
    serve = commands.add_parser("serve", help="serve the REST API, the WebSocket and the map page")
    serve.add_argument(
        "--vehicle",
        dest="vehicles",
        action="append",
        metavar="[SYSID=]URL",
        help=_help(
            "MAVLink connection: udpout://HOST:PORT, udpin://[HOST]:PORT, tcp://HOST:PORT or "
            "serial:///dev/DEVICE[:BAUD]; SYSID=URL takes only that system's autopilot; repeat it for a fleet, "
            "SYSID=URL each (vehicles may share a connection, as a router delivers them)",
            "vehicle_url",
        ),
    )
    _add_service_options(serve)
    _add_database_option(serve, "the service's database")
    serve.add_argument(
        "--vehicle-wait",
        dest="vehicle_wait_s",
        type=float,
        metavar="SECONDS",
        help=_help("seconds a mission waits for a vehicle", "vehicle_wait_s"),
    )
    serve.add_argument(
        "--heartbeat-timeout",
        dest="heartbeat_timeout_s",
        type=float,
        metavar="SECONDS",
        help=_help(
            "seconds without a vehicle heartbeat before its link counts as lost (raise it for a lossy radio)",
            "heartbeat_timeout_s",
        ),
    )
    serve.add_argument(
        "--instance-name",
        dest="instance_name",
        metavar="NAME",
        help=_help("this instance's name, shown to the others on a shared database", "instance_name", "HOST:PID"),
    )
    serve.add_argument(
        "--vehicle-name",
        dest="vehicle_name",
        metavar="NAME",
        help=_help(
            "the vehicle's name for the link lease, when instances reach it by different connection strings",
            "vehicle_name",
            "the --vehicle string",
        ),
    )
    report = commands.add_parser(
        "report",
        help="draw a mission's report (PNG figures + index.html)",
        description="The paper's Section VI from one recorded mission: route, flown "
        "track, tracking error, altitude and yaw tracking, ESO estimates.",
    )
    report.add_argument("mission_id", type=int, metavar="MISSION_ID")
    _add_database_option(report, "the service's database")
    report.add_argument(
        "--out",
        type=Path,
        default=None,
        metavar="DIR",
        help="folder for the report (default: reports/mission-ID beside the database)",
    )
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
        choices=("adrc", "pid", "px4"),  # gcs.up.CONTROLLERS (not imported here: gcs.up loads the planner)
        default="adrc",
        help="adrc (default): the cascade dual ADRC, ADRC offboard outer loop over the vehicle's ADRC attitude "
        "loop (MC_ATT_CTRL=1); pid: the PID cascade (PID outer loop, MC_ATT_CTRL=0); px4: the vehicle's own "
        "position and attitude loops, no offboard process",
    )
    _add_service_options(up)
    vehicle = up.add_mutually_exclusive_group()
    vehicle.add_argument(
        "--vehicle-port",
        type=int,
        default=DEFAULT_VEHICLE_PORT,
        help=f"UDP port the simulated vehicle listens on (default {DEFAULT_VEHICLE_PORT})",
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
        help=_help("data directory (database, logs, parameters)", "data_dir"),
    )
    _add_database_option(up, "the service's database (default in the data directory)")
    up.add_argument("--demo", action="store_true", help="fly the paper's reference scenario and print its report")
    up.add_argument("--demo-seed", type=int, default=1, help="which reference scenario the demo flies")
    up.add_argument("--exit-after-demo", action="store_true", help="stop the stack once the demo has flown")
    up.add_argument(
        "--compare",
        action="store_true",
        help="after the demo, restart the stack with the PID cascade, fly the demo again on the same seed and "
        "weather and print both side by side (and a figure of the tracking error around the gust)",
    )
    return parser


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


def _weather(args: argparse.Namespace) -> Weather | None:
    """The air `up` asks of the vehicle: None for the default (the demo's paper weather, else still air)."""
    if args.calm:
        return Weather()
    if args.wind is not None:
        speed, from_deg = args.wind
        return Weather(wind_m_s=speed, wind_from_deg=from_deg)
    return None


def settings_from_args(args: argparse.Namespace, **overrides: object) -> Settings:
    """The settings with every option given on the command line (options left at None keep the environment's
    value, else the default). Raises pydantic's ValidationError for a value of the wrong type."""
    given = {name: value for name, value in vars(args).items() if name in Settings.model_fields and value is not None}
    return Settings(**{**given, **_database(getattr(args, "database", None)), **overrides})


def _database(option: str | None) -> dict[str, object]:
    """--db's settings: a PostgreSQL URL is `db`; a file is `db_path` and overrides a $BUOY_GCS_DB URL."""
    if option is None:
        return {}
    if is_postgres_url(option):
        return {"db": option}
    return {"db": None, "db_path": Path(option)}


def _settings_error(error: ValidationError) -> str:
    first = error.errors()[0]
    where = ".".join(str(part) for part in first["loc"])
    return f"{where} ({Settings.env_name(where.split('.')[0])}): {first['msg']}"


def check_serve(settings: Settings) -> str | None:
    """Why `serve` cannot start with these settings, or None: a bad vehicle connection or port, or a database
    that cannot be opened (opened and migrated now, so a bad --db is a message, not a server traceback)."""
    try:
        parse_connection(settings.vehicle_url)
    except ConnectionStringError as error:
        return str(error)
    if not 0 < settings.port < 65536:
        return f"--port {settings.port} is not a TCP port"
    try:
        open_storage(settings.database).close()
    except StorageError as error:
        return f"--db: {error}"
    return None


def serve(settings: Settings) -> None:
    import uvicorn

    from gcs.app import create_app

    uvicorn.run(create_app(settings), host=settings.host, port=settings.port, log_level="info")


def up(args: argparse.Namespace) -> int:
    from gcs.up import UpOptions, run_up

    if args.speed is not None and not (math.isfinite(args.speed) and 0 < args.speed <= 1000):
        print("buoy-gcs: --speed must be in (0, 1000]", file=sys.stderr)
        return 2
    if not 0 < args.vehicle_port < 65536:
        print(f"buoy-gcs: --vehicle-port {args.vehicle_port} is not a port", file=sys.stderr)
        return 2
    external = args.vehicle_url is not None
    if not 1 <= args.fleet_size <= MAX_VEHICLES:
        print(f"buoy-gcs: --vehicles must be 1 to {MAX_VEHICLES}", file=sys.stderr)
        return 2
    if external and (args.fleet_size > 1 or args.depots):
        print("buoy-gcs: --vehicles and --depot simulate vehicles; they do not go with --vehicle", file=sys.stderr)
        return 2
    if args.vehicle_port + args.fleet_size - 1 >= 65536:
        print(
            f"buoy-gcs: {args.fleet_size} vehicles from port {args.vehicle_port} run past port 65535", file=sys.stderr
        )
        return 2
    if args.compare and not args.demo:
        print("buoy-gcs: --compare compares two demo flights; it needs --demo", file=sys.stderr)
        return 2
    if external and args.demo:
        print("buoy-gcs: --demo flies the simulated reference scenario; it does not go with --vehicle", file=sys.stderr)
        return 2
    # without --vehicle the service talks to the vehicle `up` starts, whatever $BUOY_GCS_VEHICLE_URL names
    vehicle_url = args.vehicle_url if external else f"udpout:127.0.0.1:{args.vehicle_port}"
    settings = settings_from_args(args, vehicle_url=vehicle_url)
    if (problem := check_serve(settings)) is not None:
        print(f"buoy-gcs: {problem}", file=sys.stderr)
        return 2
    options = UpOptions(
        settings=settings,
        lockstep=args.speed is None,
        speed=args.speed or 1.0,
        seed=args.seed,
        weather=_weather(args),
        controller=args.controller,
        simulate=not external,
        demo=args.demo,
        demo_seed=args.demo_seed,
        exit_after_demo=args.exit_after_demo,
        compare=args.compare,
        vehicles=args.fleet_size,
        depots=tuple(args.depots or ()),
    )
    return run_up(options, say=lambda text: print(text, flush=True))


def report(args: argparse.Namespace) -> int:
    """`python -m gcs report`: a missing database or an unknown mission is a message and exit 2."""
    from gcs.report import ReportError, cached_report, write_stored_report

    settings = settings_from_args(args)
    if settings.db is None and not settings.db_path.is_file():
        print(f"buoy-gcs: no database at {settings.db_path} (give the service's --db)", file=sys.stderr)
        return 2
    try:
        storage = open_storage(settings.database)
    except StorageError as error:
        print(f"buoy-gcs: --db: {error}", file=sys.stderr)
        return 2
    try:
        if args.out is None:
            index = cached_report(storage, args.mission_id, settings.reports_dir)
        else:
            record = storage.get_mission(args.mission_id)
            if record is None:
                raise ReportError(f"no mission {args.mission_id} in {storage.location}")
            index = write_stored_report(storage, record, args.out)
    except ReportError as error:
        print(f"buoy-gcs: {error.args[0]}", file=sys.stderr)
        return 2
    except OSError as error:
        print(f"buoy-gcs: cannot write the report: {error}", file=sys.stderr)
        return 2
    finally:
        storage.close()
    print(index)
    return 0


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        if args.command == "up":
            return up(args)
        if args.command == "report":
            return report(args)
        settings = settings_from_args(args)
    except ValidationError as error:  # an option or a BUOY_GCS_ variable of the wrong type
        print(f"buoy-gcs: {_settings_error(error)}", file=sys.stderr)
        return 2
    if (problem := check_serve(settings)) is not None:
        print(f"buoy-gcs: {problem}", file=sys.stderr)
        return 2
    serve(settings)
    return 0
