"""A peer program the tests start (a MAVSDK double, a camera) and the check that it ended cleanly.

Each peer writes its output to a log file in the test's directory; `peers_stopped_cleanly` stops every peer a
test started and fails the test when one exited non-zero or printed a traceback, showing its log's tail."""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
from collections.abc import Iterable, Sequence
from pathlib import Path

import pytest

from bench.processes import stop_process

LOG_TAIL_CHARS = 3000


class PeerProcess:
    """`python script *args` (under `prefix`, e.g. a time namespace's `unshare`), its output in `log_path`."""

    def __init__(
        self, directory: Path, script: Path, *args: str, prefix: Sequence[str] = (), log_name: str | None = None
    ) -> None:
        self.log_path = directory / (log_name or f"{script.stem}.log")
        self._log = self.log_path.open("w")
        self.wrapped = bool(prefix)
        self.process = subprocess.Popen(
            [*prefix, sys.executable, str(script), *args], stdout=self._log, stderr=subprocess.STDOUT
        )

    def log(self) -> str:
        return self.log_path.read_text()

    def stop(self) -> int:
        """SIGTERM to the program (under a prefix: to its child, the program; the prefix exits with its code)."""
        pid = self.process.pid
        children = Path(f"/proc/{pid}/task/{pid}/children")
        if self.wrapped and self.process.poll() is None and children.exists():
            for child in children.read_text().split():
                with contextlib.suppress(ProcessLookupError):
                    os.kill(int(child), signal.SIGTERM)
        stop_process(self.process, 15)
        self._log.close()
        return self.process.returncode


def peers_stopped_cleanly(peers: Iterable[PeerProcess]) -> None:
    """Stop each peer; fail the test naming those that exited non-zero or with a traceback."""
    problems = []
    for peer in peers:
        code = peer.stop()
        if code != 0 or "Traceback" in peer.log():
            problems.append(f"{peer.log_path.name} exited with {code}:\n{peer.log()[-LOG_TAIL_CHARS:]}")
    if problems:
        pytest.fail("\n".join(problems))
