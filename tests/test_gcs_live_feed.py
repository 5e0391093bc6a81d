"""The live feed behind /ws (gcs.api.live_feed): one producer, the same encoded state for every client, a slow or
stalled client delaying nobody; and /ws of a real service (`python -m gcs serve`) with many clients."""

from __future__ import annotations

import asyncio
import itertools
import json
import time
from collections.abc import Awaitable, Callable

import pytest
import websockets
from service_process import serving

from gcs.api.live_feed import LiveFeed

RATE_HZ = 200.0  # fast ticks: the tests wait on counts, not on time


class Clients:
    """Per-client records of what the feed sent: the state numbers and the text objects themselves."""

    def __init__(self) -> None:
        self.numbers: dict[str, list[int]] = {}
        self.texts: dict[str, dict[int, str]] = {}

    def sender(self, name: str, pause: Callable[[], Awaitable[None]] | None = None) -> Callable[[str], Awaitable]:
        self.numbers[name], self.texts[name] = [], {}

        async def send(text: str) -> None:
            number = json.loads(text)["n"]
            self.numbers[name].append(number)
            self.texts[name][number] = text
            if pause is not None:
                await pause()

        return send


def counting_state() -> tuple[Callable[[], dict], list[int]]:
    reads: list[int] = []

    def read_state() -> dict:
        reads.append(len(reads) + 1)
        return {"type": "state", "n": len(reads)}

    return read_state, reads


async def wait_until(condition: Callable[[], bool], timeout_s: float = 60.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not condition():
        assert time.monotonic() < deadline, "the feed did not get there in time"
        await asyncio.sleep(0.005)


async def stop(feed: LiveFeed, tasks: list[asyncio.Task]) -> None:
    for task in tasks:
        task.cancel()
    await asyncio.gather(*tasks, return_exceptions=True)
    assert feed.clients == 0 and not feed.producing  # the producer stops with the last client


def test_every_client_gets_every_state_encoded_once_and_a_stalled_client_delays_nobody():
    async def scenario() -> None:
        read_state, reads = counting_state()
        feed, clients, never = LiveFeed(read_state, RATE_HZ), Clients(), asyncio.Event()
        tasks = [asyncio.create_task(feed.stream(clients.sender("stalled", never.wait)))]
        tasks += [asyncio.create_task(feed.stream(clients.sender(f"fast{i}"))) for i in range(20)]
        fast = [name for name in clients.numbers if name.startswith("fast")]
        await wait_until(lambda: all(len(clients.numbers[name]) >= 50 for name in fast))
        latest = feed.published
        for name in fast:
            numbers = clients.numbers[name]
            assert numbers == list(range(numbers[0], numbers[-1] + 1))  # every state, in order, none twice
            assert numbers[-1] >= latest - 1  # up to date: the stalled client held nobody back
        assert clients.numbers["stalled"] == [1]  # its send never returned: it got nothing more
        assert len(reads) == feed.published  # one read (and one encoding) per tick, whatever the client count
        first = clients.texts[fast[0]]
        for name in fast[1:]:  # the very same text object went to every client
            assert all(first[n] is text for n, text in clients.texts[name].items() if n in first)
        await stop(feed, tasks)

    asyncio.run(scenario())


def test_a_slow_client_skips_to_the_latest_state():
    async def scenario() -> None:
        read_state, _ = counting_state()
        feed, clients = LiveFeed(read_state, RATE_HZ), Clients()

        async def three_ticks() -> None:
            await asyncio.sleep(3 / RATE_HZ)

        tasks = [asyncio.create_task(feed.stream(clients.sender("slow", three_ticks)))]
        tasks.append(asyncio.create_task(feed.stream(clients.sender("fast"))))
        await wait_until(lambda: len(clients.numbers["slow"]) >= 20)
        slow = clients.numbers["slow"]
        assert all(b > a for a, b in itertools.pairwise(slow))  # never an old state, never one twice
        assert max(b - a for a, b in itertools.pairwise(slow)) >= 2  # it skipped the ones it had no time for
        assert len(clients.numbers["fast"]) > len(slow)
        await stop(feed, tasks)

    asyncio.run(scenario())


def test_a_state_that_cannot_be_read_is_skipped_and_the_feed_goes_on():
    async def scenario() -> None:
        calls = []

        def flaky_state() -> dict:
            calls.append(1)
            if len(calls) % 2:
                raise RuntimeError("not this tick")
            return {"n": len(calls)}

        feed, clients = LiveFeed(flaky_state, RATE_HZ), Clients()
        tasks = [asyncio.create_task(feed.stream(clients.sender("one")))]
        await wait_until(lambda: len(clients.numbers["one"]) >= 5)
        assert all(n % 2 == 0 for n in clients.numbers["one"])
        await stop(feed, tasks)

    asyncio.run(scenario())


# ----- /ws of a real service
@pytest.fixture
def service_url(tmp_path):
    with serving(tmp_path / "gcs.sqlite", tmp_path / "serve.log") as url:
        yield url


@pytest.mark.integration
def test_many_websocket_clients_each_receive_the_live_state(service_url):
    url = service_url.replace("http://", "ws://") + "/ws"

    async def scenario() -> None:
        # one client that stops reading (its queue holds one message): it must not hold up the others; it cannot
        # read the close handshake either, hence its short close timeout
        async with websockets.connect(url, max_queue=1, close_timeout=0.5) as stalled:
            clients = [await websockets.connect(url) for _ in range(50)]
            try:
                received = await asyncio.gather(*(receive(ws, 10) for ws in clients))
            finally:
                await asyncio.gather(*(ws.close() for ws in clients))
            assert stalled.state == websockets.protocol.State.OPEN
        for messages in received:
            assert len(messages) == 10
            assert all(m["type"] == "state" and m["vehicle"]["connected"] is False for m in messages)
            # every vehicle of the service, as GET /vehicles lists them (here the one, not heard)
            assert all([v["connected"] for v in m["vehicles"]] == [False] for m in messages)

    async def receive(ws, count: int) -> list[dict]:
        async with asyncio.timeout(30 * count):
            return [json.loads(await ws.recv()) for _ in range(count)]

    asyncio.run(scenario())
