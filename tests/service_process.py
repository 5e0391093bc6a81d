"""`python -m gcs serve` as a child process on free loopback ports, for tests that talk to it as a client does."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import time
import urllib.request
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path

from bench.processes import free_port, stop_process


@contextmanager
def running_service(
    db: Path,
    log: Path,
    *options: str,
    sysids: Sequence[int] = (),
    env: Mapping[str, str | None] | None = None,
    ready_s: float = 180.0,
    program: Sequence[str] = (sys.executable, "-m", "gcs"),
    cwd: Path | None = None,
) -> Iterator[tuple[str, subprocess.Popen]]:
    """The service over the database `db` with no vehicle (it sends to a `silent_udp_port`), its output in
    `log`: yields its http:// URL and its process once it answers, and stops it afterwards. `sysids`: a fleet of
    vehicles with these system ids instead (each configured, so a fleet mission can be planned for them, none
    there to fly); `env`: added to the service's environment (a value None removes the variable); `program`: the
    command that runs the service's CLI (an installed `buoy-gcs`, say), run in `cwd`.

    ready_s: the service answers only once the planner's kernels are compiled (gcs.api.app's lifespan), which takes
    up to a minute on a cold numba cache and longer beside other tests' processes on a loaded machine."""
    with silent_udp_port() as udp, open(log, "w") as output:
        http = free_port(socket.SOCK_STREAM)
        links = [f"{sysid}=udpout:127.0.0.1:{udp}" for sysid in sysids] or [f"udpout:127.0.0.1:{udp}"]
        argv = [*program, "serve", *(a for link in links for a in ("--vehicle", link))]
        argv += ["--port", str(http), "--db", str(db), *options]
        environment = {name: value for name, value in {**os.environ, **(env or {})}.items() if value is not None}
        service = subprocess.Popen(argv, stdout=output, stderr=subprocess.STDOUT, env=environment, cwd=cwd)
        url = f"http://127.0.0.1:{http}"
        try:
            deadline = time.monotonic() + ready_s
            while True:
                try:
                    with urllib.request.urlopen(f"{url}/vehicle", timeout=2):
                        break
                except OSError:
                    assert service.poll() is None and time.monotonic() < deadline, log.read_text()
                    time.sleep(0.2)
            yield url, service
        finally:
            stop_process(service, 30)


@contextmanager
def silent_udp_port() -> Iterator[int]:
    """A loopback UDP port this process holds and never answers: a test service's "no vehicle". A free port picked
    and let go could be bound meanwhile by a vehicle another test worker starts, which answers whoever sends it a
    heartbeat (with its own parameters and pack): the service would connect to it and fly it."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as held:
        held.bind(("127.0.0.1", 0))
        yield held.getsockname()[1]


@contextmanager
def serving(db: Path, log: Path, *options: str, **keywords) -> Iterator[str]:
    """running_service's URL alone."""
    with running_service(db, log, *options, **keywords) as (url, _):
        yield url
