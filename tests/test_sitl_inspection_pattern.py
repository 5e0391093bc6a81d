"""The ground station's inspection pattern, flown by the vehicle in lockstep with its camera on its gimbal.

Per buoy the ground station uploads (gcs.domain.planning.inspection_items; frame GLOBAL_RELATIVE_ALT_INT for the
placed items, MISSION for the others, unused params NaN): DO_SET_ROI_LOCATION at the buoy's charted position (1 m
up), NAV_WAYPOINT at the standoff point (on the straight approach line, STANDOFF_M short of the buoy, hold 0),
IMAGE_START_CAPTURE (interval 1 / rate, count ceil(duration * rate), uavcore.light_character.burst_for),
NAV_WAYPOINT at the same standoff point holding the burst (count / rate) + 0.5 s, IMAGE_STOP_CAPTURE,
DO_SET_ROI_NONE, NAV_WAYPOINT at the buoy (dwell, acceptance radius). Built here, not by the ground station's
planner, so that this test of the vehicle does not move with the planner's API.

Two buoys (a north cardinal's quick light: 5 s at 13.3 Hz, a rate off the 50 Hz tick grid; an unlit special mark:
burst_for(None), 2 s at 10 Hz) in a 5 m/s crosswind with Dryden turbulence, the cascade ADRC flying (the stack's
default), the camera at 320x180 for speed. The same route without the groups (buoy waypoints with the same dwell)
is flown too, to measure what the pattern adds per buoy.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from adrc_offboard.cli import make_controller
from sitl_quad.attitude_loops import attitude_loops
from sitl_quad.camera import CameraSpec, camera_pose, image_name
from sitl_quad.camera_render import project
from sitl_quad.config import AttitudeControllerKind, ControlConfig, VehicleConfig
from sitl_quad.lockstep_harness import LockstepHarness
from sitl_quad.mavlink.mission import validate_item
from sitl_quad.vehicle import Vehicle
from sitl_quad.wind import WindConfig
from uavcore.buoy_world import World, WorldBuoy
from uavcore.geodesy import DEFAULT_HOME, LocalFrame
from uavcore.light_character import burst_for, parse
from uavcore.mavlink import mavlink
from uavcore.mission import MavCmd, MavFrame, MissionItem
from uavcore.rotation import rotate

pytestmark = pytest.mark.slow  # two lockstep flights of 70-85 simulated s, 87 frames rendered

SEED = 3
FRAME = LocalFrame(*DEFAULT_HOME)
ALTITUDE_M = 5.0
SPEED_M_S = 10.0
DWELL_S = 1.0
ACCEPTANCE_M = 2.0
STANDOFF_M = 20.0
ROI_UP_M = 1.0
HOLD_MARGIN_S = 0.5
WIND = WindConfig(speed_m_s=5.0, direction_from_deg=270.0, turbulence_w20_m_s=5.15)  # ~1 m/s sigma at 5 m
SPEC = CameraSpec("buoy-sim", "SimCam small", 4.5, 6.17, 6.17 * 9 / 16, 320, 180)
TICK_S = 0.02
REL, MISSION = MavFrame.GLOBAL_RELATIVE_ALT_INT, MavFrame.MISSION


@dataclass(frozen=True)
class Buoy:
    id: str
    kind: str
    light: str | None
    ne: tuple[float, float]  # charted, local NED metres from home


BUOYS = (Buoy("N1", "north", "Q W", (70.0, 25.0)), Buoy("S2", "special", None, (110.0, -35.0)))


def lat_lon(ne) -> tuple[float, float]:
    lat, lon, _ = FRAME.from_ned(float(ne[0]), float(ne[1]), 0.0)
    return float(lat), float(lon)


def world() -> World:
    buoys = []
    for b in BUOYS:
        light = parse(b.light) if b.light else None
        buoys.append(WorldBuoy(b.id, b.kind, lat_lon(b.ne), light, actual_light=light))
    return World(tuple(buoys))


@dataclass
class Group:
    """One buoy's group as uploaded: where and what the camera must do."""

    buoy: Buoy
    standoff_ne: np.ndarray  # of the uploaded (degE7) position
    interval_s: float
    count: int
    hold_s: float
    standoff_seq: int = 0  # the hold-0 waypoint
    hold_seq: int = 0  # the waypoint holding the burst
    roi_none_seq: int = 0
    buoy_seq: int = 0


