"""Property-based requests generated from the service's own OpenAPI schema (schemathesis): never a 5xx.

The app runs with its lifespan (storage, link manager) inside a TestClient; each generated case is sent
through it and checked with schemathesis's not_a_server_error. Bounded: 40 examples per operation.
"""

import socket

import pytest
import schemathesis
from fastapi.testclient import TestClient
from hypothesis import HealthCheck, settings
from schemathesis.checks import not_a_server_error

from gcs.app import create_app
from gcs.settings import Settings

pytestmark = [pytest.mark.slow, pytest.mark.filterwarnings("ignore::DeprecationWarning")]


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


@schema.parametrize()
@settings(max_examples=40, deadline=None, suppress_health_check=list(HealthCheck))
def test_no_server_errors(case, client):
    kwargs = case.as_transport_kwargs(base_url="http://testserver")
    kwargs.pop("follow_redirects", None)
    kwargs.pop("allow_redirects", None)
    response = client.request(**kwargs)
    case.validate_response(response, checks=[not_a_server_error])
