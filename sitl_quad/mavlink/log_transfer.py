"""The MAVLink log protocol (https://mavlink.io/en/services/log.html) over the vehicle's flight logs
(sitl_quad.flight_logs), as PX4's mavlink_log_handler serves them:

- LOG_REQUEST_LIST(start, end) -> a LOG_ENTRY(id, num_logs, last_log_num, time_utc, size) per finished log with
  start <= id <= end; ids count from 0, oldest first, last_log_num = num_logs - 1. No logs: one LOG_ENTRY with
  id 0 and num_logs 0 (what MAVSDK's LogFiles plugin reads as "no log files").
- LOG_REQUEST_DATA(id, ofs, count) -> LOG_DATA(id, ofs, count, data[90]) from ofs on, in 90-byte pieces, until
  count bytes or the end of the file; a new request replaces the one being served (MAVSDK asks chunk by chunk
  and asks again for a chunk it missed). An offset at or past the end gets one LOG_DATA with count 0; an unknown
  id gets nothing (as PX4).
- LOG_REQUEST_END stops the transfer; LOG_ERASE deletes the finished logs.
The pieces go out from `poll()` at up to DATA_RATE_PER_S on the wall clock, a few at each pass of the loop, so a
download never stalls the simulation and a client's socket buffer is not flooded.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

from sitl_quad.flight_logs import FlightLogs
from uavcore.mavlink import mavlink

log = logging.getLogger(__name__)

DATA_LEN = 90  # LOG_DATA.data
DATA_RATE_PER_S = 4000.0  # LOG_DATA messages a second at most: 360 kB/s, a 1 MB log in 3 s
MAX_BURST = 64  # pieces sent in one pass of the loop at most


@dataclass
class Transfer:
    """The LOG_REQUEST_DATA being served."""

    log_id: int
    data: bytes  # the whole file (a log of a flight is at most a few MB)
    offset: int
    end: int  # offset after the last byte to send
    peer: object


class LogTransfer:
    def __init__(self, logs: FlightLogs, send) -> None:
        self.logs = logs
        self.send = send  # callable(msg, peer=None)
        self.transfer: Transfer | None = None
        self._allowance = 0.0
        self._last_poll: float | None = None
        self.pieces_sent = 0
        self._cached: tuple[Path, bytes] | None = None  # the log last asked for

    def handlers(self) -> dict:
        return {
            "LOG_REQUEST_LIST": self.request_list,
            "LOG_REQUEST_DATA": self.request_data,
            "LOG_REQUEST_END": self.request_end,
            "LOG_ERASE": self.erase,
        }

    def request_list(self, peer, msg) -> None:
        entries = self.logs.entries()
        if not entries:
            self.send(mavlink.MAVLink_log_entry_message(0, 0, 0, 0, 0), peer)
            return
        last = len(entries) - 1
        for log_id in range(max(0, msg.start), min(last, msg.end) + 1):
            entry = entries[log_id]
            self.send(mavlink.MAVLink_log_entry_message(log_id, len(entries), last, entry.time_utc, entry.size), peer)

    def request_data(self, peer, msg) -> None:
        entries = self.logs.entries()
        if not 0 <= msg.id < len(entries):
            log.info("LOG_REQUEST_DATA for log %d: there are %d", msg.id, len(entries))
            return
        data = self._read(entries[msg.id].path)
        if data is None:
            return
        if msg.ofs >= len(data):
            self.send(mavlink.MAVLink_log_data_message(msg.id, msg.ofs, 0, bytes(DATA_LEN)), peer)
            self.transfer = None
            return
        end = min(len(data), msg.ofs + msg.count)
        self.transfer = Transfer(msg.id, data, msg.ofs, end, peer)

    def _read(self, path: Path) -> bytes | None:
        """The log's bytes, read once: MAVSDK asks for a log chunk by chunk, and a finished log never changes."""
        if self._cached is not None and self._cached[0] == path:
            return self._cached[1]
        try:
            data = path.read_bytes()
        except OSError as exc:  # erased meanwhile
            log.info("log %s unreadable: %s", path.name, exc)
            return None
        self._cached = (path, data)
        return data

    def request_end(self, peer, msg) -> None:
        self.transfer = None

    def erase(self, peer, msg) -> None:
        self.transfer = self._cached = None
        erased = self.logs.erase()
        log.info("LOG_ERASE: %d logs deleted", erased)

    def poll(self, now: float) -> None:
        """Each loop pass (wall clock): the pieces of the transfer due by now."""
        elapsed = 0.0 if self._last_poll is None else now - self._last_poll
        self._last_poll = now
        transfer = self.transfer
        if transfer is None:
            self._allowance = 0.0
            return
        self._allowance = min(MAX_BURST, self._allowance + elapsed * DATA_RATE_PER_S)
        pieces = int(self._allowance)
        self._allowance -= pieces
        for _ in range(pieces):  # none until a whole piece is due
            piece = transfer.data[transfer.offset : min(transfer.end, transfer.offset + DATA_LEN)]
            padded = piece + bytes(DATA_LEN - len(piece))
            self.send(
                mavlink.MAVLink_log_data_message(transfer.log_id, transfer.offset, len(piece), padded), transfer.peer
            )
            self.pieces_sent += 1
            transfer.offset += len(piece)
            if transfer.offset >= transfer.end:
                self.transfer = None
                return
