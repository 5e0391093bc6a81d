"""A fleet mission's plan (gcs.missions.fleet_planning): every buoy in one vehicle's share, each share an ordinary plan
from its vehicle's home at its own altitude layer, the makespan the longest share."""

from __future__ import annotations

import numpy as np
import pytest

from gcs.missions.fleet_planning import plan_fleet_mission
from planner.energy import EnergyModel
from planner.fleet import check_fleet
from planner.fleet_time import fleet_time_terms, share_timeline
from planner.scenario import random_area_points
from uavcore.geodesy import DEFAULT_HOME, LocalFrame

FRAME = LocalFrame(*DEFAULT_HOME)
MODEL = EnergyModel.load()


def _lat_lon(north_east: np.ndarray) -> list[tuple[float, float]]:
    return [tuple(map(float, FRAME.from_ned(n, e, 0.0)[:2])) for n, e in north_east]


def test_every_buoy_goes_to_one_vehicle_whose_share_is_a_plan_from_its_home_at_its_layer():
    homes = dict(zip((1, 2, 3), _lat_lon(np.array([[0.0, 0.0], [0.0, 3.0], [400.0, 600.0]])), strict=True))
    east_north = random_area_points(30, np.random.default_rng(4))
    buoys = _lat_lon(east_north[:, ::-1])
    ids = [f"B{i + 1}" for i in range(30)]
    plan = plan_fleet_mission(homes, buoys, ids, 5.0, 3.0, 10.0, 1.0, seed=1, time_limit_s=1.0)
    served = sorted(b for share in plan.shares for b in share.buoys)
    assert served == list(range(30))
    assert len(plan.shares) >= 2  # the min-max objective flies more than one vehicle
    for share in plan.shares:
        sysid_layer = list(homes).index(share.sysid)
        assert share.altitude_m == 5.0 + 3.0 * sysid_layer  # the request's order sets the layers
        assert share.plan.depot == pytest.approx(homes[share.sysid])
        assert share.plan.buoy_ids == [ids[b] for b in share.buoys]
        assert share.plan.order == list(range(len(share.buoys)))  # the fleet planner's flying order, kept
        assert np.allclose(share.plan.buoys_lat_lon, [buoys[b] for b in share.buoys], rtol=0, atol=1e-9)
    assert plan.makespan_s == pytest.approx(max(s.start_s + s.predicted_time_s for s in plan.shares))
    section = plan.plan_section()
    assert [s.sysid for s in section.shares] == [s.sysid for s in plan.shares]
    assert [s.buoys for s in section.shares] == [s.buoys for s in plan.shares]
    assert [s.home for s in section.shares] == [list(s.plan.depot) for s in plan.shares]


def test_the_share_times_are_the_calibrated_timelines_and_the_planners_sums_agree_with_them():
    homes = dict(zip((4, 7), _lat_lon(np.array([[0.0, 0.0], [300.0, 300.0]])), strict=True))
    buoys = _lat_lon(np.array([[50.0, 0.0], [0.0, 50.0], [320.0, 300.0], [300.0, 340.0]]))
    plan = plan_fleet_mission(homes, buoys, ["a", "b", "c", "d"], 5.0, 3.0, 10.0, 2.0, time_limit_s=0.5)
    by_vehicle = {s.sysid: sorted(s.buoys) for s in plan.shares}
    assert by_vehicle == {4: [0, 1], 7: [2, 3]}  # each takes the buoys beside its own home
    local = FRAME.project(np.array([*homes.values(), *buoys]))
    altitudes = [5.0, 8.0]
    terms = fleet_time_terms(local, [0, 1], altitudes, 10.0, 2.0, MODEL)
    fleet = check_fleet(local, [0, 1], 10.0, terms.dwell_s, terms.fixed_s, terms.leg_time_s)
    for k, share in enumerate(plan.shares):
        # two depots 400 m apart: each vehicle alone in its zone, no wait, no hold
        assert (share.start_s, share.final_hold_s, share.depart_after) == (0.0, 0.0, None)
        timeline = share_timeline(local[[k, *(2 + b for b in share.buoys)]], altitudes[k], 10.0, 2.0, MODEL)
        assert share.predicted_time_s == pytest.approx(timeline.time_s, rel=1e-9)
        # the planner's sums differ from the exact timeline by the turns only: one of the fitted mean angle (70 deg,
        # 2.5 s) before each leg in place of the real one (0 to 180 deg: 0 to 4.3 s)
        sums = fleet.route_time(k, [2 + b for b in share.buoys])
        assert abs(sums - share.predicted_time_s) <= 2.5 * (len(share.buoys) + 1)
        assert abs(sums - share.predicted_time_s) > 0.1  # they do differ: the timeline has the real turns


def test_a_lost_vehicles_buoys_go_where_they_lengthen_the_longest_remaining_flight_least():
    from gcs.missions.fleet_planning import reshare

    home = np.zeros(2)
    # vehicle 1 is near the lost buoys' corner, vehicle 2 far away with a long way still to fly
    flying = {
        1: (np.array([0.0, 100.0]), [np.array([0.0, 150.0])], home),
        2: (np.array([500.0, 0.0]), [np.array([600.0, 0.0]), np.array([700.0, 0.0])], home),
    }
    lost = [np.array([20.0, 120.0]), np.array([40.0, 160.0])]
    routes = reshare(flying, lost, 10.0, 1.0)
    # vehicle 1: its own buoy (0) and both lost ones (1 + 0, 1 + 1); vehicle 2, far and busy: its own only
    assert sorted(routes[1]) == [0, 1, 2] and routes[2] == [0, 1]
    moved = reshare({1: flying[1], 2: (np.array([10.0, 130.0]), [], home)}, lost, 10.0, 1.0)
    # both near the lost buoys: one each keeps the longest remaining flight shortest
    assert (len(moved[1]), len(moved[2])) == (2, 1)
    # one vehicle left flying (the other of a pair lost): it takes every lost buoy
    alone = reshare({1: flying[1]}, lost, 10.0, 1.0)
    assert sorted(alone[1]) == [0, 1, 2]
