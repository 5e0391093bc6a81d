"""Child processes for `buoy-gcs up`: start in order, watch, restart a crashed child, stop cleanly.

Each child's output goes to a log file in the data directory. A child that exits while the stack runs is
reported and restarted, up to `max_restarts` times in `restart_window_s`; past that the supervisor stops
everything and says which child kept failing. SIGINT and SIGTERM stop the children in reverse order
(SIGTERM, then SIGKILL after a grace period).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

GRACE_S = 10.0


@dataclass
class ChildSpec:
    name: str
    argv: list[str]
    ready: Callable[[], bool] | None = None  # polled after start until True (or start_timeout_s)
    # A fresh machine compiles the numba kernels on first start: the service compiles every planner kernel before
    # it answers (planner.warmup: about 40 s idle, 80 s on a loaded 2-core machine) while the vehicle compiles its
    # own. A child that fails exits, which is seen at once; this bounds only one that hangs.
    start_timeout_s: float = 300.0
    env: dict[str, str] = field(default_factory=dict)  # added to the environment: secrets go here, not in argv


@dataclass
class Child:
    spec: ChildSpec
    log_path: Path
    process: subprocess.Popen | None = None
    restarts: list[float] = field(default_factory=list)


class SupervisorError(RuntimeError):
    """The stack cannot run (a child never became ready, or keeps dying); the message says which and why."""


class Supervisor:
    def __init__(
        self,
        specs: list[ChildSpec],
        log_dir: Path,
        cwd: Path,
        say: Callable[[str], None] = print,
        max_restarts: int = 3,
        restart_window_s: float = 60.0,
    ) -> None:
        log_dir.mkdir(parents=True, exist_ok=True)
        self.children = [Child(spec, log_dir / f"{spec.name}.log") for spec in specs]
        self.cwd = cwd
        self.say = say
        self.max_restarts = max_restarts
        self.restart_window_s = restart_window_s
        self.stopping = False

    def install_signal_handlers(self) -> None:
        def handler(signum, _frame) -> None:
            self.stopping = True

        signal.signal(signal.SIGINT, handler)
        signal.signal(signal.SIGTERM, handler)

    def start_all(self) -> None:
        for child in self.children:
            self._start(child)

    def _start(self, child: Child) -> None:
        spec = child.spec
        with open(child.log_path, "a") as log:
            log.write(f"\n--- {time.strftime('%Y-%m-%d %H:%M:%S')} starting: {' '.join(spec.argv)}\n")
            log.flush()
            child.process = subprocess.Popen(
                spec.argv,
                cwd=self.cwd,
                stdout=log,
                stderr=subprocess.STDOUT,
                stdin=subprocess.DEVNULL,
                env={**os.environ, **spec.env} if spec.env else None,
            )
        deadline = time.monotonic() + spec.start_timeout_s
        while spec.ready is not None and not spec.ready():
            if child.process.poll() is not None:
                raise SupervisorError(
                    f"{spec.name} exited with code {child.process.returncode} while starting; see {child.log_path}"
                )
            if time.monotonic() > deadline or self.stopping:
                raise SupervisorError(
                    f"{spec.name} did not become ready in {spec.start_timeout_s:.0f} s; see {child.log_path}"
                )
            time.sleep(0.2)

    def poll(self) -> None:
        """Restart any child that died; raise SupervisorError when one dies too often."""
        for child in self.children:
            code = child.process.poll() if child.process else None
            if code is None:
                continue
            now = time.monotonic()
            child.restarts = [t for t in child.restarts if now - t < self.restart_window_s]
            if len(child.restarts) >= self.max_restarts:
                raise SupervisorError(
                    f"{child.spec.name} exited with code {code} {len(child.restarts) + 1} times "
                    f"in {self.restart_window_s:.0f} s; stopping. See {child.log_path}"
                )
            child.restarts.append(now)
            self.say(f"{child.spec.name} exited with code {code}: restarting (log: {child.log_path})")
            self._start(child)

    def run_until_stopped(self, tick: Callable[[], None] | None = None) -> None:
        while not self.stopping:
            self.poll()
            if tick is not None:
                tick()
            time.sleep(0.5)

    def stop_all(self) -> list[tuple[str, int | None]]:
        """SIGTERM every child (last started first), SIGKILL what is still alive after GRACE_S."""
        codes = []
        for child in reversed(self.children):
            process = child.process
            if process is None:
                continue
            if process.poll() is None:
                process.send_signal(signal.SIGTERM)
                try:
                    process.wait(GRACE_S)
                except subprocess.TimeoutExpired:
                    process.kill()
                    process.wait(GRACE_S)
            codes.append((child.spec.name, process.returncode))
        return codes


def python_module(module: str, *args: str) -> list[str]:
    return [sys.executable, "-m", module, *args]
