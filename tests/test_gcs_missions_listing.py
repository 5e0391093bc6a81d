"""GET /missions' filters and cursor pagination, on SQLite and PostgreSQL: pages walk every mission exactly once,
newest first by (created_at, id), following the Link header; each filter narrows as documented; the filters
combine with paging; bad input is a 422 naming its field; a fleet mission is listed (never its parts) under every
filter; the cached pages follow every write.

Missions are stored through a second storage object on the service's database (as another instance would write
them), with the creation times each test gives; the service reads them through its API.
"""

from __future__ import annotations

import base64
from collections.abc import Iterator
from datetime import UTC, date, datetime, timedelta, timezone
from pathlib import Path

import pytest
from fastapi.testclient import TestClient
from stored_missions import FLIGHT, PLAN
from test_gcs_api import BUOYS, errors_of, make_client

from gcs.domain.listing import CursorError, MissionFilter, PageKey, decode_cursor, encode_cursor
from gcs.domain.status import MissionStatus
from gcs.storage import Storage, open_storage
from gcs.storage.base import next_version

T0 = datetime(2026, 3, 1, 12, 0, tzinfo=UTC)


@pytest.fixture
def client(database: str | Path, tmp_path: Path) -> Iterator[TestClient]:
    """The service on the test's database (no vehicle)."""
    with make_client(tmp_path, **({"db": database} if isinstance(database, str) else {})) as service:
        yield service


@pytest.fixture
def other(database: str | Path, client: TestClient) -> Iterator[Storage]:
    """A second storage on the service's database (opened after the service migrated it)."""
    storage = open_storage(database)
    yield storage
    storage.close()


def created(storage: Storage, mission_id: int, at: datetime) -> int:
    """Give a stored mission this creation time, moving the change counter as every mission write does."""
    with storage.transaction() as db:
        db.execute(
            "UPDATE missions SET created_at = ?, version = ? WHERE id = ?",
            (at.astimezone(UTC).isoformat(timespec="milliseconds"), next_version(db), mission_id),
        )
    return mission_id


def mission(storage: Storage, at: datetime, status: str = "planned", vehicle: int | None = None) -> int:
    mission_id = storage.create_mission(FLIGHT, PLAN, vehicle_sysid=vehicle)
    if status != "planned":
        storage.set_status(mission_id, MissionStatus(status))
    return created(storage, mission_id, at)


def ids(response) -> list[int]:
    assert response.status_code == 200, response.text
    return [m["id"] for m in response.json()]


def walk(client: TestClient, url: str) -> list[list[int]]:
    """Every page from `url` on, following the Link header; checks the headers agree on every page."""
    pages = []
    while url:
        response = client.get(url)
        pages.append(ids(response))
        link, cursor = response.headers.get("link"), response.headers.get("x-next-cursor")
        assert (link is None) == (cursor is None), response.headers
        if link is None:
            break
        assert link.startswith("</missions?") and link.endswith('>; rel="next"')
        url = link[1 : -len('>; rel="next"')]
        assert url.endswith(f"cursor={cursor}")
        assert len(pages) < 100, "the pages never end"
    return pages


@pytest.fixture
def history(other: Storage) -> dict[str, int]:
    """Missions over three days, stored out of creation order: two created in the same millisecond (the id breaks
    the tie), single missions on vehicles 1 and 2 and on the service's one vehicle (no vehicle stored), and a
    fleet mission whose parts fly vehicles 2 and 3."""
    named = {
        "old_done": mission(other, T0 - timedelta(days=2), "completed", vehicle=1),
        "old_failed": mission(other, T0 - timedelta(days=1, hours=1), "failed", vehicle=2),
        "tie_a": mission(other, T0, "planned"),
        "tie_b": mission(other, T0, "aborted", vehicle=2),
        "newest": mission(other, T0 + timedelta(hours=5), "flying", vehicle=1),
        "earliest": mission(other, T0 - timedelta(days=3), "failed"),  # stored last, created first
    }
    fleet, parts = other.create_fleet_mission(FLIGHT, PLAN, [(FLIGHT, PLAN, 2), (FLIGHT, PLAN, 3)])
    other.set_status(fleet, MissionStatus.COMPLETED)
    named["fleet"] = created(other, fleet, T0 + timedelta(hours=1))
    for part in parts:  # the parts newer than everything: were they listed, they would come first
        created(other, part, T0 + timedelta(days=1))
    return named


# newest first by (created_at, id): the tie's later id first
ORDER = ["newest", "fleet", "tie_b", "tie_a", "old_failed", "old_done", "earliest"]


def listed(history: dict[str, int], *names: str) -> list[int]:
    """The ids of these missions in the list's order."""
    return [history[name] for name in ORDER if name in names]