def item(command: int, frame: int, params=(), ne=None, z: float = 0.0) -> dict:
    x = y = 0
    if ne is not None:
        lat, lon = lat_lon(ne)
        x, y = round(lat * 1e7), round(lon * 1e7)
    p1, p2, p3, p4 = (*map(float, params), math.nan, math.nan, math.nan, math.nan)[:4]
    return dict(command=command, frame=frame, param1=p1, param2=p2, param3=p3, param4=p4, x=x, y=y, z=z)


def uploaded_ne(it: dict) -> np.ndarray:
    north, east, _ = FRAME.to_ned(it["x"] * 1e-7, it["y"] * 1e-7, FRAME.alt0)
    return np.array([float(north), float(east)])


def inspection_mission(with_groups: bool) -> tuple[list[MissionItem], list[Group]]:
    """Take off, (the group and) a waypoint per buoy, return to launch."""
    items = [
        item(MavCmd.NAV_TAKEOFF, REL, (0.0, 0.0, 0.0, math.nan), (0.0, 0.0), ALTITUDE_M),
        item(MavCmd.DO_CHANGE_SPEED, MISSION, (1.0, SPEED_M_S, -1.0, 0.0)),
    ]
    groups = []
    previous = np.zeros(2)
    for buoy in BUOYS:
        at = np.array(buoy.ne)
        standoff = at - STANDOFF_M * (at - previous) / np.linalg.norm(at - previous)
        if with_groups:
            duration, rate = burst_for(parse(buoy.light) if buoy.light else None)
            count = math.ceil(duration * rate)
            group = Group(buoy, uploaded_ne(item(0, REL, ne=standoff)), 1 / rate, count, count / rate + HOLD_MARGIN_S)
            group.standoff_seq, group.hold_seq, group.roi_none_seq = len(items) + 1, len(items) + 3, len(items) + 5
            items += [
                item(MavCmd.DO_SET_ROI_LOCATION, REL, ne=at, z=ROI_UP_M),
                item(MavCmd.NAV_WAYPOINT, REL, (0.0, ACCEPTANCE_M, 0.0, math.nan), standoff, ALTITUDE_M),
                item(MavCmd.IMAGE_START_CAPTURE, MISSION, (0.0, 1 / rate, count, 0.0)),
                item(MavCmd.NAV_WAYPOINT, REL, (group.hold_s, ACCEPTANCE_M, 0.0, math.nan), standoff, ALTITUDE_M),
                item(MavCmd.IMAGE_STOP_CAPTURE, MISSION, (0.0,)),
                item(MavCmd.DO_SET_ROI_NONE, MISSION, (0.0,)),
            ]
            group.buoy_seq = len(items)
            groups.append(group)
        items.append(item(MavCmd.NAV_WAYPOINT, REL, (DWELL_S, ACCEPTANCE_M, 0.0, math.nan), at, ALTITUDE_M))
        previous = at
    items.append(item(MavCmd.NAV_RETURN_TO_LAUNCH, MISSION, (0.0, 0.0, 0.0, 0.0)))
    mission = [MissionItem(seq=seq, current=int(seq == 0), **it) for seq, it in enumerate(items)]
    for it in mission:  # what the vehicle's mission protocol accepts on upload
        assert validate_item(it, it.seq) == mavlink.MAV_MISSION_ACCEPTED, it
    return mission, groups


