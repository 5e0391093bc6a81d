"""An NMEA 0183 AIS feed, line by line, into AtoN reports (uavcore.ais), with bounded memory and a bounded rate.
Pure computation: the caller hands over what it read and the time (a monotonic clock, seconds).

- **Sentences**: `!AIVDM` (what a receiver heard) and `!AIVDO` (a station's own), with or without an NMEA 4.10 tag
  block in front (`\\s:STATION,c:UNIXTIME*hh\\!AIVDM,...`, as shore stations send): the tag block's station and
  time go with the report. pyais parses the fields and the payload's bits.
- **Multi-part messages** are held until every part is in, keyed by where they came from (`origin`: the peer that
  sent them), talker, sentence type, sequential message id, channel and part count, so parts may arrive out of
  order and interleaved with other messages' and other peers'. A group not completed within `group_timeout_s` is
  dropped, and at most `max_groups` are held (the oldest goes first): its parts are counted as `parts_dropped`.
- **Faults are counted, never raised**: a bad checksum (sentence or tag block), a message type AIS does not define,
  a line that is no AIS sentence at all, one longer than `max_line_bytes`. Messages of other types (position
  reports 1-3, static data 5, ...) are well formed but not ours: counted as `other_type` and not decoded further.
- **Rate**: a token bucket per decoder (one per source): `rate_lines_s` lines a second sustained, bursts of
  `burst_lines`. Lines beyond it are dropped before any parsing and counted (`rate_dropped`); a stream read while
  the bucket is empty is counted and dropped a chunk at a time, without splitting it into lines
  (`feed_stream`), so a flood costs little more than reading it. The transport may also stop reading while
  `throttled` (gcs.ais.receivers does for UDP: the kernel then drops the excess).
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import asdict, dataclass, field

from pyais.messages import AISSentence, MessageType21, NMEASentenceFactory, TagBlock

from uavcore.ais import ATON_MESSAGE_TYPE, AtonReport

DEFINED_MESSAGE_TYPES = range(1, 28)  # ITU-R M.1371-5 defines messages 1 to 27
MAX_STATION_CHARS = 64  # a tag block's station name kept at most this long


@dataclass(frozen=True)
class StreamLimits:
    """What one source may cost: memory (line length, partial groups) and time (lines parsed per second)."""

    max_line_bytes: int = 512  # NMEA 0183 caps a sentence at 82 characters; a tag block adds well under 100
    max_groups: int = 100  # multi-part messages being assembled at once
    group_timeout_s: float = 5.0  # a message's parts follow each other within a slot or two (tens of ms) on air
    rate_lines_s: float = 500.0  # a busy harbour's receiver delivers tens of lines a second
    burst_lines: float = 1000.0


@dataclass
class StreamCounts:
    """What a decoder did with the lines it was given. A line dropped on its own (rate, length, not a sentence,
    checksum) counts once as that; the other outcomes count messages, a multi-part one once for all its parts."""

    lines: int = 0  # every line but blank ones
    decoded: int = 0  # AtoN reports (message 21) decoded
    other_type: int = 0  # well-formed messages of another type (1, 3, 5, ...): ignored
    unknown_type: int = 0  # a message type AIS does not define (0, 28-63)
    bad_checksum: int = 0  # the sentence's or its tag block's checksum is wrong (or missing)
    malformed: int = 0  # no AIS sentence: garbage, other NMEA sentences, broken fields, a truncated message 21
    too_long: int = 0  # over max_line_bytes
    rate_dropped: int = 0  # beyond the token bucket
    parts: int = 0  # parts of multi-part messages (the message is counted when its last part is in)
    parts_dropped: int = 0  # parts of messages never completed (timed out, evicted, or their id reused)

    def as_dict(self) -> dict[str, int]:
        return asdict(self)


class TokenBucket:
    """`rate` tokens a second, at most `burst` saved up; `take` spends one if there is one."""

    def __init__(self, rate: float, burst: float, now: float) -> None:
        self.rate, self.burst = rate, burst
        self.tokens, self._at = burst, now

    def _refill(self, now: float) -> None:
        if now > self._at:  # a clock that went back refills nothing (and takes nothing)
            self.tokens = min(self.burst, self.tokens + (now - self._at) * self.rate)
            self._at = now

    def take(self, now: float) -> bool:
        self._refill(now)
        if self.tokens >= 1.0:
            self.tokens -= 1.0
            return True
        return False

    def empty(self, now: float) -> bool:
        self._refill(now)
        return self.tokens < 1.0

    def wait_s(self, now: float) -> float:
        """Seconds until a token is there (0 if one is)."""
        self._refill(now)
        return max(0.0, (1.0 - self.tokens) / self.rate)


@dataclass
class _Group:
    """A multi-part message being assembled: its parts by number, when its first part came, its tag block's data."""

    started: float
    parts: dict[int, AISSentence] = field(default_factory=dict)
    station_time: float | None = None
    station: str | None = None


