"""`up --real-time` / `--watch-speed N`: the simulated vehicles' SIM_SPEEDUP, set once the demo has flown (or at
once without one), so that the missions an operator flies afterwards go at a pace one can watch.

`up` sets it over MAVLink itself, as another ground station would, rather than through the service: the service
reads parameters but has no API that writes one (and the simulator's pace is no business of a ground station's
REST API), while the vehicle takes any address that sends it a datagram as a peer (sitl_quad.mavlink.link) and
answers a PARAM_SET with a PARAM_VALUE to every peer, the service included. The vehicle's start arguments are
updated too, so a vehicle the supervisor restarts comes back at the same pace (it starts at SIM_SPEEDUP 0 from
stack.children, whatever its parameter file kept from an earlier run).
"""

from __future__ import annotations

import socket
import time
from collections.abc import Callable

from stack.supervisor import ChildSpec, SupervisorError
from uavcore.mavlink import AUTOPILOT_COMPID, GCS_SYSID, Encoder, mavlink, new_parser, param_id, parse_datagram

PARAM = "SIM_SPEEDUP"
# A component of its own beside the service's 255/190: each signing stream (system, component) has its own
# timestamps, and two senders sharing one could see the other's frames taken for replays.
STACK_COMPID = mavlink.MAV_COMP_ID_USER1
RESEND_S = 1.0  # PARAM_SET again when no PARAM_VALUE came (UDP may lose either; setting twice is harmless)
ANSWER_S = 15.0  # a backstop: the vehicle answers within a loop pass, even on a loaded machine


def speedup_arg(speedup: float) -> str:
    """The vehicle's `--param` argument for SIM_SPEEDUP (stack.children gives it at every start)."""
    return f"{PARAM}={speedup:g}"


def set_sim_speedup(
    port: int, sysid: int, speedup: float, signing_key: bytes | None = None, timeout_s: float = ANSWER_S
) -> float:
    """Set SIM_SPEEDUP on the vehicle `sysid` listening on udp 127.0.0.1:`port`; the value its PARAM_VALUE
    answers with (a refused value is answered with the one kept). SupervisorError when none comes in `timeout_s`."""
    encoder = Encoder(GCS_SYSID, STACK_COMPID, signing_key)
    parser = new_parser(GCS_SYSID, STACK_COMPID, signing_key)
    request = mavlink.MAVLink_param_set_message(
        sysid, AUTOPILOT_COMPID, PARAM.encode(), speedup, mavlink.MAV_PARAM_TYPE_REAL32
    )
    deadline = time.monotonic() + timeout_s
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.connect(("127.0.0.1", port))  # datagrams from the vehicle only
        while (remaining := deadline - time.monotonic()) > 0:
            sock.send(encoder.pack(request))
            answer = _answer(sock, parser, sysid, min(RESEND_S, remaining))
            if answer is not None:
                return answer
    raise SupervisorError(f"vehicle {sysid} on udp 127.0.0.1:{port} did not answer a PARAM_SET of {PARAM}")


def _answer(sock: socket.socket, parser, sysid: int, wait_s: float) -> float | None:
    """The value of the first PARAM_VALUE naming SIM_SPEEDUP from system `sysid` within `wait_s`, else None."""
    deadline = time.monotonic() + wait_s
    while (remaining := deadline - time.monotonic()) > 0:
        sock.settimeout(remaining)
        try:
            data = sock.recv(65535)
        except TimeoutError:
            return None
        except ConnectionRefusedError:  # the vehicle's port is not open (yet, or any more): resend
            time.sleep(min(0.1, remaining))
            continue
        for msg in parse_datagram(parser, data):
            if msg.get_type() == "PARAM_VALUE" and msg.get_srcSystem() == sysid and param_id(msg) == PARAM:
                return float(msg.param_value)
    return None


def watch_at(
    vehicles: list[tuple[ChildSpec, int, int]], speedup: float, signing_key: bytes | None, say: Callable[[str], None]
) -> None:
    """Set SIM_SPEEDUP on every (vehicle's child spec, port, system id), keep it in each one's start arguments and
    say what the missions flown from now on do. A vehicle that does not take it is said, not fatal: the stack
    runs on, that vehicle at full speed."""
    done = 0
    for spec, port, sysid in vehicles:
        try:
            _watch_one(spec, port, sysid, speedup, signing_key)
            done += 1
        except SupervisorError as error:
            say(f"buoy-gcs up: {error}; its missions fly at full speed")
    if done == 0:
        return
    pace = "real time" if speedup == 1 else f"{speedup:g}x real time"
    count = len(vehicles)
    which = "" if count == 1 else f" on all {count} vehicles" if done == count else f" on {done} of {count} vehicles"
    say(f"missions from now on fly at {pace}{which} ({PARAM} {speedup:g})")


def _watch_one(spec: ChildSpec, port: int, sysid: int, speedup: float, signing_key: bytes | None) -> None:
    answered = set_sim_speedup(port, sysid, speedup, signing_key)
    if abs(answered - speedup) > 1e-6 * max(1.0, speedup):
        raise SupervisorError(f"vehicle {sysid} kept {PARAM} {answered:g}: it refused {speedup:g}")
    spec.argv = [speedup_arg(speedup) if arg.startswith(f"{PARAM}=") else arg for arg in spec.argv]