@dataclass
class Flight:
    """What happened at each tick (after the payload's turn): times, true positions, events, the gimbal."""

    ticks: int = 0
    t: list[float] = field(default_factory=list)
    position: list[np.ndarray] = field(default_factory=list)
    gimbal: list[tuple[str, float, float]] = field(default_factory=list)
    events: list[tuple[float, str, int]] = field(default_factory=list)
    captured: list = field(default_factory=list)  # CAMERA_IMAGE_CAPTURED
    groups: list[Group] = field(default_factory=list)
    image_dir: Path | None = None

    def time_of(self, kind: str, seq: int) -> float:
        return next(t for t, k, s in self.events if k == kind and s == seq)

    def position_at(self, t: float) -> np.ndarray:
        return self.position[int(np.argmin(np.abs(np.array(self.t) - t)))]

    @property
    def duration_s(self) -> float:
        return self.ticks * TICK_S


def fly(with_groups: bool, image_dir: Path) -> Flight:
    config = VehicleConfig(wind=WIND, control=ControlConfig(attitude_controller=AttitudeControllerKind.ADRC))
    vehicle = Vehicle(config, home=DEFAULT_HOME, seed=SEED, attitude_loops=attitude_loops())
    harness = LockstepHarness(vehicle, make_controller("adrc", 50.0))
    payload = harness.carry_payload(image_dir, world(), spec=SPEC)
    mission, groups = inspection_mission(with_groups)
    flight = Flight(groups=groups, image_dir=image_dir)

    def on_tick(record) -> None:
        flight.t.append(record.t)
        flight.position.append(np.array(record.truth.position, dtype=float))
        gimbal = payload.gimbal.gimbal
        flight.gimbal.append((gimbal.mode, gimbal.pitch, gimbal.yaw))
        flight.events += [(record.t, e.kind, e.seq) for e in harness.last_events]

    flight.ticks = harness.fly_mission(mission, on_tick=on_tick)
    flight.captured = list(payload.camera.captured)
    return flight


@pytest.fixture(scope="module")
def flights(tmp_path_factory) -> dict[str, Flight]:
    return {
        "pattern": fly(True, tmp_path_factory.mktemp("pattern")),
        "plain": fly(False, tmp_path_factory.mktemp("plain")),
    }


def captures_of(flight: Flight, group: Group) -> list:
    start, end = flight.time_of("mission_current", group.standoff_seq), flight.time_of("item_reached", group.hold_seq)
    return [m for m in flight.captured if start <= m.time_boot_ms / 1000 <= end + group.hold_s]


def test_the_whole_mission_is_flown_and_completes(flights):
    for flight in flights.values():
        last = max(s for _, k, s in flight.events if k == "mission_current")
        reached = [s for _, k, s in flight.events if k == "item_reached"]
        assert reached == list(range(last + 1))  # every item, in order, once
        assert ("mission_complete", last) in [(k, s) for _, k, s in flight.events]
        assert flight.events[-1][1] == "armed"  # landed back home and disarmed
        assert np.hypot(*flight.position[-1][:2]) < 1.0
    assert len(flights["pattern"].captured) == sum(g.count for g in flights["pattern"].groups)
    assert not flights["plain"].captured


def test_each_burst_is_its_commanded_count_at_its_interval_during_the_hold_at_the_standoff(flights):
    flight = flights["pattern"]
    for group in flight.groups:
        shots = captures_of(flight, group)
        assert len(shots) == group.count, group.buoy.id
        arrived = flight.time_of("item_reached", group.standoff_seq)
        # the second waypoint at the standoff is a leg of no length: reached at the next tick, then held
        assert flight.time_of("item_reached", group.hold_seq) - arrived == pytest.approx(TICK_S, abs=1e-9)
        hold_ends = flight.time_of("mission_current", group.hold_seq + 1)
        assert hold_ends - flight.time_of("item_reached", group.hold_seq) == pytest.approx(group.hold_s, abs=TICK_S)
        # capture j at the first tick at or after arrival + j * interval (the rate need not fit the tick grid)
        expected_ms = [round(1000 * (arrived + math.ceil(j * group.interval_s / TICK_S - 1e-6) * TICK_S)) for j in
                       range(group.count)]  # fmt: skip
        assert [m.time_boot_ms for m in shots] == expected_ms, group.buoy.id
        assert [m.image_index for m in shots] == list(range(shots[0].image_index, shots[0].image_index + group.count))
        for shot in shots:
            t = shot.time_boot_ms / 1000
            assert arrived <= t < hold_ends
            off = np.hypot(*(flight.position_at(t)[:2] - group.standoff_ne))
            assert off <= ACCEPTANCE_M, (group.buoy.id, t, off)
            assert shot.capture_result == 1


