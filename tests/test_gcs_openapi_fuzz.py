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
stateless run fuzzes that operation) and not flying yet. Each scenario has a service and database of its own
and waits for a started mission to end ("no vehicle"), so a replayed scenario gets the same answers however
loaded the machine.
"""

import time
from collections.abc import Iterator

import httpx
import pytest
import schemathesis
from fastapi.testclient import TestClient
from hypothesis import HealthCheck, Phase, reject, settings
from schemathesis.checks import not_a_server_error
from schemathesis.core.transport import Response
from schemathesis.specs.openapi.checks import (
    content_type_conformance,
    response_headers_conformance,
    response_schema_conformance,
    status_code_conformance,
)
from service_process import silent_udp_port

from gcs.api.app import create_app
from gcs.domain.status import TERMINAL
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


APP_FOR_SCHEMA = create_app(Settings(db_path=":memory:"))
schema = schemathesis.openapi.from_dict(APP_FOR_SCHEMA.openapi())


@pytest.fixture(scope="module")
def silent_port() -> Iterator[int]:
    """The services' "no vehicle" (a vehicle that answered would be flown, and answer differently from one step to
    the next)."""
    with silent_udp_port() as port:
        yield port


def fuzz_settings(tmp_path_factory, port: int) -> Settings:
    """A service with a database of its own and no vehicle at its link's port (missions wait 0.05 s for one)."""
    return Settings(
        db_path=tmp_path_factory.mktemp("fuzz") / "gcs.sqlite",
        vehicle_url=f"udpout:127.0.0.1:{port}",
        vehicle_wait_s=0.05,
    )


@pytest.fixture(scope="module")
def client(tmp_path_factory, silent_port):
    with TestClient(create_app(fuzz_settings(tmp_path_factory, silent_port)), raise_server_exceptions=False) as c:
        yield c


def acceptable_mission() -> dict:
    lat, lon, _ = DEFAULT_HOME
    buoys = [{"id": f"B{i}", "lat": lat + 0.001 * i, "lon": lon + 0.0007 * (i % 2)} for i in range(1, 4)]
    return {"buoys": buoys, "start": False}


def wait_until_ended(client: TestClient, mission_id: int, backstop_s: float = 60.0) -> None:
    deadline = time.monotonic() + backstop_s
    while client.get(f"/missions/{mission_id}").json()["status"] not in TERMINAL:
        assert time.monotonic() < deadline, f"mission {mission_id} never ended"
        time.sleep(0.01)


def send(client: TestClient, case) -> Response:
    kwargs = case.as_transport_kwargs(base_url=BASE_URL)
    kwargs.pop("follow_redirects", None)
    kwargs.pop("allow_redirects", None)
    return Response.from_any(client.request(**kwargs, follow_redirects=False))


@schema.parametrize()
@settings(max_examples=25, deadline=None, derandomize=True, suppress_health_check=list(HealthCheck))
def test_every_answer_is_declared(case, client):
    try:
        response = send(client, case)
    except httpx.InvalidURL:  # a query past the client's 64 KiB URL (an area of 8000 non-ASCII characters, each
        reject()  # 9 bytes encoded): no HTTP server takes such a request line, so it never reaches a route
    case.validate_response(response, checks=CHECKS)


def test_the_schema_declares_links_from_a_created_mission():
    links = APP_FOR_SCHEMA.openapi()["paths"]["/missions"]["post"]["responses"]["201"]["links"]
    assert {"get_mission", "get_telemetry", "get_report", "start_mission", "abort_mission"} <= set(links)
    operation_ids = {op["operationId"] for path in APP_FOR_SCHEMA.openapi()["paths"].values() for op in path.values()}
    assert {link["operationId"] for link in links.values()} <= operation_ids


def test_stateful_scenarios_follow_the_links(tmp_path_factory, silent_port):
    class Scenarios(schema.as_state_machine()):
        # each scenario talks to a service of its own (a fresh database): Hypothesis replays a scenario to shrink
        # it and needs the same answers to draw the same steps, which missions left by earlier scenarios (their
        # ids, their states) would change
        def setup(self):
            service_settings = fuzz_settings(tmp_path_factory, silent_port)
            self.service = TestClient(create_app(service_settings), raise_server_exceptions=False)
            self.service.__enter__()

        def teardown(self):
            self.service.__exit__(None, None, None)

        def call(self, case, **kwargs):
            if case.operation.label == "POST /missions":
                return Response.from_any(self.service.post("/missions", json=acceptable_mission()))
            response = send(self.service, case)
            if case.operation.label == "POST /missions/{mission_id}/start" and response.status_code == 200:
                # the started mission fails "no vehicle" in the background: wait for it, so the next step finds
                # the same state however loaded the machine
                wait_until_ended(self.service, case.path_parameters["mission_id"])
            return response

        def validate_response(self, response, case, additional_checks=None, **kwargs):
            case.validate_response(response, checks=CHECKS)

    Scenarios.run(
        settings=settings(
            max_examples=40,
            stateful_step_count=6,
            deadline=None,
            derandomize=True,
            suppress_health_check=list(HealthCheck),
            # a failing scenario is reported as found: shrinking one replays fresh services step by step, which on
            # a loaded machine outlasts the test's timeout and then hides the failure behind the timeout's error
            phases=(Phase.explicit, Phase.reuse, Phase.generate),
        )
    )
