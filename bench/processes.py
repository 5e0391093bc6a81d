"""What every bench and test that starts processes shares: free loopback ports, and stopping a child process for
good. It lives in bench/ because both use it: tests import bench modules (pytest's pythonpath is the repository
root), while a bench, run as `python -m bench.X`, cannot import from tests/, which is no package."""

from __future__ import annotations

import socket
import subprocess
from typing import AnyStr


def free_port(kind: int) -> int:
    """A port on 127.0.0.1 of this kind (socket.SOCK_DGRAM: UDP, SOCK_STREAM: TCP) that nothing holds right now."""
    with socket.socket(socket.AF_INET, kind) as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def free_udp_port() -> int:
    return free_port(socket.SOCK_DGRAM)


def free_tcp_port() -> int:
    return free_port(socket.SOCK_STREAM)


def free_udp_port_block(count: int) -> int:
    """The first of `count` consecutive UDP ports on 127.0.0.1 that nothing is bound to right now (a fleet's)."""
    while True:
        first = free_udp_port()
        if first + count > 65536:
            continue
        sockets = []
        try:
            for port in range(first, first + count):
                sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
                sockets.append(sock)
                sock.bind(("127.0.0.1", port))
            return first
        except OSError:
            continue
        finally:
            for sock in sockets:
                sock.close()


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
