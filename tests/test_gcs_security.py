"""The service's security: the token on every mutating route and on /ws, the WebSocket's origin check, CORS,
the Content-Security-Policy and its companions on every response, request limits (413/422, never a 5xx), and
a token that never reaches a log. The app runs in a TestClient with its lifespan; the logging test runs the
real `python -m gcs serve` (uvicorn, access log on) and talks to it over HTTP and WebSocket."""

from __future__ import annotations

import base64
import hashlib
import html
import http.client
import json
import re
import time
from datetime import UTC, datetime
from pathlib import Path

import pytest
from fastapi.routing import APIRoute
from fastapi.testclient import TestClient
from service_process import serving
from starlette.websockets import WebSocketDisconnect
from stored_missions import FLIGHT, PLAN
from websockets.exceptions import InvalidStatus
from websockets.sync.client import connect as ws_connect

from bench.processes import free_udp_port
from gcs.api.app import create_app
from gcs.api.security import LIVE_SUBPROTOCOL
from gcs.cli import build_parser, settings_from_args
from gcs.domain.records import MissionProgress, MissionResults
from gcs.domain.schemas import MAX_BUOYS, MAX_FENCE_VERTICES, MAX_FENCE_ZONES, BuoyResult, StatusEvent, VehicleEvent
from gcs.reports.report import report_html
from gcs.settings import Settings
from gcs.storage import MissionRecord
from uavcore.geodesy import DEFAULT_HOME

pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")

TOKEN = "S3CRET-token-0123456789abcdef"
HOSTILE = "<img src=x onerror=window.injected=1><script>window.injected=2</script>"
LAT, LON, _ = DEFAULT_HOME
MUTATING = {"POST", "PUT", "PATCH", "DELETE"}


def buoys(count: int, **extra: object) -> list[dict]:
    """count buoys 30 m apart in a row east of the default home."""
    return [{"lat": LAT + 0.0003, "lon": LON + 0.0004 * (i + 1), **extra} for i in range(count)]


def make_client(tmp_path: Path, **settings: object) -> TestClient:
    defaults = {"db_path": tmp_path / "gcs.sqlite", "vehicle_url": f"udpout:127.0.0.1:{free_udp_port()}"}
    return TestClient(create_app(Settings(**(defaults | settings))), raise_server_exceptions=False)


@pytest.fixture
def client(tmp_path):
    with make_client(tmp_path) as c:
        yield c


@pytest.fixture
def guarded(tmp_path):
    """A service with an API token."""
    with make_client(tmp_path, token=TOKEN) as c:
        yield c


def token_subprotocols(token: str) -> list[str]:
    """What the page offers on /ws (gcs/web/api.js liveProtocols)."""
    encoded = base64.urlsafe_b64encode(token.encode()).decode().rstrip("=")
    return [LIVE_SUBPROTOCOL, f"bearer.{encoded}"]


# ----- the token on every mutating route
def api_routes(routes: list) -> list[APIRoute]:
    """Every APIRoute, also those inside included routers (FastAPI keeps an included router whole, as
    `original_router`; our routers have no prefix)."""
    found = []
    for route in routes:
        if isinstance(route, APIRoute):
            found.append(route)
        elif hasattr(route, "original_router"):
            found += api_routes(route.original_router.routes)
    return found


def mutating_routes(app) -> list[tuple[str, str]]:
    """Every (method, path) of the app that changes something."""
    return [(method, route.path) for route in api_routes(app.routes) for method in sorted(route.methods & MUTATING)]


