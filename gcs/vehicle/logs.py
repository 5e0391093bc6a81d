"""The MAVLink log protocol, client side (https://mavlink.io/en/services/log.html): list the vehicle's flight logs
and download one, as MAVSDK's LogFiles plugin and QGroundControl's log download page do.

`entries()` sends LOG_REQUEST_LIST(0, 0xffff) and collects LOG_ENTRY until it has num_logs of them (a vehicle
with none answers one LOG_ENTRY with num_logs 0), asking again for the ids still missing after a silence.
`download(entry)` sends LOG_REQUEST_DATA for what it lacks and gathers the LOG_DATA pieces (90 bytes each, at their
offsets), asking again from the first hole after `timeout_s` of silence, `retries` times at most, then
LOG_REQUEST_END. PX4 numbers its logs from 0, ArduPilot from 1: entries carry the vehicle's own ids.
Errors are `LogTransferError` (a `LinkError`): `NoLogsError` when the vehicle has none, `LogTimeoutError` on silence,
`LogTooLargeError` for a log over `max_bytes`.
"""

from __future__ import annotations

import asyncio
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from gcs.vehicle.errors import LinkError
from uavcore.mavlink import mavlink

if TYPE_CHECKING:
    from gcs.vehicle.link import LinkManager

DATA_LEN = 90  # LOG_DATA.data
REQUEST_TIMEOUT_S = 1.0  # silence before asking again (a vehicle streams its pieces without pause)
REQUEST_RETRIES = 5
DEFAULT_MAX_BYTES = 64 * 1024 * 1024  # a flight's ULog at PX4's default rates is tens of MB at most
ALL_LOGS = 0xFFFF


@dataclass(frozen=True)
class LogEntry:
    """One of the vehicle's logs, as LOG_ENTRY describes it (MAVSDK's LogFiles.Entry)."""

    id: int
    time_utc: int  # seconds since 1970, 0 when the vehicle does not know
    size_bytes: int


class LogTransferError(LinkError):
    """Listing or downloading the vehicle's logs failed; the message says what and why."""


class NoLogsError(LogTransferError):
    pass


class LogTimeoutError(LogTransferError):
    pass


class LogTooLargeError(LogTransferError):
    pass


class LogClient:
    """The log protocol over a started `LinkManager`; one transfer at a time (the vehicle serves one)."""

    def __init__(self, link: LinkManager, timeout_s: float = REQUEST_TIMEOUT_S, retries: int = REQUEST_RETRIES) -> None:
        self.link = link
        self.timeout_s = timeout_s
        self.retries = retries
        self._lock = asyncio.Lock()

    async def entries(self) -> list[LogEntry]:
        """The vehicle's logs, by id; raises NoLogsError when it has none, LogTimeoutError when it does not answer."""
        async with self._lock:
            with self.link.subscribe({"LOG_ENTRY"}) as inbox:
                found: dict[int, LogEntry] = {}
                count: int | None = None
                for _ in range(self.retries + 1):
                    self._send(mavlink.MAVLink_log_request_list_message(*self.link.target, 0, ALL_LOGS))
                    while (message := await _next(inbox, self.timeout_s)) is not None:
                        if message.num_logs == 0:
                            raise NoLogsError("the vehicle has no flight logs")
                        count = message.num_logs
                        found[message.id] = LogEntry(message.id, message.time_utc, message.size)
                        if len(found) >= count:
                            return [found[key] for key in sorted(found)]
                if count is None:
                    raise LogTimeoutError(
                        f"no answer to LOG_REQUEST_LIST ({self.retries} retries, {self.link.connection})"
                    )
                raise LogTimeoutError(f"{len(found)} of {count} LOG_ENTRY received ({self.retries} retries)")

    async def latest(self) -> LogEntry:
        """The newest log: the highest id (PX4 and ArduPilot both count up)."""
        return (await self.entries())[-1]

    async def download(self, entry: LogEntry, max_bytes: int = DEFAULT_MAX_BYTES) -> bytes:
        """The log's bytes; raises LogTooLargeError before asking for any when it is over max_bytes."""
        if entry.size_bytes > max_bytes:
            raise LogTooLargeError(f"log {entry.id} is {entry.size_bytes} bytes, over the limit of {max_bytes}")
        async with self._lock:
            with self.link.subscribe({"LOG_DATA"}) as inbox:
                try:
                    return await self._gather(inbox, entry)
                finally:
                    self._send(mavlink.MAVLink_log_request_end_message(*self.link.target))

    async def _gather(self, inbox: asyncio.Queue, entry: LogEntry) -> bytes:
        content = bytearray(entry.size_bytes)
        received = [False] * -(-entry.size_bytes // DATA_LEN)  # per 90-byte piece
        tries_left = self.retries
        while (start := _first_missing(received)) is not None:
            offset = start * DATA_LEN
            self._send(
                mavlink.MAVLink_log_request_data_message(*self.link.target, entry.id, offset, entry.size_bytes - offset)
            )
            progressed = False
            while (message := await _next(inbox, self.timeout_s)) is not None:
                if message.id != entry.id or message.ofs % DATA_LEN or message.count > DATA_LEN:
                    continue  # another log's, or not a piece this client asked for
                if message.count == 0 or message.ofs >= entry.size_bytes:
                    break  # the vehicle says the log ends here
                piece = bytes(message.data[: message.count])
                content[message.ofs : message.ofs + len(piece)] = piece[: entry.size_bytes - message.ofs]
                received[message.ofs // DATA_LEN] = True
                progressed = True
                if all(received):
                    return bytes(content)
            if progressed:
                tries_left = self.retries
            elif tries_left == 0:
                raise LogTimeoutError(f"no LOG_DATA for log {entry.id} at offset {offset} ({self.retries} retries)")
            else:
                tries_left -= 1
        return bytes(content)

    def _send(self, message: Any) -> None:
        self.link.send(message)


async def _next(inbox: asyncio.Queue, timeout_s: float) -> Any | None:
    try:
        async with asyncio.timeout(timeout_s):
            return await inbox.get()
    except TimeoutError:
        return None


def _first_missing(received: list[bool]) -> int | None:
    return next((index for index, done in enumerate(received) if not done), None)
