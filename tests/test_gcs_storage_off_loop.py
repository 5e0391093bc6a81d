"""The storage as the event loop uses it (gcs.storage.off_loop.AsyncStorage): every call in a thread, writes in
the order issued, and version reads that callers arriving together share without ever answering one of them
with a value read before it asked."""

from __future__ import annotations

import asyncio
import threading
from collections.abc import Callable
from typing import Any

import pytest
from stored_missions import FLIGHT, PLAN

from gcs.domain.status import MissionStatus
from gcs.storage import SqliteStorage, Storage
from gcs.storage.off_loop import READ_THREADS, AsyncStorage
from gcs.storage.postgres import POOL_SIZE

WAIT_S = 30.0  # a backstop: reached only when the behaviour is wrong


class Counting:
    """Wraps a storage method: counts its calls; with `hold`, the next call reads, then keeps its thread until
    released (a query the database is slow to answer)."""

    def __init__(self, method: Callable[..., Any]) -> None:
        self.method, self.calls = method, 0
        self.hold, self.began, self.release = False, threading.Event(), threading.Event()

    def __call__(self, *args: Any) -> Any:
        self.calls += 1
        value = self.method(*args)
        if self.hold:
            self.hold = False
            self.began.set()
            assert self.release.wait(WAIT_S)
        return value


async def all_queued() -> None:
    """Let every task created so far run up to its first wait (asyncio runs ready tasks first in, first out)."""
    for _ in range(3):
        await asyncio.sleep(0)


def hold_the_reader(storage: Storage, facade: AsyncStorage) -> tuple[Counting, asyncio.Future]:
    """A slow get_mission that keeps the facade's one reader thread busy until released."""
    slow = storage.get_mission = Counting(storage.get_mission)  # type: ignore[method-assign]
    slow.hold = True
    return slow, asyncio.ensure_future(facade.get_mission(1))


@pytest.fixture
def storage(tmp_path) -> Storage:
    opened = SqliteStorage(tmp_path / "gcs.sqlite")
    yield opened
    opened.close()


def new_mission(storage: Storage) -> int:
    return storage.create_mission(FLIGHT, PLAN)


def test_every_storage_thread_has_a_postgresql_connection_of_its_own():
    # a writer waiting for a connection the four readers hold would stall every write behind a long read
    assert POOL_SIZE >= READ_THREADS + 1 + 2  # and two worker threads (a report, a track) beside them


def test_reads_and_writes_run_in_threads_and_writes_keep_their_order(storage):
    async def scenario() -> None:
        facade = AsyncStorage(storage)
        loop_thread = threading.get_ident()
        seen: list[int] = []
        original = storage.set_status

        def record_thread(*args: Any) -> None:
            seen.append(threading.get_ident())
            original(*args)

        storage.set_status = record_thread  # type: ignore[method-assign]
        mission = await facade.create_mission(FLIGHT, PLAN)
        statuses = [MissionStatus.UPLOADING, MissionStatus.UPLOADED, MissionStatus.FLYING, MissionStatus.COMPLETED]
        await asyncio.gather(*(facade.set_status(mission, status) for status in statuses))  # issued in this order
        record = await facade.get_mission(mission)
        assert [event.status for event in record.events] == ["planned", *statuses]
        assert loop_thread not in seen and len(set(seen)) == 1  # one writer thread, never the loop's
        await facade.close()

    asyncio.run(scenario())


def test_callers_asking_together_share_one_read(storage):
    async def scenario() -> None:
        facade = AsyncStorage(storage, read_threads=1)
        new_mission(storage)
        counting = storage.latest_version = Counting(storage.latest_version)  # type: ignore[method-assign]
        slow, busy = hold_the_reader(storage, facade)
        await all_queued()
        answers = asyncio.gather(*(facade.latest_version() for _ in range(20)))
        await all_queued()  # all twenty asked while the reader was busy: none of their reads has begun
        slow.release.set()
        assert await answers == [1] * 20
        assert counting.calls == 1
        await busy
        await facade.close()

    asyncio.run(scenario())


def test_a_read_already_begun_is_not_joined_by_a_caller_whose_write_it_may_have_missed(storage):
    async def scenario() -> None:
        facade = AsyncStorage(storage, read_threads=2)
        counting = storage.latest_version = Counting(storage.latest_version)  # type: ignore[method-assign]
        counting.hold = True
        early = asyncio.ensure_future(facade.latest_version())
        assert await asyncio.to_thread(counting.began.wait, WAIT_S)  # it has read: no mission yet, version 0
        await facade.create_mission(FLIGHT, PLAN)  # version 1 committed
        late = await facade.latest_version()  # asked after the write: must see it, so it reads anew
        counting.release.set()
        assert (await early, late) == (0, 1)
        assert counting.calls == 2
        await facade.close()

    asyncio.run(scenario())


def test_a_caller_cancelled_leaves_the_shared_read_to_the_others(storage):
    async def scenario() -> None:
        facade = AsyncStorage(storage, read_threads=1)
        new_mission(storage)
        slow, busy = hold_the_reader(storage, facade)
        await all_queued()
        first, second = (asyncio.ensure_future(facade.mission_version(1)) for _ in range(2))
        await all_queued()
        first.cancel()
        slow.release.set()
        assert await second == 1
        assert first.cancelled()
        await busy
        await facade.close()

    asyncio.run(scenario())