def test_every_mutating_route_answers_401_without_the_right_token(guarded):
    routes = mutating_routes(guarded.app)
    # the walk finds every mutating operation of the OpenAPI document (and any route left out of it)
    documented = {(m.upper(), p) for p, ops in guarded.app.openapi()["paths"].items() for m in ops}
    assert {(m, p) for m, p in documented if m in MUTATING} <= set(routes)
    assert {("POST", "/plans"), ("POST", "/missions"), ("POST", "/imports")} <= set(routes)
    for method, template in routes:
        path = re.sub(r"\{[^}]+\}", "1", template)
        for headers in ({}, {"Authorization": "Bearer wrong"}, {"X-API-Token": "wrong"}, {"Authorization": TOKEN}):
            answer = guarded.request(method, path, headers=headers, json={})
            assert answer.status_code == 401, (method, path, headers, answer.text)
            assert answer.headers["www-authenticate"] == "Bearer"
        # the right token gets past the check (to the route's own answer: 404 or 422 for these bodies; a battery
        # swap with no vehicle connected, 409)
        answer = guarded.request(method, path, headers={"Authorization": f"Bearer {TOKEN}"}, json={})
        own = (409,) if path == "/vehicle/battery-swap" else (404, 422)
        assert answer.status_code in own, (method, path, answer.text)


def test_reads_need_no_token(guarded):
    assert guarded.get("/missions").status_code == 200
    assert guarded.get("/vehicle").status_code == 200


# ----- /ws: token and origin
def test_the_live_stream_needs_the_token_when_the_service_has_one(guarded):
    for refused in ({}, {"headers": {"Authorization": "Bearer wrong"}}, {"subprotocols": token_subprotocols("no")}):
        with pytest.raises(WebSocketDisconnect) as closed, guarded.websocket_connect("/ws", **refused):
            pass
        assert closed.value.code == 1008, refused
    with guarded.websocket_connect("/ws", headers={"Authorization": f"Bearer {TOKEN}"}) as ws:
        assert ws.receive_json()["type"] == "state"
    with guarded.websocket_connect("/ws", subprotocols=token_subprotocols(TOKEN)) as ws:
        assert ws.accepted_subprotocol == LIVE_SUBPROTOCOL  # the token is never echoed back
        assert ws.receive_json()["type"] == "state"


def test_a_page_of_another_origin_cannot_open_the_live_stream(tmp_path):
    with make_client(tmp_path, cors_origins=["https://ops.example"]) as c:
        with (
            pytest.raises(WebSocketDisconnect) as closed,
            c.websocket_connect("/ws", headers={"Origin": "https://evil.example"}),
        ):
            pass
        assert closed.value.code == 1008
        for allowed in ("http://testserver", "https://ops.example"):  # the service's own page, a CORS origin
            with c.websocket_connect("/ws", headers={"Origin": allowed}) as ws:
                assert ws.receive_json()["type"] == "state"
        with c.websocket_connect("/ws") as ws:  # no Origin: no browser, nothing to hijack
            assert ws.receive_json()["type"] == "state"


# ----- CORS
def test_cors_is_off_by_default(client):
    answer = client.get("/missions", headers={"Origin": "https://ops.example"})
    assert answer.status_code == 200 and "access-control-allow-origin" not in answer.headers
    preflight = client.options(
        "/missions", headers={"Origin": "https://ops.example", "Access-Control-Request-Method": "POST"}
    )
    assert "access-control-allow-origin" not in preflight.headers


def test_cors_origins_allow_exactly_those_origins(tmp_path):
    with make_client(tmp_path, cors_origins=["https://ops.example"]) as c:
        ask = {"Access-Control-Request-Method": "POST", "Access-Control-Request-Headers": "authorization"}
        preflight = c.options("/missions", headers={"Origin": "https://ops.example", **ask})
        assert preflight.status_code == 200
        assert preflight.headers["access-control-allow-origin"] == "https://ops.example"
        assert "POST" in preflight.headers["access-control-allow-methods"]
        assert c.get("/missions", headers={"Origin": "https://ops.example"}).headers["access-control-allow-origin"] == (
            "https://ops.example"
        )
        other = c.options("/missions", headers={"Origin": "https://evil.example", **ask})
        assert "access-control-allow-origin" not in other.headers
        assert (
            "access-control-allow-origin" not in c.get("/missions", headers={"Origin": "https://evil.example"}).headers
        )


