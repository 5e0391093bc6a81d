"""The route energy model (planner.energy): its physics, the SortieCost it hands the planner, and one simulated
flight against the committed calibration (planner/energy_params.json)."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from planner import energy as energy_module
from planner.energy import (
    EnergyModel,
    RouteFlight,
    VehicleTerms,
    WindForecast,
    calibrated_sortie_cost,
    electrical_power_w,
    route_energy,
    turn_angles_deg,
)
from planner.errors import InputError
from planner.scenario import rest_to_rest_s
from planner.sortie_cost import EnergyBudget
from planner.sorties import plan_sorties

MODEL = EnergyModel.load()
FLIGHT = RouteFlight(altitude_m=10.0, speed_m_s=10.0, dwell_s=5.0)
CALM = WindForecast()


def leg_energy_wh(end_en, wind: WindForecast, flight: RouteFlight = FLIGHT) -> float:
    """Energy of the outbound leg alone (depot -> end) of a one-buoy mission."""
    phases = route_energy([[0.0, 0.0], end_en], flight, wind, MODEL).phases
    return sum(p.energy_wh for p in phases if p.name == "leg" and p.item == 1)


def hover_power_w(wind: WindForecast, nose_en=(0.0, 1.0)) -> float:
    air = -np.array([*wind.velocity_en, 0.0])
    variance = wind.variance_m2_s2(FLIGHT.altitude_m)
    return float(electrical_power_w(MODEL, air[None], np.zeros((1, 3)), np.array([nose_en]), 0.0, variance)[0])


def test_the_committed_parameters_are_for_the_simulated_vehicle():
    from sitl_quad.config import VehicleConfig

    config = VehicleConfig()
    assert MODEL.mismatches(VehicleTerms.from_airframe(config.airframe, config.battery.avionics_w)) == []
    assert "adrc" in MODEL.fitted_for["controller"]
    # a fitted model stays near its physical prior: hover thrust's rotor power within 20 % of kf (mg/kl)^1.5/2/eta
    prior = MODEL.vehicle.drag_torque_coefficient * (MODEL.vehicle.weight_n / MODEL.vehicle.lift_coefficient) ** 1.5
    assert MODEL.fitted.rotor_hover_w == pytest.approx(prior / 2.0 / config.battery.efficiency, rel=0.2)


def test_energy_grows_with_distance():
    energies = [route_energy([[0.0, 0.0], [d, 0.0]], FLIGHT, CALM, MODEL).energy_wh for d in (10, 50, 200, 800, 2000)]
    assert all(b > a for a, b in itertools.pairwise(energies))
    windy = WindForecast(6.0, 45.0)
    legs = [leg_energy_wh([0.0, d], windy) for d in (5, 30, 100, 400, 1500)]
    assert all(b > a for a, b in itertools.pairwise(legs))


def test_head_wind_costs_more_than_tail_wind_on_the_same_leg():
    east = [1000.0, 0.0]
    head = leg_energy_wh(east, WindForecast(6.0, 90.0))  # from the east: against a leg flown east
    tail = leg_energy_wh(east, WindForecast(6.0, 270.0))
    calm = leg_energy_wh(east, WindForecast(0.0, 0.0, turbulence_w20_m_s=6.0))  # same turbulence, no mean wind
    assert head > calm > tail
    # the leg takes the same time in all three: the commanded speed is over the ground
    times = {
        name: sum(
            p.time_s for p in route_energy([[0, 0], east], FLIGHT, w, MODEL).phases if p.name == "leg" and p.item == 1
        )
        for name, w in (("head", WindForecast(6.0, 90.0)), ("tail", WindForecast(6.0, 270.0)))
    }
    assert times["head"] == pytest.approx(times["tail"])
    assert times["head"] == pytest.approx(rest_to_rest_s(1000.0, 10.0, 3.0, 4.0))


def test_cross_wind_costs_more_than_none_at_the_same_commanded_speed():
    north = [0.0, 1000.0]
    cross = leg_energy_wh(north, WindForecast(6.0, 90.0, turbulence_w20_m_s=0.0))
    still = leg_energy_wh(north, WindForecast(0.0, 0.0, turbulence_w20_m_s=0.0))
    assert cross > still
    # holding station in that wind also costs more than hovering in still air
    assert hover_power_w(WindForecast(6.0, 90.0, 0.0)) > hover_power_w(CALM)


def test_dwell_adds_hover_power_times_time():
    route = [[0.0, 0.0], [300.0, 100.0], [-200.0, 250.0]]
    wind = WindForecast(5.0, 120.0)
    short = route_energy(route, RouteFlight(10.0, 10.0, 2.0), wind, MODEL)
    long = route_energy(route, RouteFlight(10.0, 10.0, 12.0), wind, MODEL)
    expected_wh = 0.0
    for a, b in itertools.pairwise(route):  # each dwell holds the nose along the leg flown in
        nose = np.subtract(b, a) / np.hypot(*np.subtract(b, a))
        expected_wh += hover_power_w(wind, nose) * 10.0 / 3600.0
    assert long.energy_wh - short.energy_wh == pytest.approx(expected_wh, rel=1e-9)
    assert long.time_s - short.time_s == pytest.approx(20.0)


def test_a_mission_to_nowhere_is_a_takeoff_and_a_landing():
    energy = route_energy([[0.0, 0.0]], FLIGHT, CALM, MODEL)
    assert {p.name for p in energy.phases} == {"spool-up", "climb", "overhead", "descent", "touchdown"}
    assert energy.energy_wh == pytest.approx(sum(p.energy_wh for p in energy.phases))
    assert 0.0 < energy.energy_wh < hover_power_w(CALM) * 30.0 / 3600.0  # well under half a minute of hover
    # flown at the return altitude, it is exactly every sortie's fixed part
    cost = calibrated_sortie_cost([[0.0, 0.0], [100.0, 0.0]], EnergyBudget(60.0), FLIGHT, CALM, MODEL)
    assert cost.sortie_energy_wh == pytest.approx(energy.energy_wh)
    assert cost.sortie_time_s == pytest.approx(energy.time_s)


def test_bad_input_is_refused():
    with pytest.raises(InputError):
        RouteFlight(altitude_m=0.0)
    with pytest.raises(InputError):
        WindForecast(speed_m_s=-1.0)
    with pytest.raises(InputError):
        EnergyModel.from_dict({"vehicle": {}, "navigator": {}, "fitted": {"no_such_term": 1.0}})


def harbour(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.vstack([[0.0, 0.0], rng.uniform((-300.0, -300.0), (900.0, 400.0), size=(n, 2))])


def test_sortie_cost_adds_up_to_the_route_energy_but_for_the_turns():
    """The cost charges every leg a turn of mean_turn_deg; a route flies its real turns. Past that difference the
    two agree: exactly in time, in energy up to the hovers' nose direction (north in the cost, along the leg
    flown in on the route: a slightly different drag in the wind)."""
    points = harbour(8, 3)
    wind = WindForecast(6.0, 200.0)
    cost = calibrated_sortie_cost(points, EnergyBudget(60.0), FLIGHT, wind, MODEL)
    angle = math.radians(MODEL.fitted.mean_turn_deg)
    one_mean_turn = route_energy([[0.0, 0.0], [100.0 * math.sin(angle), 100.0 * math.cos(angle)]], FLIGHT, wind, MODEL)
    mean_turn = next(p for p in one_mean_turn.phases if p.name == "turn")  # the first turn starts facing north
    for sortie in ([1, 2, 3], [4, 5, 6, 7, 8], [8, 2]):
        exact = route_energy(points[[0, *sortie]], FLIGHT, wind, MODEL)
        turns = [p for p in exact.phases if p.name == "turn"]
        legs = len(sortie) + 1
        assert len(turns) == legs
        extra_s = legs * mean_turn.time_s - sum(p.time_s for p in turns)
        extra_wh = legs * mean_turn.energy_wh - sum(p.energy_wh for p in turns)
        assert cost.time_s(sortie) == pytest.approx(exact.time_s + extra_s, abs=1e-6)
        assert cost.energy_wh(sortie) == pytest.approx(exact.energy_wh + extra_wh, rel=2e-3)


def test_the_planner_plans_within_the_budget_of_the_calibrated_cost():
    points = harbour(12, 5)
    wind = WindForecast(7.0, 300.0)
    budget = EnergyBudget(capacity_wh=20.0, reserve=0.2)  # 16 Wh usable: several sorties
    cost = calibrated_sortie_cost(points, budget, FLIGHT, wind, MODEL)
    plan = plan_sorties(cost, seed=1, time_limit_s=1.0, max_iterations=50)
    assert len(plan.sorties) >= 2
    assert cost.violations(plan.sorties) == []
    for sortie, energy in zip(plan.sorties, plan.energy_wh, strict=True):
        assert energy == pytest.approx(cost.energy_wh(sortie))
        exact = route_energy(points[[0, *sortie]], FLIGHT, wind, MODEL).energy_wh
        assert exact == pytest.approx(energy, rel=0.03)  # the mean-turn approximation, nothing more


def test_turn_angles_of_a_route():
    square = [[0.0, 0.0], [0.0, 100.0], [100.0, 100.0], [100.0, 0.0]]
    assert turn_angles_deg(square) == pytest.approx([0.0, 90.0, 90.0, 90.0])


# A whole mission in simulated time: 4.7 s on an idle machine, 7.5 to 11 s on a loaded one, the fast tier's longest.
@pytest.mark.slow
def test_one_simulated_flight_uses_the_predicted_energy():
    """A short mission flown by the whole stack in simulated time (ADRC cascade, lockstep, in-process): the
    battery's count from the start command to the disarm is within 5 % of the committed model's prediction."""
    from bench.energy_model import FlightCase, fly

    case = FlightCase(
        name="test", seed=4242, n_buoys=3, speed_m_s=9.0, altitude_m=5.0, dwell_s=3.0, wind_m_s=5.0, wind_from_deg=210.0
    )
    measured = fly(case)
    assert measured["completed"]
    predicted = route_energy(case.route_en(), case.flight, case.forecast, MODEL)
    assert predicted.energy_wh == pytest.approx(measured["energy_wh"], rel=0.05)
    assert predicted.time_s == pytest.approx(measured["time_s"], rel=0.05)


def test_many_legs_from_the_bearing_table_cost_what_each_leg_evaluated_alone_costs(monkeypatch):
    """Past EXACT_LEGS_MAX legs the cost comes from a table of bearings, exact in the length: the same numbers as
    one evaluation per leg, to 1e-4, in a wind that makes every bearing cost differently."""
    rng = np.random.default_rng(3)
    points = np.vstack([[0.0, 0.0], rng.uniform(-600.0, 600.0, (40, 2)), [[5.0, 3.0], [12.0, -20.0]]])  # short legs too
    args = (points, EnergyBudget(50.0, reserve=0.0), RouteFlight(), WindForecast(6.0, 250.0))
    assert len(points) ** 2 > energy_module.EXACT_LEGS_MAX  # the table is used
    tabled = calibrated_sortie_cost(*args)
    monkeypatch.setattr(energy_module, "EXACT_LEGS_MAX", 10**9)
    exact = calibrated_sortie_cost(*args)
    np.testing.assert_allclose(tabled.leg_energy_wh, exact.leg_energy_wh, rtol=1e-4)
    np.testing.assert_allclose(tabled.leg_time_s, exact.leg_time_s, rtol=1e-9)
