"""GET /missions' filters and pages, pure: which missions a query asks for, and the cursor that resumes a listing.

The list is newest first by (created_at, id): the time the mission was stored, then its id for missions stored in
the same millisecond. A page ends at its last mission's (created_at, id), its `PageKey`; the next page is the
missions strictly before that key (keyset pagination), so a mission created while a client walks the pages never
shifts the pages that follow, as an offset would.

Times are compared as the text storage keeps (`stored_time`: ISO 8601 in UTC to the millisecond, one fixed width
for every instant from year 1 to 9999), so the bounds given as any offset become that text and SQL compares
strings, on SQLite and PostgreSQL alike, along the index on (created_at, id).
"""

from __future__ import annotations

import base64
import binascii
import json
from dataclasses import dataclass
from datetime import UTC, date, datetime, timedelta
from typing import Annotated, Any

from pydantic import PlainValidator, WithJsonSchema

from gcs.domain.status import MissionStatus

MAX_ID = 2**63 - 1  # a mission id fits a signed 64-bit integer (SQLite's INTEGER, PostgreSQL's BIGINT)
MAX_CURSOR = 200  # characters: a cursor of ours is about 70
CURSOR_PATTERN = "^[A-Za-z0-9_-]+$"  # base64url without its padding
_MILLISECOND = timedelta(milliseconds=1)
_EARLIEST, _LATEST = datetime.min.replace(tzinfo=UTC), datetime.max.replace(tzinfo=UTC)


def stored_time(moment: datetime) -> str:
    """An aware instant as storage keeps it (created_at, updated_at): in UTC, to the millisecond."""
    return moment.astimezone(UTC).isoformat(timespec="milliseconds")


@dataclass(frozen=True)
class PageKey:
    """Where a page of the list ends: its last mission's creation time (as stored) and id."""

    created_at: str
    id: int


class CursorError(ValueError):
    """A cursor this service did not give."""


def encode_cursor(key: PageKey) -> str:
    """The opaque `cursor` that asks for the missions after `key`: base64url (no padding) of [created_at, id]."""
    text = json.dumps([key.created_at, key.id], separators=(",", ":"))
    return base64.urlsafe_b64encode(text.encode()).decode().rstrip("=")


def decode_cursor(cursor: str) -> PageKey:
    """The PageKey a cursor from `encode_cursor` holds; raises CursorError for anything else."""
    invalid = CursorError(
        f"{cursor[:40]!r} is not a cursor this service gave: pass on the one in the previous page's "
        'X-Next-Cursor header (or follow its Link rel="next" URL)'
    )
    try:
        created_at, mission_id = json.loads(base64.urlsafe_b64decode(cursor + "=" * (-len(cursor) % 4)))
        when = datetime.fromisoformat(created_at)
    except (binascii.Error, ValueError, TypeError):  # not base64, not JSON (a ValueError), not two items, not a time
        raise invalid from None
    # bool is an int in Python, and a time without an offset is not one storage wrote
    if type(mission_id) is not int or not 1 <= mission_id <= MAX_ID or when.tzinfo is None:
        raise invalid
    # the key as it was stored, not re-formatted: the next page starts exactly after that row
    return PageKey(created_at, mission_id)


def _time_bound(value: Any) -> datetime | date:
    """A date-time with its UTC offset, or a date: parsed from ISO 8601 text."""
    if isinstance(value, date):  # a datetime is a date too: both pass as they are
        if isinstance(value, datetime) and value.tzinfo is None:
            raise ValueError(f"{value.isoformat()} has no UTC offset")
        return value
    text = str(value)
    try:
        return date.fromisoformat(text)
    except ValueError:
        pass
    try:
        moment = datetime.fromisoformat(text)
    except ValueError:
        raise ValueError(
            f"{text[:40]!r} is not an ISO 8601 date-time with its offset (2026-11-27T09:30:00+01:00, "
            "2026-11-27T08:30:00Z) or a date (2026-11-27)"
        ) from None
    if moment.tzinfo is None:
        raise ValueError(f"{text!r} has no UTC offset: give one (+01:00, Z), or a date alone")
    return moment


# GET /missions' `since` and `until`: a date-time with an offset, or a date (a day in UTC); anything else (a
# date-time without an offset, whose instant is unknown) is a 422 naming the field.
TimeBound = Annotated[
    datetime | date,
    PlainValidator(_time_bound),
    WithJsonSchema({"anyOf": [{"type": "string", "format": "date-time"}, {"type": "string", "format": "date"}]}),
]


def _utc(moment: datetime) -> datetime:
    """The instant in UTC, clamped to the years datetime holds (0001-01-01T00:00+05:00 is before year 1 in UTC)."""
    try:
        return moment.astimezone(UTC)
    except OverflowError:
        return _EARLIEST if moment.year == 1 else _LATEST


def _ceil_to_stored(moment: datetime) -> str:
    """The stored text of the first millisecond at or after `moment`: created_at is kept to the millisecond, so
    `created_at >= this` is exactly "created at or after `moment`" (and `<` exactly "before")."""
    utc = _utc(moment)
    whole = utc.replace(microsecond=utc.microsecond // 1000 * 1000)
    if whole < utc:
        whole = whole + _MILLISECOND if whole < _LATEST - _MILLISECOND else _LATEST
    return stored_time(whole)


def _day_start(day: date) -> datetime:
    return datetime(day.year, day.month, day.day, tzinfo=UTC)


@dataclass(frozen=True)
class MissionFilter:
    """GET /missions' filters on the missions listed (a fleet mission, never its parts); empty or None: not
    filtered on. They combine (AND); the statuses are alternatives (OR)."""

    statuses: tuple[MissionStatus, ...] = ()  # the mission's own status (a fleet mission's, not its parts')
    vehicle: int | None = None  # the system id it was stored for; a fleet mission: any of its parts'
    since: str | None = None  # created at or after this stored time
    until: str | None = None  # created before this stored time

    @classmethod
    def of(
        cls,
        statuses: list[MissionStatus] | None = None,
        vehicle: int | None = None,
        since: datetime | date | None = None,
        until: datetime | date | None = None,
    ) -> MissionFilter:
        """The filter for the query's values: a date as `since` is its first instant (00:00 UTC), a date as
        `until` its whole day (until the next day's 00:00 UTC); a date-time is that instant."""
        if isinstance(until, date) and not isinstance(until, datetime):
            until = None if until == date.max else _day_start(until + timedelta(days=1))
        if isinstance(since, date) and not isinstance(since, datetime):
            since = _day_start(since)
        return cls(
            statuses=tuple(dict.fromkeys(statuses or ())),  # a status given twice is asked once
            vehicle=vehicle,
            since=None if since is None else _ceil_to_stored(since),
            until=None if until is None else _ceil_to_stored(until),
        )

    @property
    def empty_window(self) -> bool:
        """No mission can pass: `until` is not after `since`."""
        return self.since is not None and self.until is not None and self.until <= self.since
