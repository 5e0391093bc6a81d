"""Energy-aware planning: how much of a battery a sortie may use, the sorties that fit, and what each will draw.

Pure: the service reads the vehicle's pack (its BAT1_* and BAT_*_THR parameters) and hands it in as a PackSpec.

The budget of one sortie, in watt-hours at the pack's terminals (what BATTERY_STATUS.energy_consumed counts):
    usable = E(pack, full -> reserve charge)          (uavcore.battery_pack: the LiPo chart, the I R drop)
    budget = usable * (1 - margin)
The reserve is a state of charge, as the vehicle's thresholds are: by default the vehicle's BAT_LOW_THR, so a
sortie flown as predicted lands before the low-battery warning. The margin keeps room for the forecast's and
the model's errors (planner.energy predicts held-out flights within 0.72 % worst; gusts the forecast did not
carry add more).

Sorties: the calibrated energy model's SortieCost (planner.energy.calibrated_sortie_cost, legs against the
forecast wind) and planner.sorties.plan_sorties. Fenced legs get a time penalty (the planner avoids them like
the single-tour planner does); their energy stays true. Each sortie's prediction is then the model's exact
evaluation of its route (planner.energy.route_energy, its real turn angles, which the SortieCost approximates by
a mean turn); a sortie whose exact prediction exceeds the budget sends the planner round again with a budget
tightened by the excess, so every returned sortie fits by the exact prediction.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass

import numpy as np

from gcs.domain.planning import FlightParams, Plan, local_nodes, make_plan, sorties_plan
from gcs.domain.records import PlanEnergy, SortiePrediction
from gcs.domain.schemas import BatteryIn, PlanRequest
from gcs.missions.validation import RequestInvalidError
from planner.energy import EnergyModel, RouteFlight, WindForecast, calibrated_sortie_cost, route_energy
from planner.errors import UnreachableBuoyError
from planner.sortie_cost import EnergyBudget
from planner.sorties import plan_sorties
from uavcore.battery_pack import PackSpec

FENCED_LEG_PENALTY_S = 1e7  # a fenced leg is taken only when nothing else serves its buoy
REPLAN_ROUNDS = 3  # tightening rounds when an exact prediction exceeds the budget
# Ruin-and-recreate rounds of the sortie search: small instances converge in a few hundred (13 buoys: the same
# cost after 100 rounds as after 18 000 in 2 s), so a request is answered in a fraction of its time limit and the
# same request gives the same plan; the time limit still caps large ones (100 buoys: ~2 000 rounds in 2 s).
SEARCH_ROUNDS_BASE, SEARCH_ROUNDS_PER_BUOY = 500, 30


@dataclass(frozen=True)
class BatteryPlan:
    """What a request's battery options resolve to."""

    pack: PackSpec
    pack_source: str  # "vehicle" (read from its parameters) or "energy model" (the pack it was fitted for)
    reserve: float  # state of charge kept at landing, 0..1
    reserve_source: str  # "vehicle" (its BAT_LOW_THR) or "request"
    margin_pct: float  # energy kept free for prediction errors, % of the usable energy
    split: bool  # False: one sortie whatever the prediction says
    objective: str  # "time" or "distance"
    wind: WindForecast


def battery_plan(request: PlanRequest, vehicle_pack: PackSpec | None, model: EnergyModel) -> BatteryPlan:
    """The request's battery options over the vehicle's pack (None: the vehicle did not say; the energy model's
    pack stands in, and the answer says so)."""
    options = request.battery
    # asked only of a request with battery options; its validator turns the "vehicle" shorthand into BatteryIn()
    assert isinstance(options, BatteryIn)
    pack, source = (vehicle_pack, "vehicle") if vehicle_pack is not None else (model_pack(model), "energy model")
    if options.capacity_mah is not None:
        pack = dataclasses.replace(pack, capacity_mah=options.capacity_mah)
    if options.reserve_pct == "vehicle":
        reserve, reserve_source = pack.low_threshold, source
    else:
        reserve, reserve_source = options.reserve_pct / 100.0, "request"
    wind = request.wind
    forecast = WindForecast(wind.speed_m_s, wind.from_deg, wind.turbulence_w20_m_s) if wind else WindForecast()
    return BatteryPlan(pack, source, reserve, reserve_source, options.margin_pct, options.split, options.objective,
                       forecast)  # fmt: skip