# ----- paging
def test_pages_of_two_walk_every_mission_once_newest_first(client, history):
    pages = walk(client, "/missions?limit=2")
    assert [len(page) for page in pages] == [2, 2, 2, 1]
    assert [i for page in pages for i in page] == listed(history, *ORDER)
    assert ids(client.get("/missions")) == listed(history, *ORDER)  # one page of 100: the same order


def test_the_last_full_page_has_no_next_page(client, history):
    pages = walk(client, "/missions?limit=7")
    assert pages == [listed(history, *ORDER)]
    assert "link" not in client.get("/missions?limit=7").headers


def test_a_mission_created_while_a_client_pages_neither_shifts_nor_repeats_the_pages(client, other, history):
    first = client.get("/missions?limit=3")
    assert ids(first) == listed(history, "newest", "fleet", "tie_b")
    mission(other, T0 + timedelta(days=5))  # newer than all: an offset would now repeat tie_b
    rest = walk(client, first.headers["link"][1:].split(">")[0])
    assert [i for page in rest for i in page] == listed(history, "tie_a", "old_failed", "old_done", "earliest")


# ----- filters
@pytest.mark.parametrize(
    ("query", "names"),
    [
        ("status=failed", ["old_failed", "earliest"]),
        ("status=completed&status=aborted", ["fleet", "tie_b", "old_done"]),  # a fleet mission's own status
        ("status=waiting_for_battery", []),
        ("vehicle=1", ["newest", "old_done"]),
        ("vehicle=2", ["fleet", "tie_b", "old_failed"]),  # the fleet mission: its part flies vehicle 2
        ("vehicle=3", ["fleet"]),  # only a part flies it: the fleet mission is listed, the part is not
        ("vehicle=9", []),
        ("since=2026-03-01T12:00:00Z", ["newest", "fleet", "tie_b", "tie_a"]),  # inclusive
        ("since=2026-03-01T13:00:00.001%2B01:00", ["newest", "fleet"]),  # 12:00:00.001 UTC: after the tie
        ("until=2026-03-01T12:00:00Z", ["old_failed", "old_done", "earliest"]),  # exclusive
        ("until=2026-03-01T07:00:00.001-05:00", ["tie_b", "tie_a", "old_failed", "old_done", "earliest"]),
        ("since=2026-03-01", ["newest", "fleet", "tie_b", "tie_a"]),  # a date: from its 00:00 UTC
        ("until=2026-02-28", ["old_failed", "old_done", "earliest"]),  # a date: through its end
        ("since=2026-02-28&until=2026-02-28", ["old_failed"]),  # one whole day
    ],
)
def test_each_filter_narrows_the_list(client, history, query, names):
    assert ids(client.get(f"/missions?{query}")) == listed(history, *names)


def test_filters_combine_and_their_pages_keep_every_parameter(client, history):
    query = "status=completed&status=aborted&status=flying&vehicle=2&since=2026-03-01&limit=1"
    pages = walk(client, f"/missions?{query}")
    assert pages == [[history["fleet"]], [history["tie_b"]]]
    link = client.get(f"/missions?{query}").headers["link"]
    for parameter in query.split("&"):  # the repeated status too, each kept
        assert parameter in link
    query = "vehicle=1&until=2026-03-02T00:00:00%2B00:00&limit=1"
    assert walk(client, f"/missions?{query}") == [[history["newest"]], [history["old_done"]]]


def test_a_fleet_missions_parts_are_never_listed(client, other, history):
    parts = [part.id for part in other.fleet_parts(history["fleet"])]
    for query in ("", "vehicle=2", "vehicle=3", "status=planned", "since=2026-03-02", "limit=1"):
        listed_ids = [i for page in walk(client, f"/missions?{query}") for i in page]
        assert not set(parts) & set(listed_ids), query


# ----- bad input: 422 at the field
def cursor_of(document: bytes) -> str:
    return base64.urlsafe_b64encode(document).decode().rstrip("=")


NO_OFFSET = cursor_of(b'["2026-03-01T12:00:00", 2]')  # a time storage never wrote
NOT_AN_ID = cursor_of(b'["2026-03-01T12:00:00.000+00:00", true]')


@pytest.mark.parametrize(
    ("query", "loc", "says"),
    [
        ("cursor=bm90LWEtY3Vyc29y", ["query", "cursor"], "not a cursor this service gave"),  # base64, not ours
        (f"cursor={cursor_of(b'[1, 2]')}", ["query", "cursor"], "not a cursor"),
        (f"cursor={NO_OFFSET}", ["query", "cursor"], "not a cursor"),
        (f"cursor={NOT_AN_ID}", ["query", "cursor"], "not a cursor"),
        ("cursor=a%2Fb", ["query", "cursor"], "pattern"),
        ("status=done", ["query", "status", 0], "'completed'"),
        ("status=failed&status=lost", ["query", "status", 1], "'failed'"),
        ("since=yesterday", ["query", "since"], "not an ISO 8601 date-time"),
        ("until=2026-03-01T12:00:00", ["query", "until"], "has no UTC offset"),
        ("since=2026-03-02&until=2026-03-01", ["query", "until"], "until must be after since"),
        ("vehicle=0", ["query", "vehicle"], "greater than or equal to 1"),
        ("limit=1001", ["query", "limit"], "less than or equal to 1000"),
    ],
)
def test_bad_input_is_a_422_naming_the_field(client, query, loc, says):
    ((where, message),) = errors_of(client.get(f"/missions?{query}"))
    assert where == loc and says in message, message