def test_cors_origins_from_the_command_line_and_the_environment(monkeypatch):
    parser = build_parser()
    monkeypatch.delenv("BUOY_GCS_CORS_ORIGINS", raising=False)
    assert settings_from_args(parser.parse_args(["serve"])).cors_origins == []
    args = parser.parse_args(["serve", "--cors-origin", "https://a.example", "--cors-origin", "http://b:8080"])
    assert settings_from_args(args).cors_origins == ["https://a.example", "http://b:8080"]
    monkeypatch.setenv("BUOY_GCS_CORS_ORIGINS", "https://a.example, https://c.example")
    assert settings_from_args(parser.parse_args(["serve"])).cors_origins == ["https://a.example", "https://c.example"]


# ----- Content-Security-Policy and its companions
def policy(answer) -> dict[str, str]:
    directives = (part.strip().split(" ", 1) for part in answer.headers["content-security-policy"].split(";"))
    return {name: value for name, value in directives}


def assert_locked_down(answer) -> None:
    csp = policy(answer)
    assert csp["script-src"] == "'self'", csp  # no inline script, no other origin
    assert csp["object-src"] == csp["base-uri"] == csp["frame-ancestors"] == "'none'"
    assert answer.headers["x-content-type-options"] == "nosniff"
    assert answer.headers["referrer-policy"] == "no-referrer"


def test_every_kind_of_response_carries_the_policy(client):
    created = client.post("/missions", json={"buoys": buoys(2), "start": False})
    assert created.status_code == 201
    mission = created.json()["id"]
    for path in ("/", "/web/app.js", "/web/style.css", "/static/leaflet/leaflet.js", "/missions", "/vehicle"):
        answer = client.get(path)
        assert answer.status_code == 200, path
        assert_locked_down(answer)
    report = client.get(f"/missions/{mission}/report/index.html")
    assert report.status_code == 200 and report.headers["content-type"].startswith("text/html")
    assert_locked_down(report)
    # the report's one inline <style> is allowed by its hash, and nothing else inline is
    style = re.search(r"<style>(.*?)</style>", report.text, re.S).group(1)
    digest = base64.b64encode(hashlib.sha256(style.encode()).digest()).decode()
    assert f"'sha256-{digest}'" in policy(report)["style-src"]
    assert "<script" not in report.text.lower() and not re.search(r"\son\w+\s*=", report.text)
    for error in (client.get("/missions/999"), client.get("/nothing-here"), client.post("/plans", json={})):
        assert error.status_code in (404, 422)
        assert_locked_down(error)


def test_the_map_tiles_are_the_only_other_origin_the_page_may_load(client):
    """img-src names exactly the tile server map.js uses (when it can reach it), nothing else."""
    tile_url = re.search(r'OSM_URL = "(https://[^/"]+)/', (Settings().web_dir / "map.js").read_text()).group(1)
    csp = policy(client.get("/"))
    assert csp["img-src"].split() == ["'self'", "data:", tile_url]
    others = [value for name, value in csp.items() if name != "img-src" and "https:" in value]
    assert others == []


def test_the_report_page_escapes_mission_text():
    record = MissionRecord(
        id=7,
        created_at=HOSTILE,
        updated_at="today",
        status="failed",
        reason=HOSTILE,
        flight=FLIGHT,
        plan=PLAN,
        progress=MissionProgress(
            vehicle_events=[VehicleEvent(t_s=12.5, text=HOSTILE, at=datetime(2026, 11, 27, 23, 50, tzinfo=UTC),
                                         severity="critical")],
            reached_wall_at={0: datetime(2026, 11, 27, 23, 51, 2, tzinfo=UTC).timestamp()},
        ),
        results=MissionResults(
            buoys=[BuoyResult(index=0, id=HOSTILE, reached=True, closest_m=1.0, arrival_s=40.0)],
        ),
        events=[StatusEvent(at="2026-11-27T23:49:00Z", status="failed", reason=HOSTILE)],
    )  # fmt: skip
    page = report_html(record, [("status", f"failed ({HOSTILE})"), (HOSTILE, "x")])
    assert HOSTILE not in page and "<img src=x" not in page and "<script" not in page
    # the creation time, the status row, the row name, the buoy, and in the event log the status change's reason
    # and the vehicle's text (after it in time)
    assert page.count(html.escape(HOSTILE)) == 6
    events = page[page.index('data-testid="events"') :]
    assert events.index("2026-11-27 23:49:00 UTC") < events.index("2026-11-27 23:50:00 UTC")
    assert "critical" in events and "vehicle time 12.5 s" in events
    assert "<td>2026-11-27 23:51:02 UTC</td>" in page  # the buoy's arrival, by the wall clock