_GroupKey = tuple[str, str, str, int | None, str, int]


def _tag_fields(tag: TagBlock | None) -> tuple[float | None, str | None]:
    """A valid tag block's receive time (unix seconds; some stations send milliseconds) and station name."""
    if tag is None:
        return None, None
    try:
        stamp = float(tag.receiver_timestamp) if tag.receiver_timestamp else None
    except ValueError:
        stamp = None
    if stamp is not None and stamp > 1e11:  # 1e11 s is the year 5138; 1e11 ms is 1973
        stamp /= 1000.0
    station = tag.source_station[:MAX_STATION_CHARS] if tag.source_station else None
    return stamp, station


class AisStreamDecoder:
    """One source's lines into AtoN reports (module docstring). `counts` says what became of every line."""

    def __init__(self, limits: StreamLimits | None = None, now: float = 0.0) -> None:
        self.limits = limits or StreamLimits()
        self.counts = StreamCounts()
        self._bucket = TokenBucket(self.limits.rate_lines_s, self.limits.burst_lines, now)
        self._groups: OrderedDict[_GroupKey, _Group] = OrderedDict()  # oldest first
        self._partial = b""  # feed_stream: the unfinished line at the end of the last chunk
        self._skipping: str | None = None  # feed_stream: the line in progress is dropped; counted as this at its end

    # ----- the rate bound
    def throttled(self, now: float) -> bool:
        """No line would be parsed now: the transport may stop reading for `retry_after_s`."""
        return self._bucket.empty(now)

    def retry_after_s(self, now: float) -> float:
        return self._bucket.wait_s(now)

    # ----- what a transport hands over
    def feed_datagram(self, data: bytes, now: float, origin: str = "") -> list[AtonReport]:
        """The lines of one UDP datagram (a receiver sends one or several sentences per datagram)."""
        reports = []
        for line in data.split(b"\n"):
            report = self.feed(line, now, origin)
            if report is not None:
                reports.append(report)
        return reports

    def feed_stream(self, chunk: bytes, now: float, origin: str = "") -> list[AtonReport]:
        """A chunk of a byte stream (TCP): lines may span chunks. While throttled the chunk is dropped whole, its
        line ends counted, without splitting it (a flood costs about what reading it does)."""
        if self._bucket.empty(now):
            self._discard(chunk)
            return []
        *complete, tail = chunk.split(b"\n")
        reports = []
        if complete:
            if self._skipping is not None:  # the end of a line already dropped
                if self._skipping == "rate_dropped":
                    self._count("rate_dropped", line=True)
                self._skipping, complete = None, complete[1:]
            else:
                complete[0] = self._partial + complete[0]
            self._partial = b""
            for line in complete:
                report = self.feed(line, now, origin)
                if report is not None:
                    reports.append(report)
        if self._skipping is None:
            self._keep_partial(self._partial + tail)
        return reports

    def _discard(self, chunk: bytes) -> None:
        """feed_stream while throttled: every line ending in chunk is dropped; the line in progress after it is kept."""
        last = chunk.rfind(b"\n")
        if last < 0:
            if self._skipping is None and (self._partial or chunk.strip()):
                self._skipping, self._partial = "rate_dropped", b""  # counted when it ends
            return
        ended = chunk.count(b"\n", 0, last + 1)
        if self._skipping == "too_long":
            ended -= 1  # that line was counted when it was found too long
        self.counts.lines += ended
        self.counts.rate_dropped += ended
        self._skipping = None
        self._keep_partial(chunk[last + 1 :])

    def _keep_partial(self, partial: bytes) -> None:
        if len(partial) > self.limits.max_line_bytes:  # no line end in sight: drop it up to its end
            self._count("too_long", line=True)
            self._partial, self._skipping = b"", "too_long"
        else:
            self._partial = partial

    def _count(self, outcome: str, line: bool = False) -> None:
        """One more of this outcome (and one more line, for a line dropped before feed saw it)."""
        self.counts.lines += line
        setattr(self.counts, outcome, getattr(self.counts, outcome) + 1)

    # ----- one line
    def feed(self, line: bytes, now: float, origin: str = "") -> AtonReport | None:
        """One line (line end optional): the AtoN report it completes, if any; whatever else, counted."""
        line = line.strip()
        if not line:
            return None  # blank lines (a CR LF split at the LF) are no lines
        self.counts.lines += 1
        if not self._bucket.take(now):
            self._count("rate_dropped")
            return None
        if len(line) > self.limits.max_line_bytes:
            self._count("too_long")
            return None
        try:
            sentence = NMEASentenceFactory.produce(line)
        except Exception:  # pyais parses input from the air: whatever it raises, the line is not a sentence
            self._count("malformed")
            return None
        if not isinstance(sentence, AISSentence):  # e.g. a Gatehouse $PGHP wrapper: no AIS payload
            self._count("malformed")
            return None
        tag = sentence.tag_block
        if tag is not None:
            tag.init()
        if not sentence.is_valid or (tag is not None and not tag.is_valid):
            self._count("bad_checksum")
            return None
        station_time, station = _tag_fields(tag)
        if sentence.frag_cnt == 1:
            return self._message([sentence], station_time, station)
        return self._part(sentence, now, origin, station_time, station)

    def expire(self, now: float) -> None:
        """Drop the multi-part groups not completed within group_timeout_s (also done at every part)."""
        deadline = now - self.limits.group_timeout_s
        while self._groups:
            key, oldest = next(iter(self._groups.items()))
            if oldest.started >= deadline:
                break
            del self._groups[key]
            self.counts.parts_dropped += len(oldest.parts)

    @property
    def pending_groups(self) -> int:
        return len(self._groups)

    def _part(
        self, sentence: AISSentence, now: float, origin: str, station_time: float | None, station: str | None
    ) -> AtonReport | None:
        self.counts.parts += 1
        self.expire(now)
        key = (origin, sentence.talker_id, sentence.type, sentence.seq_id, sentence.channel, sentence.frag_cnt)
        group = self._groups.get(key)
        if group is not None and sentence.frag_num in group.parts:
            # the same part again: its group never completed and the sequential id (0-9) came round again
            del self._groups[key]
            self.counts.parts_dropped += len(group.parts)
            group = None
        if group is None:
            if len(self._groups) >= self.limits.max_groups:
                _, evicted = self._groups.popitem(last=False)
                self.counts.parts_dropped += len(evicted.parts)
            group = self._groups[key] = _Group(now)
        group.parts[sentence.frag_num] = sentence
        group.station_time = group.station_time if station_time is None else station_time
        group.station = group.station or station
        if len(group.parts) < sentence.frag_cnt:
            return None
        del self._groups[key]
        return self._message([group.parts[n] for n in sorted(group.parts)], group.station_time, group.station)

    def _message(self, parts: list[AISSentence], station_time: float | None, station: str | None) -> AtonReport | None:
        """A whole message (its parts in order): an AtoN report, or its outcome counted."""
        counts = self.counts
        # pyais joins the payloads in part order and takes the fill bits of the list's last: in order already
        sentence = AISSentence.assemble_from_iterable(parts)
        msg_type = sentence.ais_id
        if msg_type != ATON_MESSAGE_TYPE:
            if msg_type in DEFINED_MESSAGE_TYPES:
                counts.other_type += 1
            else:
                counts.unknown_type += 1
            return None
        try:
            message = sentence.decode()
            if not isinstance(message, MessageType21):
                raise ValueError(f"pyais decoded message 21 as {type(message).__name__}")
            report = AtonReport.from_message(message, station_time, station)
        except Exception:  # a truncated or corrupt payload whose checksum happened to hold: not a report
            counts.malformed += 1
            return None
        counts.decoded += 1
        return report
