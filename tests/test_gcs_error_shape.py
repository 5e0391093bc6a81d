"""Every error answer has one shape, FastAPI's 422's: {"detail": [{type, loc, msg}]} (gcs.api.errors), and the
OpenAPI document says so for every 4xx and 5xx it declares."""

from __future__ import annotations

import pytest
from fastapi.testclient import TestClient
from test_gcs_api import BUOYS, make_client

from gcs.api.app import create_app
from gcs.settings import Settings

TOKEN = {"Authorization": "Bearer s3cret"}


def problems(answer) -> list[tuple[str, list, str]]:
    """(type, loc, msg) of each problem; fails unless the body is exactly the one shape."""
    body = answer.json()
    assert list(body) == ["detail"] and isinstance(body["detail"], list) and body["detail"], body
    for problem in body["detail"]:
        assert set(problem) == {"type", "loc", "msg"}, problem
        assert isinstance(problem["msg"], str) and isinstance(problem["loc"], list), problem
    return [(p["type"], p["loc"], p["msg"]) for p in body["detail"]]


@pytest.fixture
def client(tmp_path):
    with make_client(tmp_path, token="s3cret", max_body_bytes=4096) as c:
        yield c


def test_each_kind_of_refusal_answers_in_the_one_shape_naming_what_it_concerns(client):
    cases = [
        (client.get("/missions/999"), 404, "not_found", ["path", "mission_id"], "no mission 999"),
        (client.get("/buoys/NOPE"), 404, "not_found", ["path", "buoy_id"], "no buoy 'NOPE' in the register"),
        (client.get("/vehicles/9"), 404, "not_found", ["path", "sysid"], "no vehicle with system id 9"),
        (client.get("/no/such/path"), 404, "not_found", [], "Not Found"),
        (client.delete("/plans"), 405, "method_not_allowed", [], "Method Not Allowed"),
        (client.post("/plans", json={"buoys": BUOYS}), 401, "unauthorized", ["header", "Authorization"], "missing"),
        (client.get("/missions", params={"limit": 0}), 422, "greater_than_equal", ["query", "limit"], "greater"),
        (client.post("/plans", json={"buoys": [{"lat": 95, "lon": 0}]}, headers=TOKEN), 422, None,
         ["body", "buoys", 0, "lat"], ""),
        (client.post("/plans", content=b"\xff", headers=TOKEN | {"Content-Type": "application/json"}), 422,
         "json_invalid", ["body"], "UTF-8"),
        (client.post("/plans", content=b"x" * 5000, headers=TOKEN | {"Content-Type": "application/json"}), 413,
         "too_large", ["body"], "larger than 4096 bytes"),
    ]  # fmt: skip
    for answer, status, kind, loc, words in cases:
        assert answer.status_code == status, (answer.request.url, answer.text)
        (found,) = [p for p in problems(answer) if p[1] == loc] or [None]
        assert found is not None, (answer.request.url, answer.text)
        assert kind is None or found[0] == kind, found
        assert words in found[2], found


def test_a_conflict_and_the_report_files_name_their_field(client):
    mission = client.post("/missions", json={"buoys": BUOYS, "start": False}, headers=TOKEN).json()
    client.post(f"/missions/{mission['id']}/abort", headers=TOKEN)
    again = client.post(f"/missions/{mission['id']}/start", headers=TOKEN)
    assert again.status_code == 409 and problems(again)[0][:2] == ("conflict", [])
    missing = client.get(f"/missions/{mission['id']}/report/nothing.txt")
    assert missing.status_code == 404 and problems(missing)[0][:2] == ("not_found", ["path", "name"])


def test_a_failure_inside_the_service_is_a_500_in_the_one_shape_without_its_traceback(tmp_path):
    app = create_app(Settings(db_path=tmp_path / "gcs.sqlite", vehicle_url="udpout:127.0.0.1:9"))

    @app.get("/fails")
    def fails() -> None:
        raise RuntimeError("secret internals")

    with TestClient(app, raise_server_exceptions=False) as client:
        answer = client.get("/fails")
    assert answer.status_code == 500
    (problem,) = problems(answer)
    assert problem[:2] == ("internal_error", []) and "secret" not in answer.text and "Traceback" not in answer.text


def test_the_openapi_document_declares_the_one_shape_for_every_error_answer(client):
    document = client.get("/openapi.json").json()
    shapes = set()
    for operations in document["paths"].values():
        for operation in operations.values():
            for status, response in operation["responses"].items():
                if status[0] in "45":
                    schema = response["content"]["application/json"]["schema"]["$ref"]
                    shapes.add(schema.rsplit("/", 1)[1])
    assert shapes == {"ErrorOut", "HTTPValidationError"}
    components = document["components"]["schemas"]
    item = components["ProblemOut"]["properties"]
    assert components["ErrorOut"]["properties"]["detail"]["items"]["$ref"].endswith("/ProblemOut")
    assert set(item) == set(components["ValidationError"]["properties"]) - {"input", "ctx"} == {"type", "loc", "msg"}
