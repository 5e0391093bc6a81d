"""What every bench and test that starts processes shares: free loopback ports, and stopping a child process for
good. It lives in bench/ because both use it: tests import bench modules (pytest's pythonpath is the repository
root), while a bench, run as `python -m bench.X`, cannot import from tests/, which is no package."""

from __future__ import annotations

import itertools
import os
import random
import socket
import subprocess
from pathlib import Path
from typing import AnyStr

EPHEMERAL_RANGE_FILE = Path("/proc/sys/net/ipv4/ip_local_port_range")
# Above the project's own defaults (HTTP 8000, AIS 10110, vehicles 14540 and the 100 above it `up` searches), which
# a stack started without ports takes.
POOL_FLOOR = 15000


def ephemeral_low() -> int:
    """The lowest port the kernel hands to bind(port 0) (Linux's ip_local_port_range; its default elsewhere)."""
    try:
        return int(EPHEMERAL_RANGE_FILE.read_text().split()[0])
    except (OSError, ValueError, IndexError):
        return 32768


def worker_pool() -> range:
    """The ports this process picks from: below the ephemeral range, so no socket any process binds to port 0
    (a ground station's link, a MAVSDK server, a database client) is ever handed one of them, and one slice per
    pytest-xdist worker, so two workers never pick the same one. A port picked and let go before its user binds it
    was otherwise free for anything else to take in between: beside two CPU burners, a vehicle's port was."""
    low = ephemeral_low()
    if low - POOL_FLOOR < 1000:  # a machine whose ephemeral range starts low: no room for a pool below it
        return range(0)
    worker = os.environ.get("PYTEST_XDIST_WORKER", "gw0").removeprefix("gw")
    count = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1"))
    index = int(worker) if worker.isdigit() else 0
    size = (low - POOL_FLOOR) // max(count, 1)
    return range(POOL_FLOOR + index * size, POOL_FLOOR + (index + 1) * size)


_pool = worker_pool()
# Each process walks its slice from a random place (two benches run side by side rarely start together) and never
# hands out a port again until it has gone round: a child's port may stay bound a while after the child is gone.
_next = itertools.count(random.randrange(len(_pool))) if _pool else None


def bindable(port: int, kind: int) -> bool:
    """Whether nothing on 127.0.0.1 holds `port` of this kind right now."""
    with socket.socket(socket.AF_INET, kind) as sock:
        try:
            sock.bind(("127.0.0.1", port))
        except OSError:
            return False
    return True


def free_port_block(kind: int, count: int) -> int:
    """The first of `count` consecutive ports on 127.0.0.1 of this kind (socket.SOCK_DGRAM: UDP, SOCK_STREAM:
    TCP) that nothing holds right now, from this process's pool (worker_pool)."""
    if _next is None:
        return _kernel_block(kind, count)
    for _ in range(len(_pool)):
        first = _pool[next(_next) % len(_pool)]
        if first + count <= _pool.stop and all(bindable(port, kind) for port in range(first, first + count)):
            for _ in range(count - 1):  # the block's other ports are not handed out again on this round
                next(_next)
            return first
    raise OSError(f"no {count} free consecutive ports left in {_pool.start}-{_pool.stop - 1}")


def _kernel_block(kind: int, count: int) -> int:
    """Without a pool: ports the kernel picks (bind to port 0), the block's others checked free."""
    while True:
        with socket.socket(socket.AF_INET, kind) as sock:
            sock.bind(("127.0.0.1", 0))
            first = sock.getsockname()[1]
        if first + count <= 65536 and all(bindable(port, kind) for port in range(first + 1, first + count)):
            return first


def free_port(kind: int) -> int:
    """A port on 127.0.0.1 of this kind (socket.SOCK_DGRAM: UDP, SOCK_STREAM: TCP) that nothing holds right now."""
    return free_port_block(kind, 1)


def free_udp_port() -> int:
    return free_port(socket.SOCK_DGRAM)


def free_tcp_port() -> int:
    return free_port(socket.SOCK_STREAM)


def free_udp_port_block(count: int) -> int:
    """The first of `count` consecutive UDP ports on 127.0.0.1 that nothing is bound to right now (a fleet's)."""
    return free_port_block(socket.SOCK_DGRAM, count)


def stop_process(process: subprocess.Popen, grace_s: float = 10.0) -> int:
    """SIGTERM, then SIGKILL if it has not exited within `grace_s`; returns its exit code (a process that had
    already exited is left as it was)."""
    if process.poll() is None:
        process.terminate()
        try:
            process.wait(grace_s)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
    return process.returncode


def stop_reading_output(
    process: subprocess.Popen[AnyStr], grace_s: float = 10.0
) -> tuple[AnyStr | None, AnyStr | None]:
    """stop_process for a child whose output is piped: what it wrote, (stdout, stderr), read while it stops (a
    child blocked on a full pipe would never exit while we only waited); SIGKILL if it has not exited within
    `grace_s`, after which its returncode says so."""
    if process.poll() is None:
        process.terminate()
    try:
        return process.communicate(timeout=grace_s)
    except subprocess.TimeoutExpired:
        process.kill()
        return process.communicate()
