"""Fixtures for the integration tests that start the vehicle (tests/sitl_process.py has the helpers)."""

from __future__ import annotations

from collections.abc import Callable, Iterator

import pytest
from sitl_process import GroundStation, SitlProcess


@pytest.fixture
def start_sitl() -> Iterator[Callable[..., SitlProcess]]:
    """Start vehicles with start_sitl(speed=..., extra_args=(...)); each is stopped at teardown, where it must
    exit cleanly after SIGTERM and must not have logged a traceback (a handler error it swallowed)."""
    started: list[SitlProcess] = []

    def start(speed: float = 20.0, extra_args: tuple[str, ...] = ()) -> SitlProcess:
        vehicle = SitlProcess(speed=speed, extra_args=extra_args)
        started.append(vehicle)
        return vehicle.start()

    yield start
    problems = []
    for vehicle in started:
        code = vehicle.stop()
        stderr = vehicle.stderr()
        vehicle.cleanup()
        if code != 0 or "Traceback" in stderr:
            problems.append(f"vehicle on port {vehicle.port} exited with {code}; stderr:\n{stderr[-3000:]}")
    if problems:
        pytest.fail("\n".join(problems))


@pytest.fixture
def sitl(start_sitl) -> SitlProcess:
    """One vehicle at 20x real time."""
    return start_sitl(speed=20.0)


@pytest.fixture
def gcs(sitl) -> Iterator[GroundStation]:
    """A pymavlink ground station connected to `sitl` (it has seen a HEARTBEAT)."""
    station = GroundStation(sitl.port)
    try:
        station.connect()
    except TimeoutError:
        raise RuntimeError(f"vehicle alive: {sitl.alive()}; stderr:\n{sitl.stderr()[-3000:]}") from None
    yield station
    station.close()
