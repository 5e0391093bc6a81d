"""Command line: `python -m gcs serve` (the service and map page). `up` and `report` are added by the lead."""

from __future__ import annotations

import argparse
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
    return parser


def settings_from_args(args: argparse.Namespace) -> Settings:
    return Settings(
        vehicle_url=args.vehicle,
        host=args.host,
        port=args.port,
        db_path=args.db,
        token=Settings.token_from_env(args.token),
        vehicle_wait_s=args.vehicle_wait,
    )


def serve(settings: Settings) -> None:
    import uvicorn

    from gcs.app import create_app

    uvicorn.run(create_app(settings), host=settings.host, port=settings.port, log_level="info")


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
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
