"""Command line: `python -m gcs serve` (the service and map page), `python -m gcs report` (a mission's figures).

`buoy-gcs` is this command line with `up` added (stack.cli: the whole stack, vehicle and controller included);
the ground station itself starts no vehicle. The option helpers are public for that reason."""

from __future__ import annotations

import argparse
import json
import logging
import sys
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pydantic import ValidationError

from gcs.settings import DB_FILENAME, Settings
from gcs.vehicle.connection import ConnectionStringError, parse_connection

if TYPE_CHECKING:  # the chart reader (GDAL, shapely) loads only for `chart`
    from shapely.geometry.base import BaseGeometry

    from gcs.domain.charted_marks import ChartImport

LOG_FORMAT = "%(asctime)s %(levelname)s %(name)s: %(message)s"
# On SIGTERM uvicorn waits this long for requests in progress and /ws clients before it cancels them, then the
# service stops (a mission in flight handed over or failed, its samples stored): a client that never closes its
# connection must not keep a stopping service alive until its supervisor kills it mid-write.
SHUTDOWN_GRACE_S = 5  # whole seconds (uvicorn takes an int)


def option_help(text: str, field: str, default: object = None) -> str:
    """An option's help naming its default (the settings' own) and the environment variable that sets it."""
    shown = Settings.default(field) if default is None else default
    return f"{text} (default {shown}, or ${Settings.env_name(field)})"


def add_ais_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--ais",
        dest="ais_sources",
        action="append",
        metavar="URL",
        help=option_help(
            "an NMEA AIS feed of AtoN reports: udp://[HOST]:PORT listens (a receiver's datagrams, e.g. "
            "udp://0.0.0.0:10110), tcp://HOST:PORT connects to a shore station or receiver; repeatable",
            "ais_sources",
            "none",
        ),
    )


def add_service_options(parser: argparse.ArgumentParser) -> None:
    """The options `serve` and `up` share. Each defaults to None: "the settings' value" (environment, else
    Settings' default), so a default is written only in gcs.settings."""
    parser.add_argument("--host", help=option_help("address to bind", "host"))
    parser.add_argument("--port", type=int, help=option_help("HTTP port of the service and map page", "port"))
    parser.add_argument("--token", help=option_help("API token for mutating endpoints and /ws", "token", "none"))
    parser.add_argument(
        "--cors-origin",
        dest="cors_origins",
        action="append",
        metavar="ORIGIN",
        help=option_help(
            "let pages of this origin (https://host[:port]) call the API; repeatable", "cors_origins", "none"
        ),
    )
    parser.add_argument(
        "--signing-key",
        metavar="KEY",
        help=option_help(
            "MAVLink 2 signing key (64 hex digits, or a passphrase), as the vehicle's", "signing_key", "none"
        ),
    )


def add_database_option(parser: argparse.ArgumentParser, what: str) -> None:
    """--db: a SQLite file or a PostgreSQL URL (settings_from_args sorts it into db_path or db)."""
    db_default = f"{Settings.default('data_dir')}/{DB_FILENAME}"
    parser.add_argument(
        "--db",
        dest="database",
        metavar="FILE|URL",
        help=f"{what}: a SQLite file (default {db_default}, or ${Settings.env_name('db_path')}) or a PostgreSQL "
        f"database, postgresql://USER[:PASSWORD]@HOST:PORT/NAME (or ${Settings.env_name('db')})",
    )


