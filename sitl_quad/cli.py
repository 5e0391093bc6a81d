"""`python -m sitl_quad` / `sitl-quad`: the simulated vehicle as a MAVLink UDP endpoint."""

from __future__ import annotations

import argparse
import atexit
import gc
import json
import logging
import math
import os
import shutil
import signal
import sys
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING

from uavcore.geodesy import DEFAULT_HOME
from uavcore.mavlink import SIGNING_KEY_ENV, VEHICLE_UDP_PORT, parse_signing_key

if TYPE_CHECKING:  # imported where used, after the arguments are checked: --help stays instant
    from sitl_quad.ais_out import AisOut
    from uavcore.buoy_world import World

EPILOG = """\
examples:
  sitl-quad                                   # PX4-like vehicle on udp 127.0.0.1:14540, real time
  sitl-quad --lockstep --seed 3               # deterministic, as fast as the offboard controller answers
  sitl-quad --speed 10 --out 127.0.0.1:14550  # 10x real time, also pushing to a listening QGroundControl
  sitl-quad --world buoys.geojson --image-dir img  # a camera (component 100) on a gimbal, seeing these buoys
  sitl-quad --world buoys.geojson --ais-out 127.0.0.1:10110  # its buoys with an mmsi report themselves (AIS 21)
  mavproxy.py --master=udpout:127.0.0.1:14540 # connect a ground station to it
"""


def parse_host_port(text: str) -> tuple[str, int]:
    host, _, port = text.rpartition(":")
    if not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise argparse.ArgumentTypeError(f"expected HOST:PORT, got {text!r}")
    return host, int(port)


def parse_home(text: str) -> tuple[float, float, float]:
    parts = text.split(",")
    try:
        values = [float(p) for p in parts]
    except ValueError:
        values = []
    if len(values) not in (2, 3) or not all(math.isfinite(v) for v in values):
        raise argparse.ArgumentTypeError(f"expected LAT,LON[,ALT] in degrees and metres, got {text!r}")
    lat, lon = values[0], values[1]
    if not (-90 <= lat <= 90 and -180 <= lon <= 180):
        raise argparse.ArgumentTypeError(f"home {lat},{lon} is outside lat [-90, 90] / lon [-180, 180]")
    return lat, lon, values[2] if len(values) == 3 else 0.0


def parse_param(text: str) -> tuple[str, float]:
    name, _, value = text.partition("=")
    try:
        return name.strip(), float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected NAME=VALUE, got {text!r}") from None


