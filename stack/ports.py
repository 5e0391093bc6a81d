"""The ports `buoy-gcs up` listens on, checked before any child starts: the simulated vehicles' UDP ports and the
service's HTTP port. A default that is busy is replaced by the next free one (said on the screen); a port the user
gave is kept, and a busy one is an error naming the option. Both children only find out after their numba kernels
load, which takes seconds, or minutes on a cold cache: a check here answers at once.

A check is no reservation: another program may take the port between the check and the child's bind. The child
then fails, and the supervisor shows the reason from its log and the option that avoids it
(stack.supervisor.failure_reason).
"""

from __future__ import annotations

import errno
import re
import socket
from collections.abc import Callable
from dataclasses import dataclass

VEHICLE_HOST = "127.0.0.1"  # sitl_quad's default --host, which stack.children leaves as it is
SEARCH_SPAN = 100  # how far above a busy default to look for free ports
# how a child says its port was taken: Python's OSError (and its errno), uvicorn's log line
ADDRESS_IN_USE = re.compile(rf"address already in use|EADDRINUSE|errno {errno.EADDRINUSE}\b", re.IGNORECASE)


class BusyPortError(Exception):
    """A port `up` needs is busy and cannot be replaced (the user gave it, or none is free nearby)."""


@dataclass(frozen=True)
class Port:
    """One kind of port `up` listens on, and the option that chooses it."""

    protocol: str  # "UDP" or "TCP", as the messages name it
    host: str
    option: str  # the `up` option, e.g. --vehicle-port
    listener: str  # who listens there, e.g. "the vehicle"

    @property
    def kind(self) -> int:
        return socket.SOCK_DGRAM if self.protocol == "UDP" else socket.SOCK_STREAM


def vehicle_port(vehicles: int) -> Port:
    return Port("UDP", VEHICLE_HOST, "--vehicle-port", "the vehicle" if vehicles == 1 else f"the {vehicles} vehicles")


def service_port(host: str) -> Port:
    return Port("TCP", host, "--port", "the service")


def busy_advice(option: str) -> str:
    """What to do about a port that is taken."""
    return f"choose another port with {option} PORT, or leave {option} out and up picks a free one"


def in_use(port: Port, number: int) -> OSError | None:
    """The error binding `number` gives now when something holds it; None when it is free, and for any other
    failure (no such host or address here, a privileged port), which is the child's to report: not a busy port."""
    if not 0 < number < 65536:  # no port at all (getaddrinfo would wrap it): check_serve says so
        return None
    try:
        family, kind, proto, _, address = socket.getaddrinfo(
            port.host, number, type=port.kind, flags=socket.AI_PASSIVE
        )[0]
    except OSError:
        return None
    with socket.socket(family, kind, proto) as sock:
        if port.kind == socket.SOCK_STREAM:  # as uvicorn does: a port left in TIME_WAIT is free to it
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            sock.bind(address)
        except OSError as error:
            return error if error.errno == errno.EADDRINUSE else None
    return None


def first_busy(port: Port, first: int, count: int) -> tuple[int, OSError] | None:
    """The first of ports first .. first + count - 1 that is in use, and the error; None when none is."""
    for number in range(first, first + count):
        if (error := in_use(port, number)) is not None:
            return number, error
    return None


def free_block(port: Port, start: int, count: int, span: int = SEARCH_SPAN) -> int | None:
    """The first of `count` consecutive free ports from `start` on (within `span`), or None."""
    first = start
    while first < start + span and first + count - 1 < 65536:
        busy = first_busy(port, first, count)
        if busy is None:
            return first
        first = busy[0] + 1  # every block holding the busy port is taken too
    return None


def choose(port: Port, default: int, count: int, explicit: bool, say: Callable[[str], None]) -> int:
    """The first port of `count` for `port`: `default` when free; else, unless the user gave it (`explicit`), the
    next free block above it, which `say` announces. Raises BusyPortError when the port is busy and given."""
    busy = first_busy(port, default, count)
    if busy is None:
        return default
    number, error = busy
    reason = f"{port.protocol} {port.host}:{number} is busy ({error.strerror})"
    if explicit:
        raise BusyPortError(f"{reason}; {busy_advice(port.option)}")
    chosen = free_block(port, default + 1, count)
    if chosen is None:
        raise BusyPortError(f"{reason}, and no free ones in the {SEARCH_SPAN} above it: choose with {port.option}")
    verb = "listens" if count == 1 else "listen"
    say(f"{port.protocol} {number} is busy: {port.listener} {verb} on {_span(chosen, count)} ({port.option} to choose)")
    return chosen


def _span(first: int, count: int) -> str:
    return str(first) if count == 1 else f"{first}-{first + count - 1}"
