"""`python -m gcs serve` as a child process on free loopback ports, for tests that talk to it as a client does."""

from __future__ import annotations

import socket
import subprocess
import sys
import time
import urllib.request
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path


def free_port(kind: int) -> int:
    with socket.socket(socket.AF_INET, kind) as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


@contextmanager
def serving(db: Path, log: Path, *options: str) -> Iterator[str]:
    """The service over the database `db` with no vehicle (it sends to a UDP port nobody holds), its output in
    `log`: yields its http:// URL once it answers, and stops it afterwards."""
    udp, http = free_port(socket.SOCK_DGRAM), free_port(socket.SOCK_STREAM)
    argv = [sys.executable, "-m", "gcs", "serve", "--vehicle", f"udpout:127.0.0.1:{udp}", "--port", str(http)]
    with open(log, "w") as output:
        service = subprocess.Popen([*argv, "--db", str(db), *options], stdout=output, stderr=subprocess.STDOUT)
        url = f"http://127.0.0.1:{http}"
        try:
            deadline = time.monotonic() + 60
            while True:
                try:
                    with urllib.request.urlopen(f"{url}/vehicle", timeout=2):
                        break
                except OSError:
                    assert service.poll() is None and time.monotonic() < deadline, log.read_text()
                    time.sleep(0.2)
            yield url
        finally:
            service.terminate()
            try:
                service.wait(30)
            except subprocess.TimeoutExpired:
                service.kill()
                service.wait()