# ----- request limits: 413 and 422, never a 5xx
def test_a_body_over_the_limit_is_413_whether_announced_or_streamed(tmp_path):
    with make_client(tmp_path, max_body_bytes=4096) as c:
        big = json.dumps({"buoys": buoys(200)}).encode()
        assert len(big) > 4096
        announced = c.post("/plans", content=big, headers={"Content-Type": "application/json"})
        assert announced.status_code == 413
        assert announced.json() == {
            "detail": [{"type": "too_large", "loc": ["body"], "msg": "the request body is larger than 4096 bytes"}]
        }
        assert_locked_down(announced)
        streamed = c.post(
            "/plans",
            content=(big[i : i + 1000] for i in range(0, len(big), 1000)),
            headers={"Content-Type": "text/csv"},
        )
        assert streamed.status_code == 413
        upload = c.post("/imports?filename=b.csv", content=b"lat,lon\n" + b"38.9,121.6\n" * 500)
        assert upload.status_code == 413
        assert c.post("/plans", json={"buoys": buoys(3)}).status_code == 200  # under the limit: planned


def test_the_default_limit_is_one_mebibyte(client):
    assert Settings().max_body_bytes == 1 << 20
    padding = b" " * (1 << 20)  # valid JSON with whitespace: only its size is wrong
    answer = client.post("/plans", content=b'{"buoys": []}' + padding, headers={"Content-Type": "application/json"})
    assert answer.status_code == 413


@pytest.mark.integration
def test_a_streamed_body_over_the_limit_is_refused_by_the_real_server(served):
    """Chunked transfer encoding, no Content-Length: uvicorn hands the body over in pieces as it arrives."""
    url, _ = served
    connection = http.client.HTTPConnection(url.removeprefix("http://"), timeout=30)
    chunks = (b"x" * 65536 for _ in range(20))  # 1.25 MiB
    connection.request("POST", "/plans", body=chunks, headers={"Content-Type": "application/json"}, encode_chunked=True)
    answer = connection.getresponse()
    assert answer.status == 413 and b"larger than 1048576 bytes" in answer.read()
    connection.close()


def loc_of(answer) -> list[list]:
    assert answer.status_code == 422, answer.text
    return [error["loc"] for error in answer.json()["detail"]]


def test_strings_and_lists_have_limits(client):
    assert ["body", "buoys", 0, "id"] in loc_of(client.post("/plans", json={"buoys": buoys(1, id="b" * 65)}))
    assert ["body", "buoys"] in loc_of(client.post("/plans", json={"buoys": buoys(MAX_BUOYS + 1)}))
    circle = {"kind": "circle", "inclusion": True, "center": {"lat": LAT, "lon": LON}, "radius_m": 500.0}
    fence = [circle] * (MAX_FENCE_ZONES + 1)
    assert ["body", "geofence"] in loc_of(client.post("/plans", json={"buoys": buoys(2), "geofence": fence}))
    vertices = [{"lat": LAT + 0.01 * (i % 2), "lon": LON + 0.0001 * i} for i in range(MAX_FENCE_VERTICES + 1)]
    polygon = {"kind": "polygon", "inclusion": True, "vertices": vertices}
    assert ["body", "geofence", 0, "vertices"] in loc_of(
        client.post("/plans", json={"buoys": buoys(2), "geofence": [polygon]})
    )
    assert ["query", "filename"] in loc_of(client.post(f"/imports?filename={'f' * 256}.csv", content=b"lat,lon\n"))
    rows = "".join(f"{LAT + 0.0003},{LON + 0.0004 * (i + 1)}\n" for i in range(MAX_BUOYS + 1))
    assert ["body"] in loc_of(client.post("/imports?filename=b.csv", content=rows.encode()))