def route_flight(flight: FlightParams) -> RouteFlight:
    return RouteFlight(flight.altitude_m, flight.speed_m_s, flight.dwell_s)


def energy_plan(
    depot: tuple[float, float],
    buoys: list[tuple[float, float]],
    buoy_ids: list[str],
    flight: FlightParams,
    battery: BatteryPlan,
    seed: int,
    time_limit_s: float,
    fenced: dict[tuple[int, int], str],
    method: str = "auto",
    model: EnergyModel | None = None,
) -> Plan:
    """The plan of a request with battery options: sorties that each fit the budget (or, without `split`, the
    single tour), each with its predicted energy. Raises RequestInvalidError naming a buoy no sortie can reach."""
    model = model or EnergyModel.load()
    started = time.perf_counter()
    points = np.vstack([[0.0, 0.0], local_nodes(depot, buoys)[1]])
    if not battery.split:
        tour = make_plan(depot, buoys, buoy_ids, method, seed, time_limit_s, fenced)
        sorties, method_name = [tour.order], tour.method
        estimates = [sortie_energy(points, tour.order, route_flight(flight), battery.wind, model)]
    else:
        try:
            sorties, estimates = split_into_sorties(
                points, route_flight(flight), battery, model, fenced, seed, time_limit_s
            )
        except UnreachableBuoyError as error:
            raise RequestInvalidError(unreachable_errors(error, buoy_ids)) from None
        method_name = "sorties: route-first cluster-second + SISR (planner.sorties)"
    energy = predictions(estimates, battery, model)
    return sorties_plan(depot, buoys, buoy_ids, sorties, method_name, time.perf_counter() - started, energy)


def unreachable_errors(error: UnreachableBuoyError, buoy_ids: list[str]) -> list[tuple[tuple, str]]:
    """One 422 entry per buoy no sortie can reach, naming it and its shortfall."""
    return [
        (
            ("body", "buoys", node - 1),
            f"buoy {buoy_ids[node - 1]} cannot be reached and flown back from within one battery: it needs "
            f"{short_wh + error.budget_wh:.1f} Wh, {short_wh:.1f} Wh ({short_pct:.0f} %) more than the "
            f"{error.budget_wh:.1f} Wh a sortie may use",
        )
        for node, short_wh, short_pct in zip(error.buoys, error.shortfall_wh, error.shortfall_pct, strict=True)
    ]


@dataclass(frozen=True)
class ChargeNeed:
    """What a sortie needs of the pack at take-off: its predicted energy, and the charge to land with the reserve."""

    energy_wh: float
    reserve_pct: float
    needed_pct: float  # may exceed 100: no pack of this kind flies it with the reserve left


def charge_needed(plan: Plan, sortie: int, flight: FlightParams, pack: PackSpec, model: EnergyModel) -> ChargeNeed:
    """The pre-flight figure of sortie `sortie` (0-based; a single tour is sortie 0): an energy-planned mission's
    own prediction (its reserve, its wind forecast); otherwise the same route energy model in calm air with the
    pack's BAT_LOW_THR as the reserve, so a tour flown as predicted lands before the low-battery warning."""
    if plan.energy is not None:
        entry = plan.energy.sorties[sortie]
        return ChargeNeed(entry.energy_wh, plan.energy.reserve_pct, entry.needed_charge_pct)
    points = np.vstack([[0.0, 0.0], np.asarray(plan.buoys_local, dtype=float).reshape(-1, 2)])
    energy_wh, _ = sortie_energy(points, plan.sortie_orders()[sortie], route_flight(flight), WindForecast(), model)
    landing = pack.charge_after(energy_wh, 1.0, steady_load_w(model))
    return ChargeNeed(energy_wh, 100.0 * pack.low_threshold, 100.0 * (1.0 - landing + pack.low_threshold))


def model_pack(model: EnergyModel) -> PackSpec:
    """The pack the energy model was fitted with (energy_params.json's fitted_for.battery)."""
    fitted = model.fitted_for.get("battery", {})
    names = {f.name for f in dataclasses.fields(PackSpec)}
    return PackSpec(**{k: v for k, v in fitted.items() if k in names})


def steady_load_w(model: EnergyModel) -> float:
    """The pack's typical load: hover in calm air (rotors plus avionics), for the budget's I R drop."""
    return model.fitted.rotor_hover_w + model.vehicle.avionics_w


