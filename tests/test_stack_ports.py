"""`buoy-gcs up` and busy ports: a busy default is replaced by a free port and said on the screen, a busy port the
user gave is an error naming the option, and a child that fails while starting shows the reason from its log."""

from __future__ import annotations

import json
import os
import queue
import re
import signal
import socket
import subprocess
import sys
import threading
import time
import urllib.request
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from pathlib import Path

import pytest

from bench.processes import free_tcp_port, free_udp_port, free_udp_port_block, stop_process
from stack.cli import DEFAULT_VEHICLE_PORT, main
from stack.ports import BusyPortError, choose, service_port, vehicle_port
from stack.supervisor import ChildSpec, Supervisor, SupervisorError, failure_reason

REPO = Path(__file__).resolve().parent.parent
ANSWER_S = 10.0  # the bound: `up` with the vehicle's default port taken says what it does within 10 s
# A backstop only: on a cold numba cache the vehicle (about 60 s) and then the service (140 s) compile their
# kernels one after the other, and a loaded machine takes longer; warm, the stack answers in about 30 s here.
STACK_S = 600.0

SITL_BUSY = """
--- 2026-11-27 23:12:30 starting: /venv/bin/python -m sitl_quad --port 14540 --sysid 1 --lockstep
sitl-quad: error: cannot listen on udp 127.0.0.1:14540: Address already in use
"""
# what `gcs serve` logs when its HTTP port is taken (uvicorn's logger is "uvicorn.error" on every line)
SERVICE_BUSY = """
--- 2026-11-27 23:14:00 starting: /venv/bin/python -m gcs serve --port 8000
2026-11-27 23:14:01,535 INFO uvicorn.error: Started server process [20616]
2026-11-27 23:16:24,765 INFO uvicorn.error: Application startup complete.
2026-11-27 23:16:24,766 ERROR uvicorn.error: [Errno 98] error while attempting to bind on address ('127.0.0.1', \
8000): address already in use
2026-11-27 23:16:24,766 INFO uvicorn.error: Waiting for application shutdown.
2026-11-27 23:16:24,769 INFO uvicorn.error: Application shutdown complete.
"""
TRACEBACK = """
--- 2026-11-27 23:20:00 starting: /venv/bin/python -m adrc_offboard --connect udpout:127.0.0.1:14540
outer loop at 50 Hz
Traceback (most recent call last):
  File "adrc_offboard/node.py", line 10, in run
    raise OSError(98, "Address already in use")
OSError: [Errno 98] Address already in use

During handling of the above exception, another exception occurred:

Traceback (most recent call last):
  File "adrc_offboard/node.py", line 12, in run
    raise RuntimeError("x" * 500)
RuntimeError: xxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxx\
xxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxx\
xxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxx
"""


def test_the_reason_is_the_current_runs_last_error_line_and_a_taken_port_names_its_option():
    vehicle_advice = "choose another port with --vehicle-port PORT, or leave --vehicle-port out and up picks a free one"
    assert failure_reason(SITL_BUSY, "--vehicle-port") == [
        "sitl-quad: error: cannot listen on udp 127.0.0.1:14540: Address already in use",
        vehicle_advice,
    ]
    # the error line, not uvicorn's last lines (all from its logger "uvicorn.error")
    reason, advice = failure_reason(SERVICE_BUSY, "--port")
    assert reason.endswith("8000): address already in use") and "ERROR" in reason
    assert advice.startswith("choose another port with --port PORT")
    # a traceback: its exception line, cut to a screen's length; the advice only when that line is a taken port
    (line,) = failure_reason(TRACEBACK, "--port")
    assert line.startswith("RuntimeError: xxx") and line.endswith("...") and len(line) == 240
    assert failure_reason(TRACEBACK.split("During handling")[0]) == ["OSError: [Errno 98] Address already in use"]
    # an earlier run's error is no reason for this one: only the lines after the last "starting:" marker count
    rerun = SITL_BUSY + "--- 2026-11-27 23:31:00 starting: python -m sitl_quad\nsitl-quad: camera images in /tmp\n"
    assert failure_reason(rerun, "--vehicle-port") == ["sitl-quad: camera images in /tmp"]
    # no error named: the last lines as they are; nothing written: no reason
    assert failure_reason("--- 2026 starting: x\nloading\n\ncompiling\n") == ["loading", "compiling"]
    assert failure_reason("--- 2026 starting: x\n") == []


