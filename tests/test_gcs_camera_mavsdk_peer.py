"""The inspection's capture and download path against a camera nobody here wrote: MAVSDK 4's CameraServer and
FtpServer as component 100 (tests/mavsdk_camera.py), in a system whose autopilot is MAVSDK's server-plugin vehicle
(tests/mavsdk_payload_vehicle.py: MissionRawServer & co., plus what PX4's navigator does with payload items).

The network: a hub (tests/mavlink_hub.py, mavlink-router's broadcast) joins the autopilot (udpout), the camera
(udpout) and the service's one link (its udpin port); the service hears both components of system 1 there.
The service flies an inspection mission over four charted buoys of a rendered world. At each buoy's capture items
the autopilot sends IMAGE_START_CAPTURE / IMAGE_STOP_CAPTURE to component 0 (as PX4 re-emits them) and aims the
gimbal at the ROI (GIMBAL_DEVICE_SET_ATTITUDE); MAVSDK's camera then takes the burst on its own timer, the payload
renders each frame from where the vehicle is and where the gimbal looks, and answers it with the geotag, the
camera's attitude and an mftp:// URL of a JPEG in the FtpServer's root. The service downloads the frames over
MAVLink FTP from the FtpServer, finds the buoys in them and judges each:
- B1, lit as charted: ok; B2, its light dark in every frame: defect light_out;
- B3, the camera names files its FtpServer does not have (FileNotFound), and B4, files that are text: both
  not_inspected with the reason naming the cause; the mission still completes and nothing in the service raises.
The camera's clock is its own (CAMERA_IMAGE_CAPTURED.time_boot_ms): where a time namespace can be had (unshare), it
is set 8 s behind the autopilot's, as a camera that booted after the flight controller; the frames must still go
to the buoys they show.

Wall clock: the double flies in real time at 30 m/s, so the run is its flight (about 50 s: bursts of 5 s and 2 s
at 10 Hz, a few short legs) plus start-up, about 70 s in all. Every wait polls a condition against a generous
deadline.
"""

from __future__ import annotations

import json
import logging
import math
import shutil
import subprocess
import time
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import pytest
from fastapi.testclient import TestClient
from mavlink_hub import MavlinkHub
from peer_process import PeerProcess, peers_stopped_cleanly
from sitl_process import REPO

from bench.processes import free_udp_port
from gcs.api.app import create_app
from gcs.settings import Settings
from uavcore.buoy_world import World, WorldBuoy
from uavcore.geodesy import DEFAULT_HOME, LocalFrame
from uavcore.light_character import burst_for, parse
from uavcore.mavlink import mavlink

pytestmark = [pytest.mark.integration, pytest.mark.slow, pytest.mark.timeout(600)]

VEHICLE_SCRIPT = REPO / "tests" / "mavsdk_payload_vehicle.py"
CAMERA_SCRIPT = REPO / "tests" / "mavsdk_camera.py"
HOME = LocalFrame(*DEFAULT_HOME)
CONNECT_S = 60.0
FLIGHT_S = 300.0
START, STOP = mavlink.MAV_CMD_IMAGE_START_CAPTURE, mavlink.MAV_CMD_IMAGE_STOP_CAPTURE


@dataclass(frozen=True)
class Charted:
    """A buoy as the chart has it (and the mission asks for it), where it is (metres north, east of home), and
    what it really shows."""

    id: str
    kind: str
    light: str | None
    north_east: tuple[float, float]
    shows: str = "charted"  # or "dark"

    def world_buoy(self) -> WorldBuoy:
        lat, lon, _ = HOME.from_ned(*self.north_east)
        light = None if self.light is None else parse(self.light)
        return WorldBuoy(self.id, self.kind, (float(lat), float(lon)), light, 5.0,
                         None if self.shows == "dark" else light)  # fmt: skip

    def request(self) -> dict:
        lat, lon, _ = HOME.from_ned(*self.north_east)
        return {"id": self.id, "lat": float(lat), "lon": float(lon), "kind": self.kind, "light": self.light}

    def burst_count(self) -> int:
        duration_s, rate_hz = burst_for(None if self.light is None else parse(self.light))
        return math.ceil(duration_s * rate_hz)


BUOYS = (
    Charted("B1", "port", "Fl R 2s", (90.0, 0.0)),  # as charted
    Charted("B2", "starboard", "Fl G 2s", (90.0, 90.0), shows="dark"),  # its light is out
    Charted("B3", "special", None, (0.0, 110.0)),  # the camera names files it does not have
    Charted("B4", "special", None, (-50.0, 50.0)),  # the camera's files are text
)
CAMERA_FAULTS = ("--missing", "B3", "--not-image", "B4")
CAMERA_BEHIND_S = 8.0  # the camera's clock against the autopilot's, where it can be set


