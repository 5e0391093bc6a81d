"""The service with an AIS feed (`python -m gcs serve --ais udp://...`, no vehicle): what a receiver sends shows on
GET /ais/atons, the source's state on GET /ais/sources, over real HTTP; names stay text. The settings and the CLI
refuse a bad source."""

from __future__ import annotations

import json
import socket
import time
import urllib.request

import pytest

from bench.ais_sentences import DFO2_PARTS, SF_BAY_BRIDGE_VIRTUAL, aton_line
from bench.processes import free_port
from gcs.cli import main
from gcs.settings import Settings
from tests.service_process import serving
from uavcore.ais import AtonReport


def get(url: str) -> tuple[str, object]:
    with urllib.request.urlopen(url, timeout=10) as response:
        return response.headers["Content-Type"], json.loads(response.read())


def test_ais_sources_are_settings_from_options_or_the_environment(monkeypatch):
    assert Settings().ais_sources == []
    monkeypatch.setenv("BUOY_GCS_AIS_SOURCES", "udp://:10110, tcp://shore.example:5631")
    assert Settings().ais_sources == ["udp://0.0.0.0:10110", "tcp://shore.example:5631"]


def test_serve_refuses_a_bad_ais_source(capsys):
    assert main(["serve", "--ais", "udp://0.0.0.0", "--db", "/nonexistent/never-opened.sqlite"]) == 2
    assert "ais_sources" in capsys.readouterr().err


@pytest.mark.integration  # starts the service; loopback UDP and HTTP
def test_the_service_shows_the_atons_a_receiver_sends(tmp_path):
    port = free_port(socket.SOCK_DGRAM)
    dragged = AtonReport(992191001, "PORT NO 1 <SCRIPT>", 24, 55.71, 12.61, False, True, False, 30)
    with serving(tmp_path / "gcs.sqlite", tmp_path / "service.log", "--ais", f"udp://127.0.0.1:{port}") as url:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
            for datagram in (DFO2_PARTS[1], SF_BAY_BRIDGE_VIRTUAL, DFO2_PARTS[0], aton_line(dragged), b"noise"):
                sock.sendto(datagram, ("127.0.0.1", port))
        deadline = time.monotonic() + 20
        while True:
            content_type, document = get(f"{url}/ais/atons")
            if len(document["atons"]) == 3 or time.monotonic() > deadline:
                break
            time.sleep(0.1)
        assert content_type == "application/json"  # the names are JSON strings, never a page
        assert [a["mmsi"] for a in document["atons"]] == [316021442, 992191001, 993692028]
        mine = document["atons"][1]
        assert mine["name"] == "PORT NO 1 <SCRIPT>" and mine["aid_type_name"] == "port_hand_mark"
        assert mine["off_position"] and mine["off_position_valid"] and not mine["virtual"] and not mine["stale"]
        assert (mine["lat"], mine["lon"]) == pytest.approx((55.71, 12.61))
        assert mine["source"] == f"udp://127.0.0.1:{port}" and mine["age_s"] < 20
        assert document["atons"][2]["virtual"] and document["conflicts"] == [] and document["stale_after_s"] == 420
        _, (source,) = get(f"{url}/ais/sources")
        assert source["url"] == f"udp://127.0.0.1:{port}" and source["connected"] and not source["silent"]
        assert source["counts"]["decoded"] == 3 and source["counts"]["malformed"] == 1
        _, openapi = get(f"{url}/openapi.json")
        assert {"/ais/atons", "/ais/sources"} <= set(openapi["paths"])
