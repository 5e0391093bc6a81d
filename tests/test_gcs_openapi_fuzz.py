"""Property-based requests generated from the service's own OpenAPI document (schemathesis): never a 5xx, and
every answer is one the document declares (status code, media type, headers, body schema).

The app runs with its lifespan (storage, link manager) inside one TestClient; each generated case goes through
it. No vehicle listens at the link's port and missions wait 0.05 s for one, so a mission created with
start=true ends `failed` ("no vehicle") at once and nothing flies. Bounded and reproducible: derandomized
(the same examples every run), a fixed number per operation, and short stateful scenarios.

The stateful run follows the links POST /missions declares (get_mission, get_telemetry, the files, the report,
start, abort, each with the new mission's id), so the operations on a mission are reached with ids that exist,
not only with the random ids the stateless run tries (which mostly answer 404). Its POST /missions sends a
mission the service accepts (a generated one almost never is: buoy spacing, range, airframe limits; the
stateless run fuzzes that operation) and not flying yet: its creation always succeeds, so the scenarios
do not depend on the timing of other missions (a mission flown by its start link fails "no vehicle" at once).
"""

import socket

import pytest
import schemathesis
from fastapi.testclient import TestClient
from hypothesis import HealthCheck, settings
from schemathesis.checks import not_a_server_error
from schemathesis.core.transport import Response
from schemathesis.specs.openapi.checks import (
    content_type_conformance,
    response_headers_conformance,
    response_schema_conformance,
    status_code_conformance,
)

from gcs.app import create_app
from gcs.settings import Settings
from uavcore.geodesy import DEFAULT_HOME

pytestmark = [pytest.mark.slow, pytest.mark.filterwarnings("ignore::DeprecationWarning")]

CHECKS = [
    not_a_server_error,
    status_code_conformance,
    content_type_conformance,
    response_headers_conformance,
    response_schema_conformance,
]
BASE_URL = "http://testserver"


def _free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


APP_FOR_SCHEMA = create_app(Settings(db_path=":memory:"))
schema = schemathesis.openapi.from_dict(APP_FOR_SCHEMA.openapi())


@pytest.fixture(scope="module")
def client(tmp_path_factory):
    settings_ = Settings(
        db_path=tmp_path_factory.mktemp("fuzz") / "gcs.sqlite",
        vehicle_url=f"udpout:127.0.0.1:{_free_udp_port()}",
        vehicle_wait_s=0.05,
    )
    with TestClient(create_app(settings_), raise_server_exceptions=False) as c:
        yield c


def acceptable_mission() -> dict:
    lat, lon, _ = DEFAULT_HOME
    buoys = [{"id": f"B{i}", "lat": lat + 0.001 * i, "lon": lon + 0.0007 * (i % 2)} for i in range(1, 4)]
    return {"buoys": buoys, "start": False}


def send(client: TestClient, case) -> Response:
    kwargs = case.as_transport_kwargs(base_url=BASE_URL)
    kwargs.pop("follow_redirects", None)
    kwargs.pop("allow_redirects", None)
    return Response.from_any(client.request(**kwargs, follow_redirects=False))


@schema.parametrize()
@settings(max_examples=25, deadline=None, derandomize=True, suppress_health_check=list(HealthCheck))
def test_every_answer_is_declared(case, client):
    case.validate_response(send(client, case), checks=CHECKS)


def test_the_schema_declares_links_from_a_created_mission():
    links = APP_FOR_SCHEMA.openapi()["paths"]["/missions"]["post"]["responses"]["201"]["links"]
    assert {"get_mission", "get_telemetry", "get_report", "start_mission", "abort_mission"} <= set(links)
    operation_ids = {op["operationId"] for path in APP_FOR_SCHEMA.openapi()["paths"].values() for op in path.values()}
    assert {link["operationId"] for link in links.values()} <= operation_ids


def test_stateful_scenarios_follow_the_links(client):
    class Scenarios(schema.as_state_machine()):
        def call(self, case, **kwargs):
            if case.operation.label == "POST /missions":
                return Response.from_any(client.post("/missions", json=acceptable_mission()))
            return send(client, case)

        def validate_response(self, response, case, additional_checks=None, **kwargs):
            case.validate_response(response, checks=CHECKS)

    Scenarios.run(
        settings=settings(
            max_examples=40,
            stateful_step_count=6,
            deadline=None,
            derandomize=True,
            suppress_health_check=list(HealthCheck),
        )
    )
