"""The live feed behind /ws: one producer reads and encodes the state once per tick; every client sends the
latest encoding when it is ready.

Each client used to run its own loop: read the state, encode it, send it, sleep. With N clients that is N reads
and N encodings per tick, and the ticks of N loops drift apart. Here one producer task ticks at the live rate
and publishes (sequence number, JSON text); each client's task waits for a sequence number it has not sent and
sends the text as it is. A client whose socket is slow (or stalled) holds up only its own task: when its send
returns it takes whatever is latest, so it skips the states it had no time for (every message is the whole
state, nothing is lost by skipping) and never queues old ones.

The producer runs while at least one client listens.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
from collections.abc import Awaitable, Callable
from typing import Any

log = logging.getLogger(__name__)


class LiveFeed:
    """Publishes `read_state()` as JSON text at `rate_hz` to every `stream` running."""

    def __init__(self, read_state: Callable[[], dict[str, Any]], rate_hz: float) -> None:
        self._read_state, self.period_s = read_state, 1.0 / rate_hz
        self.published = 0  # sequence number of the latest state (0: none yet)
        self._text = ""
        self._tick = asyncio.Event()  # set when a state is published, replaced by a fresh one at once
        self._clients = 0
        self._producer: asyncio.Task | None = None

    @property
    def clients(self) -> int:
        return self._clients

    @property
    def producing(self) -> bool:
        return self._producer is not None and not self._producer.done()

    async def stream(self, send: Callable[[str], Awaitable[None]]) -> None:
        """Send each new state with `send` until it raises (the client left); never sends one state twice."""
        self._clients += 1
        if self._producer is None or self._producer.done():
            self._tick = asyncio.Event()  # nobody waits on the old one; a fresh one belongs to this event loop
            self._producer = asyncio.create_task(self._produce(), name="live-feed")
        try:
            sent = 0
            while True:
                if self.published == sent:
                    await self._tick.wait()  # Event.wait: a client cancelled here cancels nobody else's wait
                sent = self.published
                await send(self._text)
        finally:
            self._clients -= 1
            if self._clients == 0:
                await self._stop_producer()

    async def _stop_producer(self) -> None:
        producer, self._producer = self._producer, None
        if producer is not None:
            producer.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await producer

    def _publish(self, text: str) -> None:
        self._text = text
        self.published += 1
        tick, self._tick = self._tick, asyncio.Event()
        tick.set()

    async def _produce(self) -> None:
        loop = asyncio.get_running_loop()
        next_time = loop.time()
        while True:
            try:
                # the encoding starlette's send_json uses, done once for every client
                self._publish(json.dumps(self._read_state(), separators=(",", ":"), ensure_ascii=False))
            except Exception:  # a state that cannot be read this tick: say so, and try again next tick
                log.exception("the live state could not be read")
            next_time = max(next_time + self.period_s, loop.time())
            await asyncio.sleep(next_time - loop.time())
