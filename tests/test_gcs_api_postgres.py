"""The service on a PostgreSQL database: the REST API stores and reads missions there, and a database that
cannot be reached stops `serve` with a message, not a traceback."""

from __future__ import annotations

import subprocess
import sys

import psycopg
import pytest
from fastapi.testclient import TestClient
from test_gcs_api import BUOYS

from bench.processes import free_udp_port
from gcs.api.app import create_app
from gcs.settings import Settings

pytestmark = pytest.mark.integration  # a PostgreSQL server, and `python -m gcs serve`


def test_missions_are_stored_in_and_read_from_postgresql(postgres_url, tmp_path):
    settings = Settings(db=postgres_url, data_dir=tmp_path, vehicle_url=f"udpout:127.0.0.1:{free_udp_port()}")
    with TestClient(create_app(settings)) as client:
        created = client.post("/missions", json={"buoys": BUOYS, "start": False})
        assert created.status_code == 201, created.text
        mission_id = created.json()["id"]
        mission = client.get(f"/missions/{mission_id}")
        assert mission.status_code == 200 and mission.json()["status"] == "planned"
        assert [m["id"] for m in client.get("/missions").json()] == [mission_id]
    assert not (tmp_path / "gcs.sqlite").exists()  # nothing went to the SQLite default
    with psycopg.connect(postgres_url) as db:
        assert db.execute("SELECT id, status FROM missions").fetchall() == [(mission_id, "planned")]


def test_serve_with_an_unreachable_database_exits_with_a_message():
    result = subprocess.run(
        [sys.executable, "-m", "gcs", "serve", "--db", "postgresql://nobody@127.0.0.1:1/x"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 2
    assert "buoy-gcs: --db: cannot connect to postgresql://nobody@127.0.0.1:1/x" in result.stderr
    assert "Traceback" not in result.stderr
