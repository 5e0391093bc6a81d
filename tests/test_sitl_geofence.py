"""Geofence: the zones and segment checks of uavcore.geofence, the fence and rally lists of the mission protocol,
GF_ACTION on a breach (a mission whose leg cuts an exclusion polygon, flown anyway, returns), SYS_STATUS."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from sitl_process import WAIT_S, GroundStation, mission_item
from test_sitl_vehicle import FRAME, HOME, fly_until, item

from sitl_quad.config import FailsafeConfig, GeofenceAction, VehicleConfig
from sitl_quad.params import ParameterError, ParameterTable
from sitl_quad.vehicle import CommandResult, Vehicle
from sitl_quad.vehicle_params import VEHICLE_PARAMETERS
from uavcore.geofence import CircleZone, FenceError, Geofence, PolygonZone
from uavcore.mavlink import mavlink
from uavcore.mission import MavCmd, MavFrame, MissionItem, MissionType
from uavcore.modes import FlightMode

GEOFENCE_BIT = mavlink.MAV_SYS_STATUS_GEOFENCE


def lat_lon(north: float, east: float) -> tuple[float, float]:
    lat, lon, _ = FRAME.from_ned(north, east, 0.0)
    return float(lat), float(lon)


def fence_item(seq: int, command: int, north: float, east: float, param1: float) -> MissionItem:
    lat, lon = lat_lon(north, east)
    return MissionItem(
        seq=seq,
        frame=MavFrame.GLOBAL_INT,
        command=command,
        param1=param1,
        x=round(lat * 1e7),
        y=round(lon * 1e7),
        mission_type=MissionType.FENCE,
    )


def polygon_items(corners: list[tuple[float, float]], command: int, first_seq: int = 0) -> list[MissionItem]:
    return [fence_item(first_seq + i, command, n, e, len(corners)) for i, (n, e) in enumerate(corners)]


# an exclusion square 20..40 m north, -10..10 m east: a leg from (0, 30) to (60, -30) cuts through it
EXCLUSION = [(20.0, -10.0), (40.0, -10.0), (40.0, 10.0), (20.0, 10.0)]


def test_fence_items_become_zones():
    items = [
        *polygon_items(EXCLUSION, MavCmd.NAV_FENCE_POLYGON_VERTEX_EXCLUSION),
        fence_item(4, MavCmd.NAV_FENCE_CIRCLE_INCLUSION, 0.0, 0.0, 200.0),
        fence_item(5, MavCmd.NAV_FENCE_RETURN_POINT, 1.0, 1.0, math.nan),
    ]
    fence = Geofence.from_items(items)
    polygon, circle = fence.zones
    assert isinstance(polygon, PolygonZone) and not polygon.inclusion and len(polygon.vertices) == 4
    assert isinstance(circle, CircleZone) and circle.inclusion and circle.radius_m == 200.0
    assert fence.return_point == pytest.approx(lat_lon(1.0, 1.0), abs=1e-7)
    assert fence.contains(*lat_lon(0.0, 0.0))
    assert not fence.contains(*lat_lon(30.0, 0.0))  # in the exclusion square
    assert not fence.contains(*lat_lon(250.0, 0.0))  # outside the inclusion circle
    assert fence.violation(*lat_lon(30.0, 0.0)) == polygon


@pytest.mark.parametrize(
    "items, seq",
    [
        (polygon_items(EXCLUSION[:3], MavCmd.NAV_FENCE_POLYGON_VERTEX_EXCLUSION)[:2], 0),  # 3 announced, 2 sent
        ([fence_item(0, MavCmd.NAV_FENCE_POLYGON_VERTEX_INCLUSION, 0, 0, 2.0)], 0),  # not a polygon
        ([fence_item(0, MavCmd.NAV_FENCE_CIRCLE_EXCLUSION, 0, 0, -1.0)], 0),  # a negative radius
        ([fence_item(0, MavCmd.NAV_FENCE_CIRCLE_INCLUSION, 0, 0, math.nan)], 0),  # no radius
        (
            [
                *polygon_items(EXCLUSION, MavCmd.NAV_FENCE_POLYGON_VERTEX_EXCLUSION)[:3],
                fence_item(3, MavCmd.NAV_FENCE_POLYGON_VERTEX_INCLUSION, 20, 10, 4.0),
            ],
            3,
        ),  # a vertex of another polygon where the fourth should be
    ],
)
def test_inconsistent_fence_lists_are_refused(items, seq):
    with pytest.raises(FenceError) as refused:
        Geofence.from_items(items)
    assert refused.value.seq == seq


def test_segment_checks_catch_legs_that_cut_a_zone_between_allowed_ends():
    fence = Geofence.from_items(polygon_items(EXCLUSION, MavCmd.NAV_FENCE_POLYGON_VERTEX_EXCLUSION))
    start, end = lat_lon(0.0, 30.0), lat_lon(60.0, -30.0)
    assert fence.contains(*start) and fence.contains(*end)
    assert fence.segment_violation(start, end) is fence.zones[0]  # through the square
    assert fence.segment_violation(lat_lon(0.0, 30.0), lat_lon(60.0, 30.0)) is None  # beside it
    assert fence.segment_violation(lat_lon(15.0, 15.0), lat_lon(45.0, 15.0)) is None
    circle = Geofence.from_items([fence_item(0, MavCmd.NAV_FENCE_CIRCLE_EXCLUSION, 50.0, 0.0, 10.0)])
    assert circle.segment_violation(lat_lon(0.0, 5.0), lat_lon(100.0, 5.0)) is not None  # chord 5 m off centre
    assert circle.segment_violation(lat_lon(0.0, 12.0), lat_lon(100.0, 12.0)) is None


def test_segment_may_pass_from_one_inclusion_zone_into_another_but_not_leave_them():
    west = [(-10.0, -20.0), (10.0, -20.0), (10.0, 1.0), (-10.0, 1.0)]
    items = [
        *polygon_items(west, MavCmd.NAV_FENCE_POLYGON_VERTEX_INCLUSION),
        fence_item(4, MavCmd.NAV_FENCE_CIRCLE_INCLUSION, 0.0, 10.0, 10.0),
    ]
    fence = Geofence.from_items(items)
    assert fence.segment_violation(lat_lon(0.0, -15.0), lat_lon(0.0, 15.0)) is None  # square, then circle
    assert fence.segment_violation(lat_lon(0.0, -15.0), lat_lon(9.0, 15.0)) is not None  # leaves at the seam
    # a concave inclusion polygon (a U): a leg across the notch leaves it although both ends are inside
    u_shape = [(0.0, 0.0), (30.0, 0.0), (30.0, 10.0), (10.0, 10.0), (10.0, 20.0), (30.0, 20.0), (30.0, 30.0), (0, 30.0)]
    concave = Geofence.from_items(polygon_items(u_shape, MavCmd.NAV_FENCE_POLYGON_VERTEX_INCLUSION))
    assert concave.contains(*lat_lon(20.0, 5.0)) and concave.contains(*lat_lon(20.0, 25.0))
    assert concave.segment_violation(lat_lon(20.0, 5.0), lat_lon(20.0, 25.0)) is not None
    assert concave.segment_violation(lat_lon(5.0, 5.0), lat_lon(5.0, 25.0)) is None


def crossing_mission() -> list[MissionItem]:
    """Takeoff, a waypoint east of the exclusion square, one north-west of it: the leg cuts the square."""
    return [
        item(0, MavCmd.NAV_TAKEOFF, 0.0, 0.0, alt=5.0),
        item(1, MavCmd.NAV_WAYPOINT, 0.0, 30.0, alt=5.0),
        item(2, MavCmd.NAV_WAYPOINT, 60.0, -30.0, alt=5.0),
        item(3, MavCmd.NAV_LAND, 60.0, -30.0, alt=0.0),
    ]


def test_a_leg_through_an_exclusion_zone_flown_anyway_triggers_gf_action_return():
    vehicle = Vehicle(VehicleConfig(failsafe=FailsafeConfig(geofence_action=GeofenceAction.RETURN)), HOME, seed=3)
    vehicle.set_fence(polygon_items(EXCLUSION, MavCmd.NAV_FENCE_POLYGON_VERTEX_EXCLUSION))
    vehicle.set_mission(crossing_mission())
    assert vehicle.arm() == CommandResult.ACCEPTED
    assert vehicle.start_mission() == CommandResult.ACCEPTED  # every waypoint is outside the square
    events = fly_until(vehicle, lambda v: v.mode != FlightMode.AUTO_MISSION, 120.0)
    assert vehicle.mode == FlightMode.AUTO_RTL
    north, east, _ = vehicle.truth.position
    assert 19.0 < north < 41.0 and -11.0 < east < 11.0  # it turned back at the square's edge
    texts = [e.text for e in events if e.kind == "text"]
    assert any(t.startswith("Geofence breached (exclusion polygon)") and "AUTO.RTL" in t for t in texts), texts
    fly_until(vehicle, lambda v: not v.armed, 120.0)
    assert math.hypot(*vehicle.truth.position[:2]) < 1.0  # back home and landed


def test_warning_only_keeps_flying_and_mission_inside_an_exclusion_is_refused():
    config = VehicleConfig(failsafe=FailsafeConfig(geofence_action=GeofenceAction.WARNING))
    vehicle = Vehicle(config, HOME, seed=3)
    vehicle.set_fence(polygon_items(EXCLUSION, MavCmd.NAV_FENCE_POLYGON_VERTEX_EXCLUSION))
    vehicle.set_mission([item(0, MavCmd.NAV_TAKEOFF), item(1, MavCmd.NAV_WAYPOINT, 30.0, 0.0)])
    vehicle.arm()
    assert vehicle.start_mission() == CommandResult.DENIED  # PX4's feasibility check: a waypoint in the square
    vehicle.set_mission(crossing_mission())
    assert vehicle.start_mission() == CommandResult.ACCEPTED
    events = fly_until(vehicle, lambda v: v.navigator.current_seq >= 3, 120.0)
    assert vehicle.mode == FlightMode.AUTO_MISSION
    assert sum(e.text.startswith("Geofence breached") for e in events) == 1  # once per breach


def test_gf_action_parameter_refuses_flight_termination():
    table = ParameterTable(VEHICLE_PARAMETERS, VehicleConfig())
    assert table.get("GF_ACTION") == GeofenceAction.HOLD
    table.set("GF_ACTION", 3)
    with pytest.raises(ParameterError):
        table.set("GF_ACTION", 4)
    assert table.get("GF_ACTION") == 3


@pytest.mark.integration
def test_fence_upload_download_and_sys_status_over_udp(start_sitl):
    vehicle = start_sitl(speed=5.0, extra_args=("--param", "GF_ACTION=3"))
    gcs = GroundStation(vehicle.port)
    try:
        gcs.connect()
        status = gcs.recv("SYS_STATUS", timeout=5)
        assert not status.onboard_control_sensors_present & GEOFENCE_BIT  # no fence yet
        corners = [lat_lon(n, e) for n, e in EXCLUSION]
        fence = [
            mission_item(
                i,
                mavlink.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION,
                lat,
                lon,
                frame=mavlink.MAV_FRAME_GLOBAL_INT,
                params=(4.0, 0.0, 0.0, 0.0),
                mission_type=mavlink.MAV_MISSION_TYPE_FENCE,
            )
            for i, (lat, lon) in enumerate(corners)
        ]
        bad = [*fence[:3]]  # three of four announced vertices
        ack = gcs.upload_mission(bad, mission_type=mavlink.MAV_MISSION_TYPE_FENCE, timeout=WAIT_S)
        assert ack is not None and ack.type == mavlink.MAV_MISSION_INVALID_PARAM1
        ack = gcs.upload_mission(fence, mission_type=mavlink.MAV_MISSION_TYPE_FENCE, timeout=WAIT_S)
        assert ack is not None and ack.type == mavlink.MAV_MISSION_ACCEPTED
        stored = gcs.download_mission(mission_type=mavlink.MAV_MISSION_TYPE_FENCE)
        assert [(i.command, i.param1, i.x, i.y) for i in stored] == [(f.command, 4.0, f.x, f.y) for f in fence]
        gcs.drain()
        status = gcs.recv("SYS_STATUS", timeout=5)
        assert status.onboard_control_sensors_present & GEOFENCE_BIT
        assert status.onboard_control_sensors_enabled & GEOFENCE_BIT
        assert status.onboard_control_sensors_health & GEOFENCE_BIT

        mission = [
            mission_item(i.seq, i.command, *lat_lon_of(i), i.z, params=(0.0, 0.0, 0.0, math.nan))
            for i in crossing_mission()
        ]
        assert gcs.upload_mission(mission).type == mavlink.MAV_MISSION_ACCEPTED
        assert gcs.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == mavlink.MAV_RESULT_ACCEPTED
        assert gcs.command(mavlink.MAV_CMD_MISSION_START).result == mavlink.MAV_RESULT_ACCEPTED
        text = gcs.recv("STATUSTEXT", timeout=2 * WAIT_S, condition=lambda m: m.text.startswith("Geofence breached"))
        assert text is not None and text.severity == mavlink.MAV_SEVERITY_CRITICAL
        assert gcs.wait_heartbeat(lambda m: FlightMode.from_custom_mode(m.custom_mode) == FlightMode.AUTO_RTL, WAIT_S)
        unhealthy = gcs.recv(
            "SYS_STATUS", timeout=5, condition=lambda m: not m.onboard_control_sensors_health & GEOFENCE_BIT
        )
        assert unhealthy is not None  # breaching: the geofence bit is not healthy
    finally:
        gcs.close()


def lat_lon_of(mission: MissionItem) -> tuple[float, float]:
    return mission.lat, mission.lon


# ----- a zone that bars home or the flying vehicle is discarded as the fence loads (PX4's Geofence::_updateFence)
# MAVSDK-Python's geofence example uploads its polygon with "no circle" spelt as a zero-radius inclusion circle at
# (0, 0); PX4 accepts the list and drops the circle, which holds no point, so not home either.
SQUARE = [(-11.0, -8.0), (11.0, -8.0), (11.0, 8.0), (-11.0, 8.0)]  # ±0.0001° around home, as the example's


def polygon_and_zero_circle() -> list[MissionItem]:
    circle = fence_item(4, MavCmd.NAV_FENCE_CIRCLE_INCLUSION, 0.0, 0.0, 0.0)
    circle = dataclasses.replace(circle, x=0, y=0)  # at latitude 0, longitude 0
    return [*polygon_items(SQUARE, MavCmd.NAV_FENCE_POLYGON_VERTEX_INCLUSION), circle]


def test_a_zero_radius_circle_is_a_zone_holding_no_point():
    fence = Geofence.from_items(polygon_and_zero_circle())
    polygon, circle = fence.zones
    assert isinstance(circle, CircleZone) and circle.radius_m == 0.0
    assert fence.contains(*lat_lon(0.0, 0.0))  # inside the polygon, one of the inclusion zones
    assert not Geofence((circle,)).contains(0.0, 0.0)  # not even its own centre (PX4: distance² < radius²)
    assert fence.violation(*lat_lon(30.0, 0.0)) == polygon


def test_the_vehicle_discards_the_zero_radius_circle_and_enforces_the_polygon():
    vehicle = Vehicle(VehicleConfig(failsafe=FailsafeConfig(geofence_action=GeofenceAction.RETURN)), HOME, seed=3)
    vehicle.set_fence(polygon_and_zero_circle())
    texts = [(e.text, e.severity) for e in vehicle.events if e.kind == "text"]
    assert texts == [("Geofence invalid, doesn't contain Home position", mavlink.MAV_SEVERITY_CRITICAL)]
    assert len(vehicle.fence_items) == 5  # kept as sent: a download hands back the whole list
    assert [zone.kind for zone in vehicle.geofence.fence.zones] == ["inclusion polygon"]
    assert vehicle.arm() == CommandResult.ACCEPTED
    assert vehicle.takeoff() == CommandResult.ACCEPTED
    fly_until(vehicle, lambda v: v.in_air and v.navigator.activity != "takeoff", 60.0)
    lat, lon = lat_lon(40.0, 0.0)
    assert vehicle.reposition(lat, lon, math.nan, math.nan) == CommandResult.ACCEPTED
    events = fly_until(vehicle, lambda v: v.mode == FlightMode.AUTO_RTL, 60.0)
    assert vehicle.mode == FlightMode.AUTO_RTL
    assert 10.0 < vehicle.truth.position[0] < 14.0  # turned back at the polygon's northern edge (11 m)
    assert any(e.text.startswith("Geofence breached (inclusion polygon)") for e in events)


def test_a_zone_barring_the_flying_vehicle_is_discarded():
    vehicle = Vehicle(VehicleConfig(failsafe=FailsafeConfig(geofence_action=GeofenceAction.RETURN)), HOME, seed=3)
    assert vehicle.arm() == CommandResult.ACCEPTED
    assert vehicle.takeoff() == CommandResult.ACCEPTED
    fly_until(vehicle, lambda v: v.in_air and v.navigator.activity != "takeoff", 60.0)
    lat, lon = lat_lon(30.0, 0.0)
    vehicle.reposition(lat, lon, math.nan, math.nan)
    fly_until(vehicle, lambda v: v.truth.position[0] > 25.0, 60.0)
    vehicle.events.clear()
    # home is inside the square, the vehicle 25 m north of it is not: PX4 keeps no zone that GF_ACTION would
    # act on at once (checkCurrentPositionRequirementsForGeofence)
    vehicle.set_fence(polygon_items(SQUARE, MavCmd.NAV_FENCE_POLYGON_VERTEX_INCLUSION))
    texts = [e.text for e in vehicle.events if e.kind == "text"]
    assert texts == ["Geofence invalid, doesn't contain current vehicle position"]
    assert not vehicle.geofence.present
    fly_until(vehicle, lambda v: False, 2.0)
    assert vehicle.mode == FlightMode.AUTO_LOITER  # no breach taken


def test_gf_action_hold_stops_a_reposition_beyond_the_fence():
    """GF_ACTION hold (the default) during a go-to, itself a loiter: the vehicle holds near the edge rather than
    flying on to the place beyond it."""
    vehicle = Vehicle(VehicleConfig(), HOME, seed=3)
    vehicle.set_fence(polygon_items(SQUARE, MavCmd.NAV_FENCE_POLYGON_VERTEX_INCLUSION))
    assert vehicle.arm() == CommandResult.ACCEPTED
    assert vehicle.takeoff() == CommandResult.ACCEPTED
    fly_until(vehicle, lambda v: v.in_air and v.navigator.activity != "takeoff", 60.0)
    vehicle.reposition(*lat_lon(60.0, 0.0), math.nan, math.nan)
    events = fly_until(vehicle, lambda v: False, 30.0)
    assert [e.text for e in events if e.kind == "text"] == ["Geofence breached (inclusion polygon): AUTO.LOITER"]
    assert vehicle.mode == FlightMode.AUTO_LOITER
    assert 11.0 < vehicle.truth.position[0] < 35.0  # past the edge by its braking distance, far from 60 m
    assert float(np.linalg.norm(vehicle.truth.velocity)) < 0.5  # holding


@pytest.mark.integration
def test_polygon_with_a_zero_radius_circle_over_udp(start_sitl):
    """The list MAVSDK's geofence example sends: accepted, the circle discarded with PX4's critical text, the list
    handed back whole, and the polygon enforced (GF_ACTION return on a go-to beyond it)."""
    vehicle = start_sitl(speed=10.0, extra_args=("--param", "GF_ACTION=3"))
    gcs, watcher = GroundStation(vehicle.port), GroundStation(vehicle.port)  # the watcher only reads STATUSTEXT
    try:
        gcs.connect()
        watcher.connect()
        fence = [
            mission_item(
                i.seq,
                i.command,
                i.lat,
                i.lon,
                frame=mavlink.MAV_FRAME_GLOBAL_INT,
                params=(i.param1, 0.0, 0.0, 0.0),
                mission_type=mavlink.MAV_MISSION_TYPE_FENCE,
            )
            for i in polygon_and_zero_circle()
        ]
        ack = gcs.upload_mission(fence, mission_type=mavlink.MAV_MISSION_TYPE_FENCE, timeout=WAIT_S)
        assert ack is not None and ack.type == mavlink.MAV_MISSION_ACCEPTED
        invalid = watcher.recv("STATUSTEXT", timeout=WAIT_S, condition=lambda m: m.text.startswith("Geofence"))
        assert invalid is not None and invalid.text == "Geofence invalid, doesn't contain Home position"
        assert invalid.severity == mavlink.MAV_SEVERITY_CRITICAL
        stored = gcs.download_mission(mission_type=mavlink.MAV_MISSION_TYPE_FENCE)
        assert [(i.command, i.param1, i.x, i.y) for i in stored] == [(f.command, f.param1, f.x, f.y) for f in fence]

        assert gcs.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == mavlink.MAV_RESULT_ACCEPTED
        assert gcs.command(mavlink.MAV_CMD_NAV_TAKEOFF).result == mavlink.MAV_RESULT_ACCEPTED
        lat, lon = lat_lon(40.0, 0.0)
        ack = gcs.command(mavlink.MAV_CMD_DO_REPOSITION, -1, 1, 0, math.nan, lat * 1e7, lon * 1e7, use_int=True)
        assert ack.result == mavlink.MAV_RESULT_ACCEPTED
        breach = watcher.recv("STATUSTEXT", timeout=WAIT_S, condition=lambda m: m.text.startswith("Geofence"))
        assert breach is not None and breach.text.startswith("Geofence breached (inclusion polygon)"), breach
        assert gcs.wait_heartbeat(lambda m: FlightMode.from_custom_mode(m.custom_mode) == FlightMode.AUTO_RTL, WAIT_S)
    finally:
        gcs.close()
        watcher.close()