def budget(battery: BatteryPlan, model: EnergyModel) -> dict[str, float]:
    """The pack's energies: full, usable down to the reserve, and the planning budget after the margin."""
    load = steady_load_w(model)
    usable = battery.pack.energy_wh(1.0, battery.reserve, load)
    return {
        "capacity_wh": battery.pack.energy_wh(1.0, 0.0, load),
        "usable_wh": usable,
        "budget_wh": usable * (1.0 - battery.margin_pct / 100.0),
    }


def split_into_sorties(
    points_en: np.ndarray,
    flight: RouteFlight,
    battery: BatteryPlan,
    model: EnergyModel,
    fenced: dict[tuple[int, int], str],
    seed: int,
    time_limit_s: float,
) -> tuple[list[list[int]], list[tuple[float, float]]]:
    """Sorties (lists of buoy indices, 0-based, in flying order) that each fit the budget by the exact prediction,
    and each one's (energy Wh, time s) by that prediction. points_en: the depot then the buoys, [east, north]
    metres. Raises planner.errors.UnreachableBuoyError."""
    target = budget(battery, model)["budget_wh"]
    limit = target
    deadline = time.perf_counter() + time_limit_s  # every round shares the request's time limit
    for _ in range(REPLAN_ROUNDS):
        cost = calibrated_sortie_cost(points_en, EnergyBudget(limit, reserve=0.0), flight, battery.wind, model)
        if fenced:
            penalty = np.zeros_like(cost.leg_time_s)
            for i, j in fenced:
                penalty[i, j] = penalty[j, i] = FENCED_LEG_PENALTY_S
            cost = dataclasses.replace(cost, leg_time_s=cost.leg_time_s + penalty)
        rounds = SEARCH_ROUNDS_BASE + SEARCH_ROUNDS_PER_BUOY * (len(points_en) - 1)
        remaining_s = max(deadline - time.perf_counter(), 0.1 * time_limit_s)
        plan = plan_sorties(cost, battery.objective, seed, remaining_s, max_iterations=rounds)
        sorties = [[node - 1 for node in sortie] for sortie in plan.sorties]
        estimates = [sortie_energy(points_en, s, flight, battery.wind, model) for s in sorties]
        worst = max(energy_wh for energy_wh, _ in estimates)
        if worst <= target:
            break
        limit *= target / worst
    return sorties, estimates  # still over after the rounds: predictions() reports the negative margin


def sortie_energy(
    points_en: np.ndarray, sortie: list[int], flight: RouteFlight, wind: WindForecast, model: EnergyModel
) -> tuple[float, float]:
    """(energy Wh, time s) the model predicts for one sortie: depot, its buoys (0-based) in order, home."""
    route = np.vstack([points_en[0], points_en[1:][sortie]])
    result = route_energy(route, flight, wind, model)
    return result.energy_wh, result.time_s


def predictions(estimates: list[tuple[float, float]], battery: BatteryPlan, model: EnergyModel) -> PlanEnergy:
    """The plan's energy section from each sortie's predicted (energy Wh, time s): the battery, the budget and,
    per sortie, the predicted energy and time, the margin left in the budget and the charge predicted at landing."""
    energies = budget(battery, model)
    load = steady_load_w(model)
    per_sortie = []
    for energy_wh, time_s in estimates:
        landing = battery.pack.charge_after(energy_wh, 1.0, load)
        per_sortie.append(
            SortiePrediction(
                energy_wh=energy_wh,
                time_s=time_s,
                margin_wh=energies["budget_wh"] - energy_wh,
                margin_pct=100.0 * (energies["budget_wh"] - energy_wh) / energies["budget_wh"],
                landing_charge_pct=100.0 * landing,
                # the charge the vehicle must have at take-off to land with the reserve
                needed_charge_pct=100.0 * (1.0 - landing + battery.reserve),
            )
        )
    return PlanEnergy(
        **energies,
        reserve_pct=100.0 * battery.reserve,
        reserve_source=battery.reserve_source,
        margin_pct=battery.margin_pct,
        pack=dataclasses.asdict(battery.pack),
        pack_source=battery.pack_source,
        wind=dataclasses.asdict(battery.wind),
        objective=battery.objective,
        split=battery.split,
        sorties=per_sortie,
    )