@pytest.mark.integration  # starts a (tiny) child process
def test_a_child_that_exits_while_starting_is_reported_with_the_reason_and_the_option(tmp_path):
    says = "import sys; sys.exit('sitl-quad: error: cannot listen on udp 127.0.0.1:14540: Address already in use')"
    spec = ChildSpec("sitl_quad", [sys.executable, "-c", says], ready=lambda: False, port_option="--vehicle-port")
    supervisor = Supervisor([spec], tmp_path / "logs", REPO, say=lambda _: None)
    try:
        with pytest.raises(SupervisorError) as failed:
            supervisor.start_all()
    finally:
        supervisor.stop_all()
    lines = str(failed.value).splitlines()
    assert lines[0] == f"sitl_quad exited with code 1 while starting; see {tmp_path / 'logs' / 'sitl_quad.log'}"
    assert lines[1:] == [
        "  sitl-quad: error: cannot listen on udp 127.0.0.1:14540: Address already in use",
        "  choose another port with --vehicle-port PORT, or leave --vehicle-port out and up picks a free one",
    ]


@contextmanager
def held(kind: int, port: int) -> Iterator[socket.socket | None]:
    """A socket bound (and for TCP listening) on 127.0.0.1:port; None when something else holds the port already,
    which makes it as busy."""
    sock = socket.socket(socket.AF_INET, kind)
    try:
        try:
            sock.bind(("127.0.0.1", port))
        except OSError:
            yield None
            return
        if kind == socket.SOCK_STREAM:
            sock.listen()
        yield sock
    finally:
        sock.close()


def test_a_busy_default_moves_to_the_next_free_ports_and_says_so_a_given_one_is_an_error():
    said: list[str] = []
    http = free_tcp_port()
    with held(socket.SOCK_STREAM, http):
        chosen = choose(service_port("127.0.0.1"), http, 1, explicit=False, say=said.append)
        assert chosen > http
        assert said == [f"TCP {http} is busy: the service listens on {chosen} (--port to choose)"]
        with pytest.raises(
            BusyPortError, match=rf"TCP 127.0.0.1:{http} is busy \(.*\); choose another port with --port"
        ):
            choose(service_port("127.0.0.1"), http, 1, explicit=True, say=said.append)
    # a fleet: every vehicle's port must be free, so the block starts above the busy one
    first = free_udp_port_block(5)
    with held(socket.SOCK_DGRAM, first + 1):
        assert choose(vehicle_port(3), first, 3, explicit=False, say=said.append) == first + 2
    fleet = f"the 3 vehicles listen on {first + 2}-{first + 4}"
    assert said[-1] == f"UDP {first + 1} is busy: {fleet} (--vehicle-port to choose)"
    free = free_udp_port()
    assert choose(vehicle_port(1), free, 1, explicit=True, say=said.append) == free and len(said) == 2


def _env() -> dict[str, str]:
    return {k: v for k, v in os.environ.items() if not k.startswith("BUOY_GCS_")}  # as a user's shell without them


@pytest.mark.integration  # a fresh interpreter: `buoy-gcs up`, which stops before any child starts
def test_a_busy_vehicle_port_given_on_the_command_line_is_an_error_naming_the_reason_and_the_option(tmp_path):
    port = free_udp_port()
    with held(socket.SOCK_DGRAM, port):
        argv = [sys.executable, "-m", "stack", "up", "--vehicle-port", str(port), "--data", str(tmp_path)]
        result = subprocess.run(argv, cwd=REPO, env=_env(), capture_output=True, text=True, timeout=120)
    assert result.returncode == 2, result.stdout + result.stderr
    assert f"UDP 127.0.0.1:{port} is busy (Address already in use)" in result.stderr
    assert "choose another port with --vehicle-port PORT" in result.stderr
    assert not (tmp_path / "logs").exists()  # no child was started


def test_a_busy_http_port_given_on_the_command_line_is_an_error_naming_the_option(tmp_path, capsys):
    port = free_tcp_port()
    with held(socket.SOCK_STREAM, port):
        assert main(["up", "--port", str(port), "--data", str(tmp_path), "--vehicle-port", str(free_udp_port())]) == 2
    error = capsys.readouterr().err
    assert f"TCP 127.0.0.1:{port} is busy" in error and "--port PORT" in error


