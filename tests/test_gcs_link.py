"""Link manager, mission protocol and lifecycle failure paths against a tiny scripted in-test vehicle
(tests/scripted_vehicle.py); the real vehicle is flown in test_gcs_integration.py.
"""

import asyncio
import math
import time

import pytest
from fastapi.testclient import TestClient
from scripted_vehicle import ScriptedVehicle, mavlink

from gcs.api.app import create_app
from gcs.settings import Settings
from gcs.vehicle.link import CommandTimeoutError, LinkManager
from gcs.vehicle.mission_protocol import MissionRejectedError, MissionTimeoutError, download_items, upload_items
from uavcore.mission import MavCmd, MissionItem

# The scripted vehicle answers over loopback UDP, in real time: the lifecycle tests wait out the service's
# timeouts and graces (3 to 8 s each).
pytestmark = pytest.mark.integration

ITEMS = [
    MissionItem(seq=i, frame=6, command=MavCmd.NAV_WAYPOINT, param1=1.0, x=389210000 + i, y=1216630000, z=5.0)
    for i in range(4)
]


@pytest.fixture
def vehicle():
    v = ScriptedVehicle()
    v.start()
    yield v
    v.stop()


# A deadline for what the scripted vehicle (a thread of this process, sharing its GIL) or the link will do: only
# reached when the behaviour is wrong, however loaded the machine.
BACKSTOP_S = 60.0  # only a condition that never comes reaches it (a loaded machine starves the fake's thread)


async def connected_link(vehicle, timeout_s: float = 5.0) -> LinkManager:
    """A link to the scripted vehicle. Its heartbeats come at 10 Hz: the heartbeat timeout is a backstop for a
    loaded machine's stalls unless a test is about the timeout itself."""
    link = LinkManager(f"udpout:127.0.0.1:{vehicle.port}", heartbeat_timeout_s=timeout_s)
    await link.start()
    assert await link.wait_connected(BACKSTOP_S)
    return link


async def eventually(condition, what: str) -> None:
    """Poll `condition` on the event loop until it holds (the link works on the same loop meanwhile)."""
    deadline = time.monotonic() + BACKSTOP_S
    while not condition():
        assert time.monotonic() < deadline, f"never: {what}"
        await asyncio.sleep(0.05)


def test_link_connects_identifies_as_gcs_and_tracks_state(vehicle):
    async def scenario():
        link = await connected_link(vehicle)
        await eventually(lambda: (255, 190, mavlink.MAV_TYPE_GCS) in vehicle.gcs_heartbeats, "a GCS heartbeat")
        await eventually(lambda: link.status.yaw is not None, "an ATTITUDE")
        await eventually(lambda: mavlink.MAV_CMD_REQUEST_MESSAGE in vehicle.commands_seen, "HOME_POSITION asked for")
        await link.stop()
        return link

    link = asyncio.run(scenario())
    assert link.status.yaw == pytest.approx(0.5) and link.status.time_boot_ms >= 60_000


def test_command_ack_and_three_tries_without_one(vehicle):
    vehicle.command_results[mavlink.MAV_CMD_COMPONENT_ARM_DISARM] = mavlink.MAV_RESULT_DENIED
    vehicle.command_results[mavlink.MAV_CMD_NAV_LAND] = None

    async def scenario():
        link = await connected_link(vehicle)
        try:
            denied = await link.command_long(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, [1])
            with pytest.raises(CommandTimeoutError):
                await link.command_long(mavlink.MAV_CMD_NAV_LAND, [], tries=3, timeout_s=0.2)
        finally:
            await link.stop()
        return denied

    assert asyncio.run(scenario()) == mavlink.MAV_RESULT_DENIED
    # the link has stopped: the vehicle's thread may still be reading the last try from its socket
    deadline = time.monotonic() + BACKSTOP_S
    while vehicle.commands_seen.count(mavlink.MAV_CMD_NAV_LAND) < 3 and time.monotonic() < deadline:
        time.sleep(0.05)
    assert vehicle.commands_seen.count(mavlink.MAV_CMD_NAV_LAND) == 3


def test_upload_retries_a_lost_request_and_download_round_trips(vehicle):
    vehicle.drop_first_request_of = {2}

    async def scenario():
        link = await connected_link(vehicle)
        try:
            await upload_items(link, ITEMS, step_timeout_s=1.0)  # a loaded machine's late answer is not a loss
            return await download_items(link, step_timeout_s=1.0)
        finally:
            await link.stop()

    back = asyncio.run(scenario())
    assert [(i.seq, i.x, i.param1, i.z) for i in back] == [(i.seq, i.x, i.param1, i.z) for i in ITEMS]
    assert math.isnan(back[0].param2)


def test_upload_refused_and_upload_unanswered(vehicle):
    async def scenario():
        link = await connected_link(vehicle)
        try:
            vehicle.mission_result = mavlink.MAV_MISSION_NO_SPACE
            with pytest.raises(MissionRejectedError, match="MAV_MISSION_NO_SPACE"):
                await upload_items(link, ITEMS, step_timeout_s=1.0)
            vehicle.mission_result = mavlink.MAV_MISSION_ACCEPTED
            vehicle.ignore_mission = True
            with pytest.raises(MissionTimeoutError, match="after MISSION_COUNT"):
                await upload_items(link, ITEMS, step_timeout_s=0.1, retries=2)
        finally:
            await link.stop()

    asyncio.run(scenario())