def clock_shifted(offset_s: float) -> list[str] | None:
    """A command prefix running a program in a new time namespace whose CLOCK_MONOTONIC reads offset_s (whole
    seconds) more than ours (util-linux unshare; as root, or in a user namespace where those are allowed); None
    where neither works. The program is unshare's child: unshare ignores SIGTERM, and kills it if itself killed."""
    shift = ["--time", f"--monotonic={round(offset_s)}", "--fork", "--kill-child=SIGKILL"]
    for prefix in (["unshare", *shift], ["unshare", "--user", "--map-root-user", *shift]):
        if shutil.which("unshare") and subprocess.run([*prefix, "true"], capture_output=True).returncode == 0:
            return prefix
    return None


@pytest.fixture
def start_peer(tmp_path):
    """start_peer(script, *args, prefix=()); each must exit cleanly on SIGTERM, without a traceback."""
    started: list[PeerProcess] = []

    def start(script: Path, *args: str, prefix: Sequence[str] = ()) -> PeerProcess:
        started.append(PeerProcess(tmp_path, script, *args, prefix=prefix))
        return started[-1]

    yield start
    peers_stopped_cleanly(started)


def wait_for(condition, timeout_s: float, what) -> None:
    deadline = time.monotonic() + timeout_s
    while not condition():
        assert time.monotonic() < deadline, what() if callable(what) else what
        time.sleep(0.2)


def captures(records: Path) -> list[dict]:
    """What the camera says it captured, one record per CAMERA_IMAGE_CAPTURED it sent."""
    return [json.loads(line) for line in records.read_text().splitlines()] if records.exists() else []


