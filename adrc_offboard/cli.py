"""`python -m adrc_offboard` / `adrc-offboard`: the outer position loop as its own process."""

from __future__ import annotations

import argparse
import logging
import math
import os
import signal
import sys

from uavcore.mavlink import SIGNING_KEY_ENV, VEHICLE_UDP_PORT

EPILOG = """\
examples:
  adrc-offboard                              # ADRC outer loop for the vehicle on udp 127.0.0.1:14540
  adrc-offboard --controller pid             # the PID baseline, same structure, rates and limits
  adrc-offboard --no-engage                  # answer setpoints but never ask for OFFBOARD
"""


def parse_connect(text: str) -> tuple[str, int]:
    scheme, _, rest = text.partition(":")
    host, _, port = rest.rpartition(":")
    if scheme != "udpout" or not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise argparse.ArgumentTypeError(f"expected udpout:HOST:PORT, got {text!r}")
    return host, int(port)


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="adrc-offboard",
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Cascade-ADRC outer loop (paper Section IV): follows the vehicle's POSITION_TARGET_LOCAL_NED "
        "and sends SET_ATTITUDE_TARGET over MAVLink.",
    )
    p.add_argument(
        "--connect",
        type=parse_connect,
        default=("127.0.0.1", VEHICLE_UDP_PORT),
        metavar="udpout:HOST:PORT",
        help=f"the vehicle (default udpout:127.0.0.1:{VEHICLE_UDP_PORT})",
    )
    p.add_argument("--controller", choices=("adrc", "pid"), default="adrc", help="outer-loop law (default adrc)")
    p.add_argument(
        "--sysid",
        type=int,
        choices=range(1, 256),
        metavar="N",
        help="the vehicle's system id (default: follow the first autopilot heard)",
    )
    p.add_argument(
        "--rate",
        type=float,
        default=50.0,
        metavar="HZ",
        help="outer-loop rate; must match the vehicle's --outer-rate (default 50)",
    )
    p.add_argument(
        "--no-engage",
        dest="engage",
        action="store_false",
        help="never request OFFBOARD (answer setpoints only, e.g. to keep a lockstep vehicle paced)",
    )
    p.add_argument(
        "--signing-key",
        metavar="KEY",
        default=os.environ.get(SIGNING_KEY_ENV) or None,
        help=f"MAVLink 2 signing key, the vehicle's (64 hex digits, or a passphrase; default: ${SIGNING_KEY_ENV})",
    )
    p.add_argument("--duration", type=float, metavar="SECONDS", help="exit after this many wall-clock seconds")
    p.add_argument("-v", "--verbose", action="store_true")
    return p


def make_controller(kind: str, rate_hz: float):
    """The outer loop for the default airframe (paper Table 2), its gains from the family's shipped design
    (adrc_offboard/gains/design.json) and its limits from the airframe's envelope (adrc_offboard.design)."""
    from adrc_offboard.design import outer_loop_for
    from uavcore.airframe import Airframe

    return outer_loop_for(kind, Airframe.table2(), rate_hz=rate_hz)


def warm_up(controller, rate_hz: float) -> None:
    """One throwaway update, then a reset: the control laws' numba kernels compile (or load from the cache) now,
    before the node talks to the vehicle. A cold cache takes seconds, and a lockstep vehicle waits at most 2 s for a
    peer that has been answering before it flies on without it."""
    import numpy as np

    from uavcore.state import TrajectorySetpoint, VehicleState

    controller.update(TrajectorySetpoint(position=np.zeros(3)), VehicleState(), 1.0 / rate_hz)
    controller.reset()


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    logging.basicConfig(
        level=logging.DEBUG if args.verbose else logging.WARNING, format="adrc-offboard %(levelname)s: %(message)s"
    )
    if not (math.isfinite(args.rate) and 10 <= args.rate <= 250):
        print("adrc-offboard: error: --rate must be between 10 and 250 Hz", file=sys.stderr)
        return 2
    from adrc_offboard.node import OffboardNode
    from uavcore.mavlink import parse_signing_key

    key = parse_signing_key(args.signing_key) if args.signing_key is not None else None
    controller = make_controller(args.controller, args.rate)
    warm_up(controller, args.rate)
    node = OffboardNode(
        controller,
        args.connect,
        args.rate,
        args.engage,
        sysid=args.sysid,
        signing_key=key,
    )
    signal.signal(signal.SIGTERM, lambda *_: node.stop())
    signal.signal(signal.SIGINT, lambda *_: node.stop())
    print(
        f"adrc-offboard: {args.controller} outer loop at {args.rate:g} Hz -> udp {args.connect[0]}:{args.connect[1]}",
        flush=True,
    )
    node.run(args.duration)
    return 0