def test_every_string_a_request_carries_is_bounded(client):
    """Every string field of a request body in the OpenAPI document has a maxLength or a fixed set of values,
    so a new field cannot forget one."""
    document = client.get("/openapi.json").json()
    schemas = document["components"]["schemas"]
    seen, unbounded = set(), []

    def walk(schema: dict, where: str) -> None:
        if "$ref" in schema:
            name = schema["$ref"].rsplit("/", 1)[1]
            if name not in seen:
                seen.add(name)
                walk(schemas[name], name)
            return
        if schema.get("type") == "string" and not {"maxLength", "enum", "const"} & set(schema):
            unbounded.append(where)
        for key in ("anyOf", "oneOf", "allOf"):
            for i, option in enumerate(schema.get(key, [])):
                walk(option, f"{where}|{i}")
        for name, field in schema.get("properties", {}).items():
            walk(field, f"{where}.{name}")
        if isinstance(schema.get("items"), dict):
            walk(schema["items"], f"{where}[]")

    for path in document["paths"].values():
        for operation in path.values():
            for content in operation.get("requestBody", {}).get("content", {}).values():
                if content.get("schema", {}).get("type") != "string":  # a file sent as the body: 413 bounds it
                    walk(content.get("schema", {}), "body")
    assert {"PlanRequest", "MissionRequest", "BuoyIn"} <= seen
    assert unbounded == []


# ----- the real server: the token never reaches its output
@pytest.fixture
def served(tmp_path):
    """`python -m gcs serve --token ...` on free ports, output to a file; yields (url, log path)."""
    log = tmp_path / "serve.log"
    with serving(tmp_path / "gcs.sqlite", log, "--token", TOKEN) as url:
        yield url, log


@pytest.mark.integration
def test_the_token_never_reaches_the_log(served):
    url, log = served
    host = url.removeprefix("http://")
    for headers in (
        {"Authorization": f"Bearer {TOKEN}"},
        {"X-API-Token": TOKEN},
        {"Authorization": f"Bearer {TOKEN}x"},
        {"Authorization": TOKEN},
    ):
        connection = http.client.HTTPConnection(host, timeout=30)
        connection.request("POST", "/plans", body=b"{}", headers={"Content-Type": "application/json", **headers})
        assert connection.getresponse().status in (401, 422)
        connection.close()
    with ws_connect(f"ws://{host}/ws", subprotocols=token_subprotocols(TOKEN), open_timeout=30) as ws:
        assert json.loads(ws.recv(timeout=30))["type"] == "state"
    with pytest.raises(InvalidStatus), ws_connect(f"ws://{host}/ws", subprotocols=token_subprotocols("guess")):
        pass
    # the access log is written as each request ends: wait until every line is there (a backstop deadline)
    deadline, output = time.monotonic() + 60, ""
    while time.monotonic() < deadline:
        output = log.read_text()
        if output.count('"POST /plans HTTP/1.1"') >= 4 and output.count("/ws") >= 2:
            break
        time.sleep(0.1)
    assert '"POST /plans HTTP/1.1" 401' in output and '"POST /plans HTTP/1.1" 422' in output, output
    assert "/ws" in output  # the WebSocket handshakes were logged too
    encoded = token_subprotocols(TOKEN)[1].removeprefix("bearer.")
    assert TOKEN not in output and encoded not in output
