"""The fleet benchmark's plumbing: the reference solvers are given our times and read back in our node numbers,
and every answer is judged by our own evaluator."""

import functools

import numpy as np
import pytest

from bench.energy_model import ACCEPTANCE_RADIUS_M, fly_items
from bench.fleet import instance, integer_times, judge, solve_ortools, solve_pyvrp
from gcs.domain.planning import FlightParams, mission_items
from gcs.missions.fleet_planning import plan_fleet_mission
from sitl_quad.config import VehicleConfig
from uavcore.geodesy import DEFAULT_HOME, LocalFrame


def test_integer_arcs_add_up_to_our_route_time():
    _, fleet = instance(20, 3, 0)
    times = integer_times(fleet)
    route = [5, 2, 17, 9]
    arcs = sum(times[a, b] for a, b in zip([0, *route], [*route, 0], strict=True))
    assert arcs / 1e3 == pytest.approx(fleet.route_time(0, route), abs=5 * 5e-4)  # 5 arcs rounded to the ms
    assert np.all(np.diag(times) == 0)


def test_both_reference_solvers_return_complete_plans_for_the_fleet():
    points, fleet = instance(25, 3, 1)
    # counted searches (PyVRP iterations, OR-Tools solutions), not a time limit: a loaded machine must get the
    # same answers (OR-Tools' first solution alone flies one vehicle); 60 s is only a backstop
    pyvrp = functools.partial(solve_pyvrp, iterations=100)
    ortools = functools.partial(solve_ortools, solutions=100)
    for solver in (pyvrp, ortools):
        verdict = judge(fleet, solver(fleet, points, 60.0, 0))
        assert verdict["feasible"], solver.func.__name__
        assert verdict["flying"] >= 2  # the min-max objective puts more than one vehicle in the air


def test_a_shares_predicted_time_is_what_its_vehicle_flies_in_lockstep():
    """The fleet's time model against the vehicle: the second vehicle of a depot (pad 3 m east, layer 8 m, started
    in its turn, held at its last buoy to land in its turn) flies its share, mission items as the service uploads
    them, in lockstep with its ADRC controller; start command to disarm as predicted, within 2 %."""
    frame = LocalFrame(*DEFAULT_HOME)

    def lat_lon(north: float, east: float) -> tuple[float, float]:
        return tuple(map(float, frame.from_ned(north, east, 0.0)[:2]))

    homes = {1: lat_lon(0.0, 0.0), 2: lat_lon(0.0, 3.0)}
    buoys = [lat_lon(60.0, -40.0), lat_lon(120.0, 20.0), lat_lon(-50.0, 80.0), lat_lon(-90.0, -30.0)]
    plan = plan_fleet_mission(homes, buoys, list("abcd"), 5.0, 3.0, 10.0, 1.0, time_limit_s=0.5)
    share = next(s for s in plan.shares if s.sysid == 2)
    assert share.depart_after == 1 and share.start_s > 0 and share.final_hold_s > 0  # this case has both
    flight = FlightParams(share.altitude_m, 10.0, 1.0, ACCEPTANCE_RADIUS_M, final_hold_s=share.final_hold_s)
    home = (*homes[2], DEFAULT_HOME[2])
    items = mission_items(share.plan, flight, homes[2])
    flown = fly_items(items, len(share.buoys), VehicleConfig(), 1, "adrc", 3.0 * share.predicted_time_s, home)
    assert flown["completed"]
    assert flown["time_s"] == pytest.approx(share.predicted_time_s, rel=0.02)
