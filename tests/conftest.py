"""Fixtures for the integration tests that start the vehicle (tests/sitl_process.py has the helpers), and the
database a storage test runs on, once per backend, and the ArduCopter double behind the service that the browser
tests of the map page share."""

from __future__ import annotations

import json
import socket
import subprocess
import sys
from collections import defaultdict
from collections.abc import Iterator
from pathlib import Path

import pytest
from ardupilot_double import ArduCopterDouble
from longest_first import RECORDED_FROM_S, LongestFirstScheduling
from postgres_server import PostgresServer, postgres_bindir
from sitl_process import GroundStation, SitlProcess
from web_page import TOKEN, wait_until_connected

from bench.processes import free_port, stop_process

# The fixtures below that start a real process: the vehicle (`python -m sitl_quad`) or a PostgreSQL server.
# `make test-fast` leaves the integration tier out, so a test using one must carry that marker.
PROCESS_FIXTURES = frozenset({"start_sitl", "shared_sitl", "postgres_server"})


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption(
        "--record-durations",
        metavar="PATH",
        help="write each test's seconds (setup, call, teardown) to PATH as JSON, for the longest-first order "
        "of `pytest -n N` (tests/longest_first.py)",
    )


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_make_scheduler(config: pytest.Config, log) -> LongestFirstScheduling | None:
    """`-n N` (xdist's `--dist load`, the default) hands the tests out longest first; another --dist is xdist's."""
    return LongestFirstScheduling(config, log) if config.getvalue("dist") == "load" else None


class DurationRecorder:
    """--record-durations: in the process that reports every test (the only one, or xdist's controller)."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.seconds: defaultdict[str, float] = defaultdict(float)

    def pytest_runtest_logreport(self, report: pytest.TestReport) -> None:
        self.seconds[report.nodeid] += report.duration

    def pytest_sessionfinish(self) -> None:
        kept = {nodeid: round(s, 1) for nodeid, s in sorted(self.seconds.items()) if s >= RECORDED_FROM_S}
        self.path.write_text(json.dumps(kept, indent=0) + "\n")


def pytest_configure(config: pytest.Config) -> None:
    path = config.getoption("--record-durations")
    if path and not hasattr(config, "workerinput"):
        config.pluginmanager.register(DurationRecorder(Path(path)), "record-durations")


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Refuse to run a test that starts the vehicle or PostgreSQL through a fixture (directly or through one
    that needs it, as `gcs` and `postgres_url` do) without the integration marker: unmarked, it would land in
    the fast tier and make it need those processes."""
    unmarked = [
        item.nodeid
        for item in items
        if PROCESS_FIXTURES & set(getattr(item, "fixturenames", ())) and item.get_closest_marker("integration") is None
    ]
    if unmarked:
        raise pytest.UsageError(
            "these tests start a process through a fixture but are not marked integration:\n  " + "\n  ".join(unmarked)
        )


class VehicleStarter:
    """Starts vehicles on free ports and, at the end, stops them and reports any that misbehaved."""

    def __init__(self) -> None:
        self.started: list[SitlProcess] = []

    def __call__(self, speed: float = 20.0, extra_args: tuple[str, ...] = ()) -> SitlProcess:
        vehicle = SitlProcess(speed=speed, extra_args=extra_args)
        self.started.append(vehicle)
        return vehicle.start()

    def stop_all(self) -> None:
        """Each vehicle must exit cleanly on SIGTERM and must not have logged a traceback (a handler error
        it swallowed to stay up counts as a failure too)."""
        problems = []
        for vehicle in self.started:
            code = vehicle.stop()
            stderr = vehicle.stderr()
            vehicle.cleanup()
            if code != 0 or "Traceback" in stderr:
                problems.append(f"vehicle on port {vehicle.port} exited with {code}:\n{stderr[-3000:]}")
        if problems:
            pytest.fail("\n".join(problems))


def connected(vehicle: SitlProcess) -> GroundStation:
    station = GroundStation(vehicle.port)
    try:
        station.connect()
    except TimeoutError:
        station.close()
        alive, stderr = vehicle.alive(), vehicle.stderr()[-3000:]
        raise RuntimeError(f"no HEARTBEAT; vehicle alive: {alive}; stderr:\n{stderr}") from None
    return station


@pytest.fixture
def start_sitl() -> Iterator[VehicleStarter]:
    """start_sitl(speed=..., extra_args=(...)) starts a vehicle of this test's own."""
    starter = VehicleStarter()
    yield starter
    starter.stop_all()


@pytest.fixture(scope="module")
def shared_sitl() -> Iterator[SitlProcess]:
    """One vehicle at 2x real time for a whole test module: for tests that set up the state they need."""
    starter = VehicleStarter()
    yield starter(speed=2.0)
    starter.stop_all()


@pytest.fixture(scope="module")
def shared_gcs(shared_sitl) -> Iterator[GroundStation]:
    station = connected(shared_sitl)
    yield station
    station.close()


@pytest.fixture
def gcs(shared_gcs, shared_sitl) -> GroundStation:
    """The module's ground station on the shared vehicle, with nothing left over from earlier tests."""
    assert shared_sitl.alive(), f"the shared vehicle died:\n{shared_sitl.stderr()[-3000:]}"
    shared_gcs.drain()
    shared_gcs.send_heartbeat()  # a peer silent for 10 s stops getting telemetry: be a peer again
    return shared_gcs


@pytest.fixture(scope="session")
def postgres_server() -> Iterator[PostgresServer]:
    """One PostgreSQL server per test process, from the machine's binaries (`make test` installs them)."""
    bindir = postgres_bindir()
    if bindir is None:
        pytest.skip("PostgreSQL binaries (initdb, pg_ctl) not found: `make test` installs Debian's postgresql")
    server = PostgresServer(bindir).start()
    yield server
    server.stop()


@pytest.fixture
def postgres_url(postgres_server: PostgresServer) -> str:
    """A fresh, empty database of this test's own: its postgresql:// URL."""
    return postgres_server.new_database()


@pytest.fixture(params=["sqlite", pytest.param("postgresql", marks=pytest.mark.integration)])
def database(request: pytest.FixtureRequest, tmp_path: Path) -> str | Path:
    """Where a test's database is, the test running once on each backend: a SQLite file, or a fresh database on
    the test PostgreSQL server."""
    if request.param == "sqlite":
        return tmp_path / "gcs.sqlite"
    return request.getfixturevalue("postgres_url")


@pytest.fixture
def double_and_service(tmp_path):
    """`python -m gcs serve --token ...` listening (udpin) for the ArduCopter double; yields (url, double)."""
    udp, http = free_port(socket.SOCK_DGRAM), free_port(socket.SOCK_STREAM)
    logs = open(tmp_path / "service.log", "w")  # noqa: SIM115 - closed below
    argv = [sys.executable, "-m", "gcs", "serve", "--vehicle", f"udpin://127.0.0.1:{udp}", "--port", str(http)]
    argv += ["--db", str(tmp_path / "gcs.sqlite"), "--token", TOKEN, "--vehicle-wait", "60"]
    gcs = subprocess.Popen(argv, stdout=logs, stderr=subprocess.STDOUT)
    double = ArduCopterDouble(udp).start()
    url = f"http://127.0.0.1:{http}"
    wait_until_connected(url, tmp_path / "service.log")
    yield url, double
    double.stop()
    stop_process(gcs)
    logs.close()