def test_the_vehicle_holds_the_standoff_without_drifting(flights):
    flight = flights["pattern"]
    for group in flight.groups:
        start, end = flight.time_of("item_reached", group.standoff_seq), flight.time_of("item_reached", group.hold_seq)
        end += group.hold_s
        held = [p for t, p in zip(flight.t, flight.position, strict=True) if start <= t <= end]
        errors = [np.hypot(*(p[:2] - group.standoff_ne)) for p in held]
        assert max(errors) < 0.5, (group.buoy.id, max(errors))  # in a 5 m/s crosswind with turbulence
        assert max(abs(p[2] + ALTITUDE_M) for p in held) < 0.3


def test_every_image_shows_its_buoy_and_the_gimbal_aims_at_the_roi(flights):
    flight = flights["pattern"]
    buoys = world()
    charted = [np.array(b.ne) for b in BUOYS]
    for k, group in enumerate(flight.groups):
        roi = np.array([*charted[k], -ROI_UP_M])
        for shot in captures_of(flight, group):
            t = shot.time_boot_ms / 1000
            # the camera's pose as the capture reports it: geotag (the estimate) and the camera's attitude
            north, east, down = FRAME.to_ned(shot.lat * 1e-7, shot.lon * 1e-7, shot.alt * 1e-3)
            pose = camera_pose((north, east, down), DEFAULT_HOME[2], shot.q)
            drift = buoys.positions(t, WIND.direction_from_deg, WIND.speed_m_s)[k]
            waterline = np.array([[*(charted[k] + drift), 0.0]])
            (u, v), in_front = (c[0] for c in project(pose, SPEC.intrinsics, waterline))
            assert in_front and 0 <= u < SPEC.width_px and 0 <= v < SPEC.height_px, (group.buoy.id, t, u, v)
            axis = rotate(np.array(shot.q), np.array([1.0, 0.0, 0.0]))
            sight = roi - np.array([north, east, down])
            miss = math.degrees(math.acos(np.dot(axis, sight) / np.linalg.norm(sight)))
            assert miss < 1.5, (group.buoy.id, t, miss)
            with Image.open(flight.image_dir / image_name(shot.image_index)) as image:
                assert image.format == "JPEG" and image.size == (SPEC.width_px, SPEC.height_px)


def test_the_gimbal_returns_to_neutral_after_roi_none(flights):
    flight = flights["pattern"]
    for group in flight.groups:
        none_at = flight.time_of("item_reached", group.roi_none_seq)
        after = [g for t, g in zip(flight.t, flight.gimbal, strict=True) if none_at <= t <= none_at + 1.0]
        assert all(mode == "neutral" for mode, _, _ in after)
        _, pitch, yaw = after[-1]
        assert (pitch, yaw) == (0.0, 0.0)
        before = flight.gimbal[flight.t.index(none_at) - 1]
        assert before[0] == "roi"


def test_what_the_pattern_adds_per_buoy(flights):
    """The pattern's cost: each burst's hold and the stop at the standoff, and the short leg from there."""
    added_s = (flights["pattern"].duration_s - flights["plain"].duration_s) / len(BUOYS)
    holds_s = sum(g.hold_s for g in flights["pattern"].groups) / len(BUOYS)
    stop_and_go_s = added_s - holds_s
    print(f"\nthe pattern adds {added_s:.2f} s per buoy: {holds_s:.2f} s of hold, {stop_and_go_s:.2f} s stop-and-go")
    assert 0 < stop_and_go_s < 6.0
