"""Flight logs on the service's side: the log protocol client (gcs.vehicle.logs) against the real vehicle process
serving a log directory, the vehicle's answers at the edges (pymavlink: an offset past the end, LOG_REQUEST_END,
LOG_ERASE, no logs), and the flight_logs records on both storage backends."""

from __future__ import annotations

import asyncio
import os
import time

import pytest
from sitl_process import WAIT_S, GroundStation
from stored_missions import FLIGHT, PLAN
from test_gcs_battery_link import connected_link

from gcs.missions.flight_log import fetch_flight_log
from gcs.storage import StoredFlightLog, open_storage
from gcs.storage.off_loop import AsyncStorage
from gcs.vehicle.link import LinkManager
from gcs.vehicle.logs import DATA_LEN, LogTooLargeError, NoLogsError

pytestmark = pytest.mark.integration

# two logs as a vehicle left them on its card: their bytes need not be ULog for the transfer
FIRST = "log_0001_20261128T050000Z.ulg"
SECOND = "log_0002_20261128T051500Z.ulg"


@pytest.fixture
def log_dir(tmp_path):
    directory = tmp_path / "logs"
    directory.mkdir()
    (directory / FIRST).write_bytes(os.urandom(1000))
    (directory / SECOND).write_bytes(os.urandom(5 * DATA_LEN + 7))
    (directory / "log_0003_20261128T052000Z.ulg.part").write_bytes(b"being written")  # not listed
    return directory


def test_the_link_lists_and_downloads_the_vehicles_logs(start_sitl, log_dir):
    vehicle = start_sitl(speed=1, extra_args=("--log-dir", str(log_dir)))

    async def scenario() -> None:
        async with connected_link(vehicle.port) as link:
            entries = await link.logs.entries()
            assert [(e.id, e.size_bytes) for e in entries] == [(0, 1000), (1, 5 * DATA_LEN + 7)]
            assert entries[1].time_utc == 1_795_842_900  # 2026-11-28 05:15:00 UTC, from the file's name
            assert await link.logs.latest() == entries[1]
            assert await link.logs.download(entries[1]) == (log_dir / SECOND).read_bytes()
            assert await link.logs.download(entries[0]) == (log_dir / FIRST).read_bytes()
            with pytest.raises(LogTooLargeError, match="over the limit of 999"):
                await link.logs.download(entries[0], max_bytes=999)

    asyncio.run(scenario())


def test_the_vehicle_answers_the_log_protocol_at_its_edges(start_sitl, log_dir):
    vehicle = start_sitl(speed=1, extra_args=("--log-dir", str(log_dir)))
    gcs = GroundStation(vehicle.port)
    try:
        gcs.connect()
        gcs.mav.log_request_list_send(1, 1, 1, 1)  # only the second
        entry = gcs.recv("LOG_ENTRY", timeout=WAIT_S)
        assert (entry.id, entry.num_logs, entry.last_log_num, entry.size) == (1, 2, 1, 5 * DATA_LEN + 7)
        assert gcs.recv("LOG_ENTRY", timeout=0.5) is None

        gcs.mav.log_request_data_send(1, 1, 1, 4 * DATA_LEN, 0xFFFFFFFF)  # the rest from the fifth piece
        pieces = [gcs.recv("LOG_DATA", timeout=WAIT_S) for _ in range(2)]
        assert [(p.ofs, p.count) for p in pieces] == [(4 * DATA_LEN, DATA_LEN), (5 * DATA_LEN, 7)]
        data = (log_dir / SECOND).read_bytes()
        assert bytes(pieces[1].data[:7]) == data[-7:] and bytes(pieces[1].data[7:]) == bytes(DATA_LEN - 7)
        gcs.mav.log_request_data_send(1, 1, 1, 10_000, 90)  # past the end: one empty piece
        past = gcs.recv("LOG_DATA", timeout=WAIT_S)
        assert (past.ofs, past.count) == (10_000, 0)
        gcs.mav.log_request_data_send(1, 1, 7, 0, 90)  # no log 7: no answer, as PX4
        assert gcs.recv("LOG_DATA", timeout=0.5) is None

        gcs.mav.log_erase_send(1, 1)
        deadline = time.monotonic() + WAIT_S
        while list(log_dir.glob("*.ulg")) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert sorted(p.name for p in log_dir.iterdir()) == ["log_0003_20261128T052000Z.ulg.part"]
        gcs.mav.log_request_list_send(1, 1, 0, 0xFFFF)
        none = gcs.recv("LOG_ENTRY", timeout=WAIT_S)
        assert (none.id, none.num_logs, none.last_log_num, none.size) == (0, 0, 0, 0)
    finally:
        gcs.close()


def test_a_vehicle_without_logs_is_a_no_logs_error_and_the_mission_gets_a_note(start_sitl, tmp_path):
    vehicle = start_sitl(speed=1, extra_args=("--log-dir", str(tmp_path / "empty")))
    storage = AsyncStorage(open_storage(tmp_path / "gcs.sqlite"))
    mission = storage.blocking.create_mission(FLIGHT, PLAN)

    async def scenario() -> None:
        async with connected_link(vehicle.port) as link:
            with pytest.raises(NoLogsError, match="no flight logs"):
                await link.logs.entries()
            await fetch_flight_log(link, storage, mission)

    asyncio.run(scenario())
    recorded = storage.blocking.flight_log(mission)
    assert recorded is not None and recorded.size_bytes is None and storage.blocking.flight_log_data(mission) is None
    assert recorded.note == "flight log not downloaded: the vehicle has no flight logs"
    assert storage.blocking.get_mission(mission).status == "planned"  # the mission's own record untouched
    asyncio.run(storage.close())


def test_without_a_link_or_a_mission_the_fetch_notes_or_gives_up_quietly(tmp_path):
    storage = AsyncStorage(open_storage(tmp_path / "gcs.sqlite"))
    mission = storage.blocking.create_mission(FLIGHT, PLAN)
    link = LinkManager()  # never started: not connected

    async def scenario() -> None:
        await fetch_flight_log(link, storage, mission)
        assert (await storage.flight_log(mission)).note == "flight log not downloaded: no link to the vehicle"
        assert await storage.delete_mission(mission)
        await fetch_flight_log(link, storage, mission)  # deleted meanwhile: nothing recorded, no error
        assert await storage.flight_log(mission) is None

    asyncio.run(scenario())
    asyncio.run(storage.close())


def test_flight_logs_are_recorded_replaced_and_deleted_with_their_mission(database):
    storage = open_storage(database)
    try:
        mission = storage.create_mission(FLIGHT, PLAN)
        other = storage.create_mission(FLIGHT, PLAN)
        assert storage.flight_log(mission) is None
        before = storage.get_mission(mission)
        failed = StoredFlightLog(downloaded_at="2026-11-28T05:00:00.000000+00:00", note="flight log not downloaded")
        storage.set_flight_log(mission, failed)
        assert storage.flight_log(mission) == failed
        assert storage.get_mission(mission).status == before.status  # the mission's own record as it was
        assert storage.get_mission(mission).updated_at > before.updated_at  # but its report is drawn anew
        stored = StoredFlightLog(downloaded_at="2026-11-28T05:01:00.000000+00:00", size_bytes=4, vehicle_log_id=4)
        storage.set_flight_log(mission, stored, b"ULog")
        assert storage.flight_log(mission) == stored and storage.flight_log(other) is None
        assert storage.flight_log_data(mission) == b"ULog" and storage.flight_log_data(other) is None
        assert storage.delete_mission(mission)
        assert storage.flight_log(mission) is None and storage.flight_log_data(mission) is None
    finally:
        storage.close()
