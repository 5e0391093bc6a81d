"""ULog, PX4's flight log format (https://docs.px4.io/main/en/dev_log/ulog_file_format.html), as bytes: pure
encoding, no I/O (sitl_quad.flight_logs writes the files).

A file is the 16-byte header (magic "ULog", version 1, start timestamp in microseconds), the flag bits message
('B'), then the definitions: a format ('F') per topic, information ('I') and parameters ('P'), and a subscription
('A') per topic; then the data section: samples ('D': the topic's msg_id then its fields packed little-endian,
the uint64 timestamp first) and logged strings ('L'). Every message starts with its size (uint16, the header
excluded) and its type (one ASCII byte). PX4 tools (pyulog, FlightPlot, Flight Review) read the files.
"""

from __future__ import annotations

import struct
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

MAGIC = b"ULog\x01\x12\x35"
VERSION = 1
# field type -> struct code; arrays are written "float[4] q" and packed as that many of the code
TYPE_CODES = {
    "int8_t": "b",
    "uint8_t": "B",
    "int16_t": "h",
    "uint16_t": "H",
    "int32_t": "i",
    "uint32_t": "I",
    "int64_t": "q",
    "uint64_t": "Q",
    "float": "f",
    "double": "d",
    "bool": "?",
    "char": "c",
}
# 'L' log levels, as PX4 writes them: the ASCII digit of the syslog level ('0' emergency .. '7' debug), which are
# MAV_SEVERITY's numbers too
LOG_LEVEL_DIGIT = b"01234567"


class ULogError(ValueError):
    """A topic, field or value the format cannot carry."""


@dataclass(frozen=True)
class Topic:
    """A logged topic: its name and its fields after the timestamp, (type, name), e.g. ("float[4]", "q")."""

    name: str
    fields: tuple[tuple[str, str], ...]

    def struct(self) -> struct.Struct:
        codes = ["<Q"]
        for kind, _ in self.fields:
            base, _, count = kind.partition("[")
            if base not in TYPE_CODES:
                raise ULogError(f"{self.name}: unknown field type {kind!r}")
            codes.append(f"{int(count.rstrip(']')) if count else 1}{TYPE_CODES[base]}")
        return struct.Struct("".join(codes))

    def format_text(self) -> str:
        """The 'F' message's text: "name:uint64_t timestamp;type field;..."."""
        return f"{self.name}:uint64_t timestamp;" + "".join(f"{kind} {name};" for kind, name in self.fields)


def _message(kind: bytes, payload: bytes) -> bytes:
    if len(payload) > 0xFFFF:
        raise ULogError(f"ULog message {kind!r} too long: {len(payload)} bytes")
    return struct.pack("<HB", len(payload), kind[0]) + payload


def _key_value(kind: bytes, key: str, value: bytes) -> bytes:
    key_bytes = key.encode()
    return _message(kind, struct.pack("<B", len(key_bytes)) + key_bytes + value)


class ULogEncoder:
    """The bytes of one ULog file, piece by piece: `definitions()` once, then `sample()` and `text()`."""

    def __init__(self, topics: Sequence[Topic]) -> None:
        names = [t.name for t in topics]
        if len(set(names)) != len(names):
            raise ULogError("duplicate topic names")
        self.topics = {t.name: t for t in topics}
        self.ids = {t.name: i for i, t in enumerate(topics)}
        self.structs = {t.name: t.struct() for t in topics}

    def definitions(self, start_us: int, info: Mapping[str, str], parameters: Mapping[str, tuple[int, float]]) -> bytes:
        """Header, flag bits, formats, information, parameters ((MAV_PARAM_TYPE-like kind, value): "int32_t" when
        kind is the INT32 6, else "float") and the subscriptions: everything before the first sample."""
        out = [MAGIC, struct.pack("<BQ", VERSION, start_us)]
        out.append(_message(b"B", bytes(8) + bytes(8) + bytes(3 * 8)))  # no compatible/incompatible flags
        out.extend(_message(b"F", topic.format_text().encode()) for topic in self.topics.values())
        for key, text in info.items():
            value = text.encode()
            out.append(_key_value(b"I", f"char[{len(value)}] {key}", value))
        for name, (kind, value) in parameters.items():
            if kind == 6:
                out.append(_key_value(b"P", f"int32_t {name}", struct.pack("<i", int(value))))
            else:
                out.append(_key_value(b"P", f"float {name}", struct.pack("<f", float(value))))
        for name, msg_id in self.ids.items():
            out.append(_message(b"A", struct.pack("<BH", 0, msg_id) + name.encode()))
        return b"".join(out)

    def sample(self, topic: str, timestamp_us: int, values: Iterable[float | int | bool]) -> bytes:
        """A 'D' message: the topic's fields in their order (arrays flattened)."""
        try:
            packed = self.structs[topic].pack(timestamp_us, *values)
        except KeyError:
            raise ULogError(f"unknown topic {topic!r}") from None
        except struct.error as exc:
            raise ULogError(f"{topic}: {exc}") from exc
        return _message(b"D", struct.pack("<H", self.ids[topic]) + packed)

    @staticmethod
    def text(level: int, timestamp_us: int, text: str) -> bytes:
        """An 'L' message: a logged string at a syslog / MAV_SEVERITY level 0..7."""
        digit = LOG_LEVEL_DIGIT[min(max(level, 0), 7) : min(max(level, 0), 7) + 1]
        return _message(b"L", digit + struct.pack("<Q", timestamp_us) + text.encode())
