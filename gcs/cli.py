"""Command line: `python -m gcs serve` (the service and map page), `python -m gcs up` (the whole stack)."""

from __future__ import annotations

import argparse
import math
import sqlite3
import sys
from pathlib import Path

from gcs.link import parse_udpout
from gcs.settings import TOKEN_ENV, Settings
from gcs.storage import Storage, StorageError


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="buoy-gcs", description="Ground-control mission service for buoy inspection")
    commands = parser.add_subparsers(dest="command", required=True)
    serve = commands.add_parser("serve", help="serve the REST API, the WebSocket and the map page")
    serve.add_argument("--vehicle", default="udpout:127.0.0.1:14540", help="MAVLink connection (udpout:HOST:PORT)")
    serve.add_argument("--host", default="127.0.0.1", help="address to bind (default loopback only)")
    serve.add_argument("--port", type=int, default=8000)
    serve.add_argument("--db", type=Path, default=Path("data/gcs.sqlite"), help="SQLite file")
    serve.add_argument("--token", default=None, help=f"API token for mutating endpoints (or ${TOKEN_ENV})")
    serve.add_argument("--vehicle-wait", type=float, default=5.0, help="seconds a mission waits for a vehicle")
    serve.add_argument(
        "--signing-key",
        default=None,
        metavar="KEY",
        help="MAVLink 2 signing key (64 hex digits, or a passphrase), as the vehicle's --signing-key",
    )
    report = commands.add_parser(
        "report",
        help="draw a mission's report (PNG figures + index.html)",
        description="The paper's Section VI from one recorded mission: route, flown "
        "track, tracking error, altitude and yaw tracking, ESO estimates.",
    )
    report.add_argument("mission_id", type=int, metavar="MISSION_ID")
    report.add_argument("--db", type=Path, default=Path("data/gcs.sqlite"), help="SQLite file of the service")
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
    up.add_argument(
        "--wind",
        type=_wind,
        default=(0.0, 0.0),
        metavar="SPEED[,FROM_DEG]",
        help="steady wind in m/s, blowing from FROM_DEG (default calm)",
    )
    up.add_argument(
        "--controller",
        choices=("adrc", "pid", "none"),
        default="adrc",
        help="outer loop: the ADRC process (default), the PID baseline, or none (the vehicle's own)",
    )
    up.add_argument("--host", default="127.0.0.1")
    up.add_argument("--port", type=int, default=8000, help="HTTP port of the service and map page")
    up.add_argument("--vehicle-port", type=int, default=14540, help="UDP port the vehicle listens on")
    up.add_argument("--data", type=Path, default=Path("data"), help="data directory (database, logs, parameters)")
    up.add_argument("--token", default=None, help=f"API token for mutating endpoints (or ${TOKEN_ENV})")
    up.add_argument("--demo", action="store_true", help="fly the paper's reference scenario and print its report")
    up.add_argument("--demo-seed", type=int, default=1, help="which reference scenario the demo flies")
    up.add_argument("--exit-after-demo", action="store_true", help="stop the stack once the demo has flown")
    up.add_argument(
        "--signing-key",
        default=None,
        metavar="KEY",
        help="MAVLink 2 signing key shared by the vehicle, the offboard controller and the service",
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


def settings_from_args(args: argparse.Namespace) -> Settings:
    return Settings(
        vehicle_url=args.vehicle,
        host=args.host,
        port=args.port,
        db_path=args.db,
        token=Settings.token_from_env(args.token),
        vehicle_wait_s=args.vehicle_wait,
        signing_key=args.signing_key,
    )


def serve(settings: Settings) -> None:
    import uvicorn

    from gcs.app import create_app

    uvicorn.run(create_app(settings), host=settings.host, port=settings.port, log_level="info")


def up(args: argparse.Namespace) -> int:
    from gcs.up import UpOptions, run_up

    if args.speed is not None and not (math.isfinite(args.speed) and 0 < args.speed <= 1000):
        print("buoy-gcs: --speed must be in (0, 1000]", file=sys.stderr)
        return 2
    for name in ("port", "vehicle_port"):
        if not 0 < getattr(args, name) < 65536:
            print(f"buoy-gcs: --{name.replace('_', '-')} {getattr(args, name)} is not a port", file=sys.stderr)
            return 2
    options = UpOptions(
        lockstep=args.speed is None,
        speed=args.speed or 1.0,
        seed=args.seed,
        wind_m_s=args.wind[0],
        wind_from_deg=args.wind[1],
        controller=args.controller,
        host=args.host,
        port=args.port,
        vehicle_port=args.vehicle_port,
        data_dir=args.data,
        demo=args.demo,
        demo_seed=args.demo_seed,
        exit_after_demo=args.exit_after_demo,
        token=Settings.token_from_env(args.token),
        signing_key=args.signing_key,
    )
    return run_up(options, say=lambda text: print(text, flush=True))


def report(args: argparse.Namespace) -> int:
    """`python -m gcs report`: a missing database or an unknown mission is a message and exit 2."""
    from gcs.report import ReportError, cached_report, write_report

    if not args.db.is_file():
        print(f"buoy-gcs: no database at {args.db} (give the service's --db file)", file=sys.stderr)
        return 2
    try:
        storage = Storage(args.db)
    except (StorageError, OSError, sqlite3.Error) as error:
        print(f"buoy-gcs: --db {args.db}: {error}", file=sys.stderr)
        return 2
    try:
        if args.out is None:
            index = cached_report(storage, args.mission_id, args.db.parent / "reports")
        else:
            record = storage.get_mission(args.mission_id)
            if record is None:
                raise ReportError(f"no mission {args.mission_id} in {args.db}")
            index = write_report(record, storage.telemetry(args.mission_id), args.out)
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
    if args.command == "up":
        return up(args)
    if args.command == "report":
        return report(args)
    if args.command == "serve":
        try:
            parse_udpout(args.vehicle)
        except ValueError as error:
            print(f"buoy-gcs: {error}", file=sys.stderr)
            return 2
        if not 0 < args.port < 65536:
            print(f"buoy-gcs: --port {args.port} is not a TCP port", file=sys.stderr)
            return 2
        try:  # open (and migrate) the database now, so a bad --db is a message, not a server traceback
            Storage(args.db).close()
        except (StorageError, OSError) as error:
            print(f"buoy-gcs: --db {args.db}: {error}", file=sys.stderr)
            return 2
        serve(settings_from_args(args))
    return 0
