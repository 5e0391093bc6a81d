"""A database that holds a query up stops nothing else: the service's event loop, which also runs the vehicle
link, never waits on the database (gcs.storage.off_loop).

Real PostgreSQL (tests/postgres_server.py): another session locks the missions table, as a migration, a
backup or a second instance's long transaction would, so the service's GET /missions waits on the database.
Meanwhile the vehicle (tests/scripted_vehicle.py) must go on hearing the service's heartbeats, and a command
the service sends must be acknowledged and answered: before the storage moved off the loop, both stopped
until the lock was released.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor

import psycopg
import pytest
from fastapi.testclient import TestClient
from scripted_vehicle import ScriptedVehicle, mavlink

from gcs.api.app import create_app
from gcs.settings import Settings
from uavcore.mavlink import MAV_CMD_BATTERY_RESET

pytestmark = pytest.mark.integration

BACKSTOP_S = 60.0  # reached only when the behaviour is wrong, however loaded the machine
HEARTBEATS_WHILE_HELD = 3  # the service sends one a second


def eventually(condition: Callable[[], bool], what: str) -> None:
    deadline = time.monotonic() + BACKSTOP_S
    while not condition():
        assert time.monotonic() < deadline, f"never: {what}"
        time.sleep(0.05)


def waiting_on_a_lock(watcher: psycopg.Connection) -> int:
    """How many sessions of this database wait for a lock (the service's query behind the table lock)."""
    row = watcher.execute(
        "SELECT count(*) FROM pg_stat_activity WHERE datname = current_database() AND wait_event_type = 'Lock'"
    ).fetchone()
    return row[0]


def test_a_query_the_database_holds_up_delays_neither_heartbeats_nor_command_acknowledgements(postgres_url, tmp_path):
    vehicle = ScriptedVehicle()
    vehicle.landed_state = mavlink.MAV_LANDED_STATE_ON_GROUND  # a pack is swapped on the ground
    vehicle.start()
    settings = Settings(db=postgres_url, data_dir=tmp_path, vehicle_url=f"udpout:127.0.0.1:{vehicle.port}")
    try:
        # left in reverse: the lock goes first (an assertion failing while it is held ends the transaction), then
        # the requests it held complete, then the service stops
        with (
            TestClient(create_app(settings)) as client,
            ThreadPoolExecutor(2) as requests,
            psycopg.connect(postgres_url, autocommit=True) as watcher,
            psycopg.connect(postgres_url) as locker,
        ):
            eventually(lambda: client.get("/vehicle").json()["connected"], "the vehicle connected")
            locker.execute("LOCK TABLE missions IN ACCESS EXCLUSIVE MODE")  # held until the transaction ends
            held = requests.submit(client.get, "/missions")
            eventually(lambda: waiting_on_a_lock(watcher) >= 1, "GET /missions waiting on the database")
            beats = len(vehicle.gcs_heartbeat_times)

            # the command goes out, the vehicle acknowledges it, and the answer comes back, all while held
            swap = requests.submit(client.post, "/vehicle/battery-swap", json={"charge_pct": 100})
            answer = swap.result(BACKSTOP_S)
            assert answer.status_code == 200, answer.text
            assert answer.json()["vehicle"] == "accepted"
            assert MAV_CMD_BATTERY_RESET in vehicle.commands_seen
            # and the heartbeats go on
            eventually(
                lambda: len(vehicle.gcs_heartbeat_times) >= beats + HEARTBEATS_WHILE_HELD,
                f"{HEARTBEATS_WHILE_HELD} heartbeats while the database holds the query",
            )
            assert not held.done() and waiting_on_a_lock(watcher) >= 1  # all of it while the query waited

            locker.commit()  # the lock goes: the held request completes, nothing lost
            listed = held.result(BACKSTOP_S)
            assert listed.status_code == 200 and listed.json() == []
    finally:
        vehicle.stop()