# ----- the cache
def test_every_page_follows_the_writes_and_the_plain_list_is_served_from_the_cache(client, other, history):
    pages = client.app.state.service.mission_pages
    plain = client.get("/missions").content
    hits = pages.hits
    assert client.get("/missions").content == plain and pages.hits == hits + 1  # no write: the same bytes, cached
    assert ids(client.get("/missions?status=uploading")) == []
    other.set_status(history["tie_a"], MissionStatus.UPLOADING)  # behind the service's back
    assert ids(client.get("/missions?status=uploading")) == [history["tie_a"]]
    assert client.get("/missions").json()[3]["status"] == "uploading"
    second_page = client.get("/missions?limit=2").headers["link"][1:].split(">")[0]
    assert ids(client.get(second_page)) == listed(history, "tie_b", "tie_a")
    created(other, history["tie_b"], T0 + timedelta(days=9))  # now the newest: off the second page, onto the first
    assert ids(client.get(second_page)) == listed(history, "tie_a", "old_failed")
    assert ids(client.get("/missions?limit=2")) == [history["tie_b"], history["newest"]]
    # a mission deleted (not the latest written: the highest version stays) is gone from every list at once
    before = ids(client.get("/missions"))
    other.delete_mission(history["old_failed"])
    assert ids(client.get("/missions")) == [i for i in before if i != history["old_failed"]]
    # the latest written deleted and another mission stored: the list shows the new one, never the deleted one
    # (a counter derived from the missions gave the new one the deleted one's number, the cached list's key)
    before = ids(client.get("/missions"))
    other.delete_mission(history["tie_b"])
    newer = mission(other, T0 + timedelta(days=10))
    assert ids(client.get("/missions")) == [newer] + [i for i in before if i != history["tie_b"]]


# ----- through the API as clients create missions
def test_missions_created_with_start_false_are_paged_newest_first(client):
    answers = [client.post("/missions", json={"buoys": BUOYS, "start": False}).json() for _ in range(5)]
    created_ids = [answer["id"] for answer in answers]
    newest_first = created_ids[::-1]
    assert walk(client, "/missions?limit=2&status=planned") == [newest_first[:2], newest_first[2:4], newest_first[4:]]
    first_day, last_day = (answers[i]["created_at"][:10] for i in (0, -1))  # UTC dates: two if midnight passed
    assert ids(client.get(f"/missions?since={first_day}&until={last_day}")) == newest_first
    # a mission's own created_at as the bound: `since` takes it in, `until` leaves it out
    assert ids(client.get("/missions", params={"since": answers[-1]["created_at"]})) == [created_ids[-1]]
    assert ids(client.get("/missions", params={"until": answers[0]["created_at"]})) == []


# ----- the cursor and the filter's bounds, pure
def test_a_cursor_holds_the_key_as_stored_and_nothing_else_passes():
    key = PageKey("2026-03-01T12:00:00.000+00:00", 42)
    assert decode_cursor(encode_cursor(key)) == key
    assert "=" not in encode_cursor(key) and "/" not in encode_cursor(key)
    for bad in ("", "!!", cursor_of(b"{}"), cursor_of(b'["2026-03-01T12:00:00+00:00", 0]'), cursor_of(b"\xff")):
        with pytest.raises(CursorError):
            decode_cursor(bad)


def test_the_bounds_are_stored_times_to_the_millisecond():
    plus_two = timezone(timedelta(hours=2))
    where = MissionFilter.of(
        [MissionStatus.FAILED, MissionStatus.FAILED], 3, datetime(2026, 3, 1, 14, 0, 0, 1, plus_two), date(2026, 3, 1)
    )
    assert where.statuses == (MissionStatus.FAILED,) and where.vehicle == 3
    assert where.since == "2026-03-01T12:00:00.001+00:00"  # the first stored millisecond at or after it
    assert where.until == "2026-03-02T00:00:00.000+00:00"  # a date: through its end
    assert MissionFilter.of(until=date.max).until is None  # no day after the last one: no bound
    assert MissionFilter.of(since=datetime(1, 1, 1, tzinfo=plus_two)).since == "0001-01-01T00:00:00.000+00:00"
    assert MissionFilter.of(since=date(2026, 3, 1), until=date(2026, 2, 28)).empty_window