class Up:
    """`python -m stack up` in a session of its own, its screen read line by line with the time each arrived."""

    def __init__(self, *args: str) -> None:
        self.started = time.monotonic()
        self.process = subprocess.Popen(
            [sys.executable, "-m", "stack", "up", *args],
            cwd=REPO,
            env=_env(),
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            start_new_session=True,  # its children too: stop() makes sure none is left behind
        )
        self.lines: list[tuple[float, str]] = []
        self._arrived: queue.Queue[tuple[float, str]] = queue.Queue()
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        for line in self.process.stdout:
            self._arrived.put((time.monotonic() - self.started, line.rstrip("\n")))

    def screen(self) -> list[tuple[float, str]]:
        while not self._arrived.empty():
            self.lines.append(self._arrived.get())
        return self.lines

    def text(self) -> str:
        return "\n".join(line for _, line in self.screen())

    def wait_line(self, pattern: str, timeout_s: float) -> tuple[float, re.Match[str]]:
        deadline = time.monotonic() + timeout_s
        while True:
            for at, line in self.screen():
                if match := re.search(pattern, line):
                    return at, match
            assert self.process.poll() is None, f"buoy-gcs up exited:\n{self.text()}"
            assert time.monotonic() < deadline, f"no line matching {pattern!r} in {timeout_s} s:\n{self.text()}"
            time.sleep(0.1)

    def stop(self) -> int:
        """SIGTERM (up stops its children), then SIGKILL to whatever of its session is left."""
        code = stop_process(self.process, 60)
        with suppress(ProcessLookupError):
            os.killpg(self.process.pid, signal.SIGKILL)
        self._reader.join(10)  # its last lines
        return code


def _vehicle(http_port: int) -> dict | None:
    try:
        with urllib.request.urlopen(f"http://127.0.0.1:{http_port}/vehicle", timeout=2) as response:
            return json.load(response)
    except OSError:
        return None


@pytest.mark.integration
@pytest.mark.slow
@pytest.mark.timeout(STACK_S + 120)
def test_up_with_the_default_vehicle_port_taken_starts_on_another_and_says_so(tmp_path):
    """The issue's check: `make run` with UDP 14540 taken starts anyway. A real socket holds the default port;
    `up` says within 10 s which port the vehicle listens on instead, and the service then hears the vehicle."""
    http_port = free_tcp_port()  # given: this test is about the vehicle's port, and 8000 may be anyone's
    with held(socket.SOCK_DGRAM, DEFAULT_VEHICLE_PORT):
        up = Up("--port", str(http_port), "--data", str(tmp_path))
        try:
            busy = rf"UDP {DEFAULT_VEHICLE_PORT} is busy: the vehicle listens on (\d+) \(--vehicle-port to choose\)"
            at, match = up.wait_line(busy, ANSWER_S)
            port = int(match[1])
            assert port > DEFAULT_VEHICLE_PORT
            deadline = time.monotonic() + STACK_S
            while not ((vehicle := _vehicle(http_port)) and vehicle["connected"]):
                assert up.process.poll() is None, f"buoy-gcs up exited:\n{up.text()}"
                assert time.monotonic() < deadline, f"the service never heard the vehicle:\n{up.text()}"
                time.sleep(0.5)
            up.wait_line(r"^running; Ctrl-C stops everything", STACK_S)
            print(f"port message after {at:.1f} s, vehicle heard after {time.monotonic() - up.started:.1f} s")
        finally:
            code = up.stop()
    assert code == 0, up.text()
    assert f"--port {port}" in (tmp_path / "logs" / "sitl_quad.log").read_text()
    assert f"udpout:127.0.0.1:{port}" in (tmp_path / "logs" / "gcs.log").read_text()  # the service's link
    assert up.text().splitlines()[-1] == "stopped"


# `up` without its port check (stack.cli does that; run_up trusts its options): what a port taken between the
# check and the child's bind looks like
RUN_UP = """
import sys
from pathlib import Path
from gcs.settings import Settings
from stack.options import UpOptions
from stack.up import run_up
data, vehicle_port, http_port = Path(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3])
settings = Settings(data_dir=data, vehicle_url=f"udpout:127.0.0.1:{vehicle_port}", port=http_port)
sys.exit(run_up(UpOptions(settings=settings, controller="px4"), say=lambda text: print(text, flush=True)))
"""


@pytest.mark.integration  # the vehicle starts, loads its kernels and fails to bind
def test_a_vehicle_whose_port_was_taken_after_the_check_fails_with_the_reason_and_the_option_on_screen(tmp_path):
    port = free_udp_port()
    with held(socket.SOCK_DGRAM, port):
        argv = [sys.executable, "-c", RUN_UP, str(tmp_path), str(port), str(free_tcp_port())]
        result = subprocess.run(argv, cwd=REPO, env=_env(), capture_output=True, text=True, timeout=STACK_S)
    assert result.returncode == 1, result.stdout + result.stderr
    screen = result.stdout.splitlines()
    failed = screen.index(
        f"buoy-gcs up: sitl_quad exited with code 2 while starting; see {tmp_path}/logs/sitl_quad.log"
    )
    assert screen[failed + 1 : failed + 3] == [
        f"  sitl-quad: error: cannot listen on udp 127.0.0.1:{port}: Address already in use",
        "  choose another port with --vehicle-port PORT, or leave --vehicle-port out and up picks a free one",
    ]