def parse_percent(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a percentage, got {text!r}") from None
    if not 0 <= value <= 100:
        raise argparse.ArgumentTypeError(f"a percentage is in [0, 100], got {value:g}")
    return value


def parse_current(text: str) -> tuple[float, float]:
    try:
        to_deg, speed = (float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected TO_DEG,M_S, got {text!r}") from None
    if not (math.isfinite(to_deg) and math.isfinite(speed) and speed >= 0):
        raise argparse.ArgumentTypeError(f"a current is a finite direction and a speed >= 0, got {text!r}")
    return to_deg, speed


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="sitl-quad",
        description="Software-in-the-loop quadrotor (paper eq. 1-3, Table 2) that speaks "
        "MAVLink 2 over UDP like a PX4 autopilot.",
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--host", default="127.0.0.1", help="address to listen on (default 127.0.0.1)")
    p.add_argument(
        "--port", type=int, default=VEHICLE_UDP_PORT, help=f"UDP port to listen on (default {VEHICLE_UDP_PORT})"
    )
    p.add_argument(
        "--sysid",
        type=int,
        default=1,
        choices=range(1, 256),
        metavar="N",
        help="MAVLink system id of the vehicle, 1-255 (default 1; PX4's MAV_SYS_ID)",
    )
    p.add_argument(
        "--out",
        type=parse_host_port,
        action="append",
        default=[],
        metavar="HOST:PORT",
        help="also push telemetry to this address, e.g. a listening QGroundControl (repeatable)",
    )
    pacing = p.add_mutually_exclusive_group()
    pacing.add_argument(
        "--speed",
        type=float,
        default=1.0,
        metavar="N",
        help="run simulated time N times faster than the wall clock (default 1; SIM_SPEEDUP > 0 replaces it)",
    )
    pacing.add_argument(
        "--lockstep",
        action="store_true",
        help="wait at each outer-loop tick for the offboard controller's answer; run freely while none streams "
        "(never faster than SIM_SPEEDUP times real time when that is set)",
    )
    p.add_argument("--seed", type=int, default=0, help="seed of wind, turbulence, disturbance and noise")
    p.add_argument(
        "--home",
        type=parse_home,
        default=DEFAULT_HOME,
        metavar="LAT,LON[,ALT]",
        help=f"home (the depot) in degrees and metres AMSL (default {DEFAULT_HOME})",
    )
    p.add_argument(
        "--params",
        type=Path,
        metavar="FILE",
        help="parameter file (QGC format) loaded at start and saved after every PARAM_SET",
    )
    p.add_argument(
        "--param",
        type=parse_param,
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="set one parameter at start, after --params (repeatable)",
    )
    p.add_argument(
        "--battery-percent",
        type=parse_percent,
        default=100.0,
        metavar="PERCENT",
        help="charge of the pack at start (default 100; MAV_CMD_BATTERY_RESET swaps it on the ground)",
    )
    p.add_argument(
        "--outer-rate",
        type=float,
        default=50.0,
        metavar="HZ",
        help="outer-loop (and lockstep tick) rate in Hz (default 50, PX4's position loop)",
    )
    p.add_argument(
        "--log",
        type=Path,
        metavar="FILE",
        help="write a CSV flight log: true state, estimate, reference and commands per tick",
    )
    p.add_argument(
        "--signing-key",
        type=parse_signing_key,
        default=os.environ.get(SIGNING_KEY_ENV) or None,
        metavar="KEY",
        help=f"MAVLink 2 signing key (64 hex digits, or a passphrase): unsigned messages are refused (default: "
        f"${SIGNING_KEY_ENV}, which keeps it out of ps and logs)",
    )
    p.add_argument(
        "--duration",
        type=float,
        metavar="SECONDS",
        help="exit after this much simulated time (default: run until interrupted)",
    )
    p.add_argument(
        "--stats",
        type=Path,
        metavar="FILE",
        help="at exit, write JSON counters: tick pacing, link drops by kind, mission transfers",
    )
    p.add_argument(
        "--ftp-root",
        type=Path,
        metavar="DIR",
        help="serve this directory read-only over MAVLink FTP (default: the camera's --image-dir when it carries one, "
        "else nothing: the autopilot refuses every request at once)",
    )
    p.add_argument(
        "--ftp-component",
        type=int,
        default=100,
        choices=range(1, 256),
        metavar="N",
        help="MAVLink component id serving --ftp-root (default 100, MAV_COMP_ID_CAMERA; 1 serves it as the "
        "autopilot, as PX4 serves its SD card)",
    )
    # ----- the camera on its gimbal (sitl_quad.mavlink.camera, sitl_quad.mavlink.gimbal)
    p.add_argument(
        "--world",
        type=Path,
        metavar="FILE",
        help="the buoys the camera sees: a GeoJSON world file (uavcore.buoy_world; default: open sea, no buoys)",
    )
    p.add_argument(
        "--camera",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="carry a camera (MAVLink component 100) on a gimbal managed by the autopilot (default: with --world)",
    )
    p.add_argument(
        "--image-dir",
        type=Path,
        metavar="DIR",
        help="where the camera writes IMG_<index>.jpg, created if missing (default: a temporary directory, removed at "
        "exit); served over MAVLink FTP from component 100 unless --ftp-root says otherwise: "
        "CAMERA_IMAGE_CAPTURED's file_url",
    )
    p.add_argument(
        "--current",
        type=parse_current,
        default=(0.0, 0.0),
        metavar="TO_DEG,M_S",
        help="the water's current moving the buoys on their moorings: direction it flows to, speed (default 0,0)",
    )
    # ----- the world's AIS (sitl_quad.ais_station, sitl_quad.ais_out)
    p.add_argument(
        "--ais-out",
        type=parse_host_port,
        metavar="HOST:PORT",
        help="send the world's AIS AtoN reports (message 21, NMEA !AIVDM) as UDP datagrams to this address: each "
        "--world buoy with an mmsi every 3 minutes of simulated time, from where it floats, off-position flagged "
        "outside its charted swing circle (e.g. a ground station's `serve --ais udp://0.0.0.0:10110`)",
    )
    p.add_argument(
        "--ais-virtual",
        action="append",
        default=[],
        metavar="MMSI,LAT,LON[,NAME[,KIND]]",
        help="also report a virtual AtoN (nothing in the water; virtual flag set) at this position, e.g. over a new "
        "wreck; KIND one of the world file's kinds (default isolated_danger); repeatable; needs --ais-out",
    )
    p.add_argument(
        "--log-dir",
        type=Path,
        metavar="DIR",
        help="where the ULog flight logs go, one per arming, served over the MAVLink log protocol "
        "(default: a temporary directory, printed at start and removed at exit)",
    )
    p.add_argument("--list-params", action="store_true", help="print every parameter with its value and exit")
    p.add_argument("-v", "--verbose", action="store_true", help="log every peer and protocol event")
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    logging.basicConfig(
        level=logging.DEBUG if args.verbose else logging.WARNING, format="sitl-quad %(levelname)s %(name)s: %(message)s"
    )
    if not (math.isfinite(args.speed) and 0 < args.speed <= 1000):
        return _fail("--speed must be in (0, 1000]")
    rate = args.outer_rate
    if not (math.isfinite(rate) and 10 <= rate <= 250 and abs(1000 / rate - round(1000 / rate)) < 1e-9):
        return _fail("--outer-rate must divide the 1 kHz physics into whole steps, between 10 and 250 Hz")
    if not 0 <= args.port < 65536:
        return _fail(f"--port {args.port} is not a UDP port")
    if args.ftp_root is not None and not args.ftp_root.is_dir():
        return _fail(f"--ftp-root {args.ftp_root} is not a directory")
    camera = args.camera if args.camera is not None else args.world is not None
    world = None
    if (camera or args.ais_out) and args.world is not None:
        from uavcore.buoy_world import WorldFileError, load_world

        try:
            world = load_world(args.world)
        except (OSError, WorldFileError) as exc:
            return _fail(f"--world {args.world}: {exc}")
    ais_out = None
    if args.ais_out is not None or args.ais_virtual:
        try:
            ais_out = _ais_out(args.ais_out, world, args.ais_virtual)
        except (OSError, ValueError) as exc:
            return _fail(str(exc))
    # Imports after argument checks so that --help is instant.
    from sitl_quad.attitude_loops import attitude_loops
    from sitl_quad.camera import Environment
    from sitl_quad.config import VehicleConfig
    from sitl_quad.mavlink.link import UdpLink
    from sitl_quad.params import ParameterError, ParameterTable
    from sitl_quad.server import VehicleServer
    from sitl_quad.vehicle import Vehicle
    from sitl_quad.vehicle_params import VEHICLE_PARAMETERS
    from sitl_quad.warmup import warm_up

    config = VehicleConfig()
    table = ParameterTable(VEHICLE_PARAMETERS, config)
    try:
        if args.params is not None and args.params.exists():
            table.load(args.params)
        for name, value in args.param:
            table.set(name, value)
    except ParameterError as exc:
        return _fail(str(exc))
    if args.list_params:
        for spec in table.specs:
            print(f"{spec.name:16} {table.get(spec.name):<14.6g} {spec.description}")
        return 0
    try:
        image_dir = _directory(args.image_dir, "--image-dir", "camera images", "sitl_quad_images_") if camera else None
        log_dir = _directory(args.log_dir, "--log-dir", "flight logs", "sitl_quad_logs_")
    except ValueError as exc:
        return _fail(str(exc))
    warm_up(config, args.home, args.outer_rate)  # before listening: no ground station waits on a compile
    vehicle = Vehicle(
        config, home=args.home, seed=args.seed, outer_rate_hz=args.outer_rate, attitude_loops=attitude_loops()
    )
    vehicle.battery.reset(args.battery_percent / 100.0)
    try:
        link = UdpLink(args.host, args.port, args.out, sysid=args.sysid, signing_key=args.signing_key)
    except OSError as exc:
        return _fail(f"cannot listen on udp {args.host}:{args.port}: {exc.strerror}")

    def save_params() -> None:
        if args.params is not None:
            tmp = args.params.with_suffix(args.params.suffix + ".tmp")
            table.save(tmp)
            tmp.replace(args.params)  # atomic: a crash never leaves half a parameter file

    server = VehicleServer(
        vehicle,
        table,
        link,
        speed=args.speed,
        lockstep=args.lockstep,
        flight_log=args.log,
        log_dir=log_dir,
        on_params_changed=save_params,
        # the camera's images are served where its CAMERA_IMAGE_CAPTURED file_url (mftp://[;comp=100]/...) says
        ftp_root=args.ftp_root or image_dir,
        ftp_component=args.ftp_component,
        image_dir=image_dir,
        world=world,
        current=Environment(current_to_deg=args.current[0], current_speed_m_s=args.current[1]),
        ais_out=ais_out,
    )
    signal.signal(signal.SIGTERM, lambda *_: server.stop())
    signal.signal(signal.SIGINT, lambda *_: server.stop())
    host, port = link.address
    pacing = _pacing_text(args.lockstep, server.pace())
    print(f"sitl-quad: listening on udp {host}:{port} ({pacing}, seed {args.seed}, home {args.home})", flush=True)
    # Everything loaded so far (numpy, numba's compiled kernels, the vehicle) lives as long as the process: moved
    # out of the collector's sight, a full collection in the 50 Hz loop no longer walks it (a late tick)
    gc.collect()
    gc.freeze()
    server.run(args.duration)
    if args.stats is not None:
        args.stats.write_text(json.dumps(server.stats(), indent=2) + "\n")
    return 0


def _directory(given: Path | None, option: str, what: str, prefix: str) -> Path:
    """The directory an option names, created if missing (ValueError naming the option when it cannot be), or else
    a new temporary one removed when the process exits (a stop or a signal; not after SIGKILL): a vehicle started
    without --log-dir or --image-dir keeps its files for its own run only, as a test's or a demo's does."""
    if given is None:
        given = Path(tempfile.mkdtemp(prefix=prefix))
        atexit.register(shutil.rmtree, given, ignore_errors=True)
    try:
        given.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ValueError(f"{option} {given}: {exc.strerror}") from None
    print(f"sitl-quad: {what} in {given}", flush=True)
    return given


def _ais_out(address: tuple[str, int] | None, world: World | None, virtual: list[str]) -> AisOut:
    """The AIS sender for --ais-out and --ais-virtual; ValueError naming what is wrong, OSError for the address."""
    from sitl_quad.ais_out import AisOut
    from sitl_quad.ais_station import AisStation, VirtualAton
    from uavcore.buoy_world import World

    if address is None:
        raise ValueError("--ais-virtual needs --ais-out HOST:PORT to send to")
    station = AisStation(world or World(()), tuple(VirtualAton.parse(text) for text in virtual))
    if not station.transmitters:
        raise ValueError("--ais-out: nothing to report: give a --world whose buoys have an mmsi, or --ais-virtual")
    return AisOut(address, station)


def _pacing_text(lockstep: bool, pace: float | None) -> str:
    """How simulated time runs, for the "listening" line: lockstep (capped by SIM_SPEEDUP, if set) or paced."""
    if not lockstep:
        return f"speed {pace:g}x"
    return "lockstep" if pace is None else f"lockstep, at most {pace:g}x (SIM_SPEEDUP)"


def _fail(message: str) -> int:
    print(f"sitl-quad: error: {message}", file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main())
