"""Child processes for `buoy-gcs up`: start in order, watch, restart a crashed child, stop cleanly.

Each child's output goes to a log file in the data directory. A child that exits while the stack runs is
reported and restarted, up to `max_restarts` times in `restart_window_s`; past that the supervisor stops
everything and says which child kept failing. Each of these errors, and a child that exits or hangs while it
starts, shows the reason from the child's log (its current run's last error line, else its last lines) and, for a
port that is taken, the `up` option that chooses another. SIGINT and SIGTERM stop the children in reverse order
(SIGTERM, then SIGKILL after a grace period).
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from stack.ports import ADDRESS_IN_USE, busy_advice

GRACE_S = 10.0
REASON_LINES = 3  # the last lines shown when the log names no error
REASON_CHARS = 240  # a line of the reason is cut here: a long one (a command line, a repr) would swamp the screen
# the line _start writes before each run of a child; the child's output follows it
RUN_MARKER = re.compile(r"^--- (?:.* )?starting: .*$", re.MULTILINE)
TRACEBACK = "Traceback (most recent call last):"
# a line that states an error: a level or `prog: error:` as a word of its own (not uvicorn's logger name,
# "uvicorn.error", which is on all its lines), or an exception's class
ERROR_LINE = re.compile(r"(?:^|[\s\[:])(?i:error|critical|fatal)(?=[\s:\]]|$)|\b[A-Z]\w*(?:Error|Exception)\b")


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
    port_option: str | None = None  # the `up` option choosing the port it listens on, advised when that is taken


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
                what = f"{spec.name} exited with code {child.process.returncode} while starting"
                raise SupervisorError(_explained(what, child))
            if time.monotonic() > deadline or self.stopping:
                what = f"{spec.name} did not become ready in {spec.start_timeout_s:.0f} s"
                raise SupervisorError(_explained(what, child))
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
                what = (
                    f"{child.spec.name} exited with code {code} {len(child.restarts) + 1} times "
                    f"in {self.restart_window_s:.0f} s; stopping"
                )
                raise SupervisorError(_explained(what, child))
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


def current_run(log_text: str) -> str:
    """What the child wrote in its current run: the log after the supervisor's last "starting:" line (the log
    holds every run, and an earlier run's error is no reason for this one's)."""
    markers = list(RUN_MARKER.finditer(log_text))
    return log_text[markers[-1].end() :] if markers else log_text


def failure_reason(log_text: str, port_option: str | None = None) -> list[str]:
    """Why a child's current run failed, from its log: the last error line (a traceback's exception line, or a
    line naming an error), else its last REASON_LINES lines; then, when the reason is a port in use and the child
    has a `port_option`, what to do about it. Empty when the run wrote nothing."""
    lines = [line.rstrip() for line in current_run(log_text).splitlines() if line.strip()]
    errors = _error_lines(lines)
    reason = [lines[errors[-1]]] if errors else lines[-REASON_LINES:]
    reason = [line if len(line) <= REASON_CHARS else line[: REASON_CHARS - 3] + "..." for line in reason]
    if port_option is not None and any(ADDRESS_IN_USE.search(line) for line in reason):
        reason.append(busy_advice(port_option))
    return reason


def _error_lines(lines: list[str]) -> list[int]:
    """Which lines state an error: each traceback's exception line (the first unindented line after its frames)
    and lines that name an error (a log level, `prog: error:`, an exception class) or an address in use."""
    found, in_traceback = [], False
    for i, line in enumerate(lines):
        if line == TRACEBACK:
            in_traceback = True
        elif in_traceback and not line.startswith((" ", "\t")):
            found.append(i)
            in_traceback = False
        elif not in_traceback and (ERROR_LINE.search(line) or ADDRESS_IN_USE.search(line)):
            found.append(i)
    return found


def _explained(what: str, child: Child) -> str:
    """A start-up failure's message: what happened, the reason from the child's log, and where that log is."""
    try:
        text = child.log_path.read_text(errors="replace")
    except OSError:
        text = ""
    reason = "".join(f"\n  {line}" for line in failure_reason(text, child.spec.port_option))
    return f"{what}; see {child.log_path}{reason}"


def python_module(module: str, *args: str) -> list[str]:
    return [sys.executable, "-m", module, *args]