def build_parser(
    more_commands: Callable[[Any], None] | None = None, prog: str = "python -m gcs"
) -> argparse.ArgumentParser:
    """`serve` and `report`; `more_commands(subparsers)` may add others (stack.cli adds `up` for `buoy-gcs`)."""
    parser = argparse.ArgumentParser(
        prog=prog,
        description="Ground-control mission service for buoy inspection",
        epilog="The whole stack on this machine (simulated vehicle, offboard controller, this service): buoy-gcs up "
        "(python -m stack up).",
    )
    commands = parser.add_subparsers(dest="command", required=True)
    serve = commands.add_parser("serve", help="serve the REST API, the WebSocket and the map page")
    serve.add_argument(
        "--vehicle",
        dest="vehicles",
        action="append",
        metavar="[SYSID=]URL",
        help=option_help(
            "MAVLink connection: udpout://HOST:PORT, udpin://[HOST]:PORT, tcp://HOST:PORT or "
            "serial:///dev/DEVICE[:BAUD]; SYSID=URL takes only that system's autopilot; repeat it for a fleet, "
            "SYSID=URL each (vehicles may share a connection, as a router delivers them)",
            "vehicle_url",
        ),
    )
    add_service_options(serve)
    add_database_option(serve, "the service's database")
    add_ais_option(serve)
    serve.add_argument(
        "--vehicle-wait",
        dest="vehicle_wait_s",
        type=float,
        metavar="SECONDS",
        help=option_help("seconds a mission waits for a vehicle", "vehicle_wait_s"),
    )
    serve.add_argument(
        "--heartbeat-timeout",
        dest="heartbeat_timeout_s",
        type=float,
        metavar="SECONDS",
        help=option_help(
            "seconds without a vehicle heartbeat before its link counts as lost (raise it for a lossy radio)",
            "heartbeat_timeout_s",
        ),
    )
    serve.add_argument(
        "--instance-name",
        dest="instance_name",
        metavar="NAME",
        help=option_help("this instance's name, shown to the others on a shared database", "instance_name", "HOST:PID"),
    )
    serve.add_argument(
        "--vehicle-name",
        dest="vehicle_name",
        metavar="NAME",
        help=option_help(
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
    add_database_option(report, "the service's database")
    report.add_argument(
        "--out",
        type=Path,
        default=None,
        metavar="DIR",
        help="folder for the report (default: reports/mission-ID beside the database)",
    )
    add_chart_command(commands)
    if more_commands is not None:
        more_commands(commands)
    return parser


def add_chart_command(commands: Any) -> None:
    """`chart`: the buoys and beacons of an S-57 cell, as POST /imports reads them."""
    chart = commands.add_parser(
        "chart",
        help="list the buoys and beacons of an S-57 chart cell (.000), and write them as a world file",
        description="Read an S-57 ENC cell (with its update files beside it) as POST /imports does: each buoy and "
        "beacon with its kind, light, colours and position, and what could not be mapped.",
    )
    chart.add_argument("cell", type=Path, metavar="CELL.000", help="the cell's base file")
    chart.add_argument(
        "--area",
        metavar="AREA",
        help="only the marks inside: west,south,east,north in degrees (--area=W,S,E,N when W is negative), a "
        "GeoJSON Polygon, or a file holding one",
    )
    chart.add_argument(
        "--region",
        dest="iala_region",
        choices=("A", "B"),
        help=option_help("IALA region of marks the cell places in none (its own MARSYS wins)", "iala_region"),
    )
    chart.add_argument(
        "--geojson",
        type=Path,
        metavar="OUT",
        help="write the marks as GeoJSON that POST /imports and sitl-quad --world read",
    )


def settings_from_args(args: argparse.Namespace, **overrides: object) -> Settings:
    """The settings with every option given on the command line (options left at None keep the environment's
    value, else the default). Raises pydantic's ValidationError for a value of the wrong type."""
    given = {name: value for name, value in vars(args).items() if name in Settings.model_fields and value is not None}
    return Settings(**{**given, **_database(getattr(args, "database", None)), **overrides})


def _database(option: str | None) -> dict[str, object]:
    """--db's settings: a PostgreSQL URL is `db`; a file is `db_path` and overrides a $BUOY_GCS_DB URL."""
    if option is None:
        return {}
    from gcs.storage import is_postgres_url  # here, as in check_serve: see there

    if is_postgres_url(option):
        return {"db": option}
    return {"db": None, "db_path": Path(option)}


def settings_error(error: ValidationError) -> str:
    first = error.errors()[0]
    where = ".".join(str(part) for part in first["loc"])
    return f"{where} ({Settings.env_name(where.split('.')[0])}): {first['msg']}"


def check_serve(settings: Settings) -> str | None:
    """Why `serve` cannot start with these settings, or None: a bad vehicle connection or port, or a database
    that cannot be opened (opened and migrated now, so a bad --db is a message, not a server traceback)."""
    # not at the top: the storage loads the domain and the planner (seconds on a busy machine), and `up` answers
    # before that whether its ports are free (stack.ports)
    from gcs.storage import StorageError, open_storage

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
    """Run the service until SIGINT or SIGTERM; SIGUSR1 writes its threads' and tasks' stacks to the log."""
    import uvicorn

    from gcs.api.app import create_app
    from gcs.api.stack_dump import install_stack_dump

    # one format for uvicorn's lines and ours, with the time: a log read after an incident must say when
    logging.basicConfig(level=logging.INFO, format=LOG_FORMAT)
    install_stack_dump()
    uvicorn.run(
        create_app(settings, freeze_startup_heap=True),
        host=settings.host,
        port=settings.port,
        log_level="info",
        log_config=None,
        timeout_graceful_shutdown=SHUTDOWN_GRACE_S,
    )


def report(args: argparse.Namespace) -> int:
    """`python -m gcs report`: a missing database or an unknown mission is a message and exit 2."""
    from gcs.reports.report import ReportError, cached_report, write_stored_report
    from gcs.storage import StorageError, open_storage

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
    return run(build_parser().parse_args(argv))


def chart(args: argparse.Namespace) -> int:
    """`python -m gcs chart`: the table on stdout, the warnings on stderr; a file that gives no buoys (not a cell,
    damaged, none in the area) is a message and exit 2."""
    from gcs.charts import read_cell
    from gcs.domain.areas import AreaError
    from gcs.domain.charted_marks import ChartError, world_of

    try:
        area = None if args.area is None else _area(args.area)
        result = read_cell(args.cell, settings_from_args(args).iala_region, area)
    except (AreaError, ChartError) as error:
        print(f"buoy-gcs: chart: {error}", file=sys.stderr)
        return 2
    print("\n".join(chart_table(result)))
    warnings = list(result.warnings)
    if args.geojson is not None:
        world, left_out = world_of(result.marks)
        warnings += left_out
        try:
            args.geojson.write_text(json.dumps(world.to_geojson(), indent=1) + "\n", encoding="utf-8")
        except OSError as error:
            print(f"buoy-gcs: chart: cannot write {args.geojson}: {error.strerror}", file=sys.stderr)
            return 2
        print(f"wrote {args.geojson}: {len(world.buoys)} of the {len(result.marks)} marks")
    for warning in warnings:
        print(f"warning: {warning}", file=sys.stderr)
    return 0


def _area(text: str) -> BaseGeometry:
    """--area: the text itself, or the file it names (AreaError, as a bad area, if it cannot be read)."""
    from gcs.domain.areas import AreaError, parse_area

    path = Path(text)
    if not text.lstrip().startswith("{") and path.is_file():
        try:
            text = path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as error:
            raise AreaError(f"{path}: cannot be read: {error}") from None
    return parse_area(text)


def chart_table(result: ChartImport) -> list[str]:
    """The marks as a text table, then a line on the cell."""
    rows = [("id", "kind", "mark", "light", "colours", "lat", "lon", "name")]
    for m in result.marks:
        what = "beacon" if m.beacon else "buoy"
        colours = "/".join(m.colours) or "-"
        rows.append((m.id, m.kind or "?", what, m.light or "-", colours, f"{m.lat:.6f}", f"{m.lon:.6f}", m.name or ""))
    widths = [max(len(row[i]) for row in rows) for i in range(len(rows[0]) - 1)]  # the name, last, runs on
    lines = ["  ".join(c.ljust(w) for c, w in zip(row[:-1], widths, strict=True)) + "  " + row[-1] for row in rows]
    cell, buoys = result.cell, sum(not m.beacon for m in result.marks)
    lines.append(
        f"{cell.name} (edition {cell.edition}, update {cell.update}, issued {cell.issued}), IALA region "
        f"{result.region} ({'the chart' if result.region_source == 'chart' else 'the default'}'s): "
        f"{len(result.marks)} marks, {buoys} buoys and {len(result.marks) - buoys} beacons, "
        f"{sum(m.light is not None for m in result.marks)} lit"
    )
    return lines


def run(args: argparse.Namespace) -> int:
    """`serve`, `report` or `chart`, from parsed arguments: a bad option is a message and exit 2."""
    try:
        if args.command == "report":
            return report(args)
        if args.command == "chart":
            return chart(args)
        settings = settings_from_args(args)
    except ValidationError as error:  # an option or a BUOY_GCS_ variable of the wrong type
        print(f"buoy-gcs: {settings_error(error)}", file=sys.stderr)
        return 2
    if (problem := check_serve(settings)) is not None:
        print(f"buoy-gcs: {problem}", file=sys.stderr)
        return 2
    serve(settings)
    return 0