def test_reboot_and_heartbeat_loss_are_detected(vehicle):
    async def scenario():
        link = await connected_link(vehicle, timeout_s=2.0)
        try:
            # connected is the first HEARTBEAT; the clock comes in the ATTITUDE the vehicle's thread sends after it,
            # which a loaded machine can delay past the move below: the link must hold the old clock first
            await eventually(lambda: link.status.time_boot_ms is not None, "the vehicle's clock (an ATTITUDE)")
            vehicle.boot_start = time.monotonic() + 60.0  # time_boot_ms jumps back by a minute
            await eventually(lambda: link.status.reboots > 0, "the reboot seen (the next ATTITUDE shows it)")
            reboots = link.status.reboots
            vehicle.silent = True
            await eventually(lambda: not link.status.connected, "the silent vehicle's link lost")
            return reboots, link.status.connected
        finally:
            await link.stop()

    assert asyncio.run(scenario()) == (1, False)


# ----- lifecycle failure paths through the API
def fly(tmp_path, vehicle, timeout_s=60.0) -> dict:
    settings = Settings(
        db_path=tmp_path / "gcs.sqlite", vehicle_url=f"udpout:127.0.0.1:{vehicle.port}", vehicle_wait_s=30.0
    )
    with TestClient(create_app(settings)) as client:
        mission_id = client.post("/missions", json={"buoys": [{"lat": 38.9215, "lon": 121.6635}]}).json()["id"]
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            mission = client.get(f"/missions/{mission_id}").json()
            if mission["status"] in ("completed", "failed", "aborted"):
                return mission
            time.sleep(0.05)
    raise AssertionError(f"mission still {mission['status']}")


def test_mission_refused_by_the_vehicle_fails_with_its_reason(tmp_path, vehicle):
    vehicle.mission_result = mavlink.MAV_MISSION_INVALID_PARAM1
    mission = fly(tmp_path, vehicle)
    assert mission["status"] == "failed" and "MAV_MISSION_INVALID_PARAM1" in mission["reason"]
    assert [e["status"] for e in mission["events"]] == ["planned", "uploading", "failed"]


def test_arm_refused_fails_with_its_reason(tmp_path, vehicle):
    vehicle.command_results[mavlink.MAV_CMD_COMPONENT_ARM_DISARM] = mavlink.MAV_RESULT_TEMPORARILY_REJECTED
    mission = fly(tmp_path, vehicle)
    assert mission["status"] == "failed"
    assert mission["reason"] == "the vehicle refused to arm (MAV_RESULT_TEMPORARILY_REJECTED)"
    assert len(vehicle.stored) == 4  # takeoff, speed, one buoy, return


def test_arm_refused_with_the_vehicles_words_gives_them_as_the_reason(tmp_path, vehicle):
    """The cause is the STATUSTEXT the vehicle sends with its refusal (after the COMMAND_ACK here), not only the
    MAV_RESULT."""
    vehicle.command_results[mavlink.MAV_CMD_COMPONENT_ARM_DISARM] = mavlink.MAV_RESULT_DENIED
    vehicle.refusal_texts[mavlink.MAV_CMD_COMPONENT_ARM_DISARM] = "Arming denied: battery 0%, below 7%"
    mission = fly(tmp_path, vehicle)
    assert mission["status"] == "failed"
    assert mission["reason"] == "the vehicle refused to arm: Arming denied: battery 0%, below 7% (MAV_RESULT_DENIED)"


def test_vehicle_that_never_arms_ends_failed_not_flying_forever(tmp_path, vehicle):
    # it acknowledges arm and start but its heartbeat never shows armed: the disarm grace ends the mission
    mission = fly(tmp_path, vehicle)
    assert mission["status"] == "failed" and "disarmed before completing" in mission["reason"]
    assert mavlink.MAV_CMD_DO_SET_MODE in vehicle.commands_seen


def test_a_busy_service_behind_on_its_reading_does_not_take_a_talking_vehicle_for_lost(vehicle):
    """The event loop held up longer than the heartbeat timeout (a busy service: asyncio reads one datagram a
    turn) while the vehicle goes on talking: its heartbeats wait unread in the socket, and the watchdog, run
    before they are read, must not call the link lost. A vehicle that really falls silent still is."""

    async def scenario():
        link = await connected_link(vehicle, timeout_s=0.5)
        try:
            time.sleep(1.0)  # the loop blocked: nothing read for twice the timeout, the vehicle's thread sending
            assert link._transport is not None and link._transport.backlogged()
            link._check_heartbeat_timeout()  # what the heartbeat task does when the loop next runs it
            held = link.status.connected
            vehicle.silent = True
            await eventually(lambda: not link.status.connected, "the silent vehicle's link lost")
            return held
        finally:
            await link.stop()

    assert asyncio.run(scenario()) is True