def test_the_service_inspects_with_mavsdks_camera_and_ftp_servers(tmp_path, start_peer, caplog):
    root = tmp_path / "camera-root"
    root.mkdir()
    world_file, records = tmp_path / "world.geojson", tmp_path / "captures.jsonl"
    world_file.write_text(json.dumps(World(tuple(b.world_buoy() for b in BUOYS), seed=1).to_geojson()))
    service_port = free_udp_port()
    caplog.set_level(logging.INFO, logger="gcs")
    settings = Settings(db_path=tmp_path / "gcs.sqlite", vehicle_url=f"udpin://127.0.0.1:{service_port}",
                        vehicle_wait_s=60.0)  # fmt: skip
    watched = frozenset({mavlink.MAVLINK_MSG_ID_COMMAND_LONG, mavlink.MAVLINK_MSG_ID_COMMAND_ACK,
                         mavlink.MAVLINK_MSG_ID_CAMERA_IMAGE_CAPTURED})  # fmt: skip
    hub = MavlinkHub(watched)
    autopilot_port, camera_port = hub.listen("autopilot"), hub.listen("camera")
    hub.connect("service", service_port)
    started = time.monotonic()
    with TestClient(create_app(settings)) as client, hub:
        vehicle = start_peer(VEHICLE_SCRIPT, "--connect", f"udpout://127.0.0.1:{autopilot_port}",
                             "--items-out", str(tmp_path / "items.json"), "--speed", "30")  # fmt: skip
        # the camera's clock is its own: CAMERA_IMAGE_CAPTURED's time_boot_ms is its host's CLOCK_MONOTONIC (MAVSDK's
        # CameraServer), the autopilot's the time since its TelemetryServer started. Where a time namespace can be
        # had, the camera's reads CAMERA_BEHIND_S less than the autopilot's, as a camera that booted after the
        # flight controller (a companion computer's) would; else its host's uptime, hours ahead.
        shifting = clock_shifted(-1.0) is not None
        least_s = CAMERA_BEHIND_S + 1.0 if shifting else 0.0  # a clock is never negative
        wait_for(lambda: (client.get("/vehicle").json()["t_s"] or -1.0) >= least_s, CONNECT_S,
                 lambda: f"the service never saw the MAVSDK vehicle:\n{vehicle.log()}")  # fmt: skip
        autopilot_s = client.get("/vehicle").json()["t_s"]
        prefix = clock_shifted(autopilot_s - CAMERA_BEHIND_S - time.monotonic()) if shifting else None
        camera = start_peer(CAMERA_SCRIPT, "--connect", f"udpout://127.0.0.1:{camera_port}", "--root", str(root),
                            "--world", str(world_file), "--records", str(records), *CAMERA_FAULTS,
                            prefix=prefix or ())  # fmt: skip
        wait_for(lambda: "ready" in camera.log().splitlines(), CONNECT_S,
                 lambda: f"the camera did not start:\n{camera.log()}")  # fmt: skip

        created = client.post("/missions", json={"buoys": [b.request() for b in BUOYS]})
        assert created.status_code == 201, created.text
        mission_id = created.json()["id"]

        def flown() -> bool:
            return client.get(f"/missions/{mission_id}").json()["status"] in ("completed", "failed", "aborted")

        wait_for(flown, FLIGHT_S, lambda: f"mission not over: {client.get(f'/missions/{mission_id}').json()}")
        mission = client.get(f"/missions/{mission_id}").json()
        assert (mission["status"], mission["reason"]) == ("completed", None), vehicle.log()[-3000:]
        inspections = {i["buoy"]: i for i in client.get(f"/missions/{mission_id}/inspections").json()}
        frames = {buoy: [client.get(url).content for url in inspections[buoy]["frames"]] for buoy in ("B1", "B2")}
    elapsed = time.monotonic() - started
    stamps = [h.message.time_boot_ms / 1000.0 for h in hub.messages("CAMERA_IMAGE_CAPTURED", "camera")]
    clock = f"set {CAMERA_BEHIND_S:g} s behind the autopilot's" if prefix else "its host's uptime"
    print(f"flown and judged in {elapsed:.1f} s; the camera's clock {clock}: it stamped {stamps[0]:.1f}..")
    print(f"..{stamps[-1]:.1f} s; the autopilot's read {autopilot_s:.1f} s as the camera started")

    # the verdicts: from real frames of the rendered world, downloaded from MAVSDK's FtpServer
    summary = {b: (i["verdict"], [f["code"] for f in i["findings"]], i["reason"]) for b, i in inspections.items()}
    assert set(summary) == {"B1", "B2", "B3", "B4"}, summary
    assert summary["B1"] == ("ok", [], None), summary
    assert summary["B2"] == ("defect", ["light_out"], None), summary
    assert inspections["B2"]["light_seen"] == "dark"
    assert summary["B3"][0] == "not_inspected" and "FileNotFound" in summary["B3"][2], summary
    assert summary["B4"][0] == "not_inspected" and "not an image" in summary["B4"][2], summary
    assert inspections["B3"]["frames"] == inspections["B4"]["frames"] == []

    # the camera was commanded as PX4 does it: from the autopilot (1/1) to component 0 of its system, a burst per
    # buoy with the interval and count of the mission's item, then a stop; the camera accepted each
    commands = [h.message for h in hub.messages("COMMAND_LONG", "autopilot") if h.message.command in (START, STOP)]
    sent = [(m.get_srcSystem(), m.get_srcComponent(), m.target_system, m.target_component) for m in commands]
    assert set(sent) == {(1, 1, 1, 0)}, sent
    starts = [(m.param2, m.param3) for m in commands if m.command == START]
    assert sorted(starts) == sorted((pytest.approx(0.1), b.burst_count()) for b in BUOYS), starts
    assert [m.command for m in commands] == [START, STOP] * len(BUOYS)
    acks = [(h.message.command, h.message.result) for h in hub.messages("COMMAND_ACK", "camera")]
    accepted = mavlink.MAV_RESULT_ACCEPTED
    assert Counter(a for a in acks if a[0] in (START, STOP)) == {(START, accepted): 4, (STOP, accepted): 4}, acks

    # every capture the camera reported reached the service; each frame of the lit and the dark buoy was
    # downloaded byte for byte and is stored behind the verdict
    taken = captures(records)
    assert len(hub.messages("CAMERA_IMAGE_CAPTURED", "camera")) == len(taken)
    by_buoy = Counter(c["buoy"] for c in taken)
    for buoy in BUOYS:
        assert 0.8 * buoy.burst_count() <= by_buoy[buoy.id] <= buoy.burst_count(), by_buoy
    for buoy in ("B1", "B2"):
        written = {(root / c["file"]).read_bytes() for c in taken if c["buoy"] == buoy}
        assert len(frames[buoy]) == by_buoy[buoy] and set(frames[buoy]) == written

    # nothing in the service raised or logged an error
    problems = [r for r in caplog.records if r.exc_info or r.levelno >= logging.ERROR]
    assert not problems, [f"{r.name}: {r.getMessage()}" for r in problems]
