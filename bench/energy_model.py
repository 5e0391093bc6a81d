"""Calibrate the route energy model (planner.energy) against simulated flights and validate it on others.

    .venv/bin/python -m bench.energy_model            # fit, validate; writes planner/energy_params.json,
                                                      # bench/results/energy_model.json and .png
    .venv/bin/python -m bench.energy_model --quick    # fewer, shorter flights (development); writes *_quick
    .venv/bin/python -m bench.energy_model --validate-only   # the committed parameters on the held-out set

Flights: the whole stack in one process and in simulated time (sitl_quad.lockstep_harness): the vehicle with
the ADRC attitude loop (MC_ATT_CTRL = 1) under the ADRC offboard outer loop, as users fly it. Each flight is a
mission the ground station would upload (gcs.domain.planning: the planner's order, take-off, DO_CHANGE_SPEED, one
waypoint per buoy with its dwell, RTL) over 5-15 buoys uniform in the paper's 1200 m x 700 m harbour area, at a
commanded speed of 5-12 m/s, 5-15 m altitude, 1-10 s dwell, in a mean wind of 0-8 m/s with Dryden turbulence
of W20 = the wind speed (the forecast's reading) and the paper's D terms. The battery (sitl_quad.battery)
counts the energy from the start command to the disarm after landing, per mission item (take-off, each buoy's
turn + leg + dwell, the return and landing).

Training and held-out sets differ in everything random: buoy sets and turbulence seeds (different seeds),
wind directions (training: from 0/90/180/270 deg +- 20 deg; held-out: from 45/135/225/315 deg +- 20 deg),
speeds, winds, altitudes and dwells drawn independently. The fit (scipy least_squares) minimises the per-item
energy errors of the training flights over the model's free terms (planner.energy.FittedTerms); the held-out
flights are then predicted from their route, flight parameters and forecast alone, and their total energy
compared with what the battery counted: mean and worst absolute error in % of the energy used (targets:
mean <= 5 %, worst <= 10 %). A few held-out flights are flown again with the PID cascades (PID offboard +
PID attitude; the built-in PX4-like cascade) to show how much their energy differs from the ADRC's.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np

from bench.control.flight import make_controller
from bench.control.scenario import OUTER_RATE_HZ, wind_config
from gcs.domain.planning import FIRST_BUOY_SEQ, FlightParams, make_plan, mission_items
from planner.energy import (
    PARAMS_PATH,
    EnergyModel,
    RouteFlight,
    VehicleTerms,
    WindForecast,
    route_energy,
    turn_angles_deg,
)
from planner.scenario import DISTURBANCE_VARIANCE, Weather, random_area_points
from sitl_quad.attitude_loops import attitude_loops
from sitl_quad.config import AttitudeControllerKind, ControlConfig, VehicleConfig
from sitl_quad.disturbances import DisturbanceConfig
from sitl_quad.lockstep_harness import LockstepHarness
from sitl_quad.vehicle import Vehicle
from uavcore.geodesy import DEFAULT_HOME, LocalFrame

REPO = Path(__file__).resolve().parents[1]
RESULTS = REPO / "bench" / "results"
ACCEPTANCE_RADIUS_M = 2.0
TARGET_MEAN_PCT = 5.0
TARGET_WORST_PCT = 10.0


@dataclass(frozen=True)
class FlightCase:
    """One simulated mission: its buoys (from the seed), how it is flown, and the air."""

    name: str
    seed: int
    n_buoys: int
    speed_m_s: float
    altitude_m: float
    dwell_s: float
    wind_m_s: float
    wind_from_deg: float
    controller: str = "adrc"

    @property
    def flight(self) -> RouteFlight:
        return RouteFlight(self.altitude_m, self.speed_m_s, self.dwell_s)

    @property
    def forecast(self) -> WindForecast:
        return WindForecast(self.wind_m_s, self.wind_from_deg)

    def route_en(self) -> np.ndarray:
        """The depot then the buoys in the planner's order, [east, north] m (what the mission flies)."""
        return self._plan()[1]

    def _plan(self):
        rng = np.random.default_rng(self.seed)
        local = random_area_points(self.n_buoys, rng)
        frame = LocalFrame(*DEFAULT_HOME)
        lat_lon = frame.unproject(local)
        plan = make_plan(
            DEFAULT_HOME[:2], [tuple(p) for p in lat_lon.tolist()], [f"b{i}" for i in range(self.n_buoys)], "auto"
        )
        route = np.vstack([[0.0, 0.0], np.asarray(plan.buoys_local)[plan.order]])
        return plan, route


def draw_cases(prefix: str, count: int, seed: int, directions: tuple[float, ...], max_buoys: int) -> list[FlightCase]:
    """`count` cases with independent draws; buoy sets and air from seeds seed*1000 + k."""
    rng = np.random.default_rng(seed)
    cases = []
    for k in range(count):
        cases.append(
            FlightCase(
                name=f"{prefix}{k:02d}",
                seed=seed * 1000 + k,
                n_buoys=int(rng.integers(5, max_buoys + 1)),
                speed_m_s=round(float(rng.uniform(5.0, 12.0)), 1),
                altitude_m=float(rng.choice([5.0, 10.0, 15.0])),
                dwell_s=round(float(rng.uniform(1.0, 10.0)), 1),
                wind_m_s=round(float(rng.uniform(0.0, 8.0)), 1),
                wind_from_deg=round(float(directions[k % len(directions)] + rng.uniform(-20.0, 20.0)) % 360.0, 1),
            )
        )
    return cases


TRAIN_DIRECTIONS = (0.0, 90.0, 180.0, 270.0)
HELD_OUT_DIRECTIONS = (45.0, 135.0, 225.0, 315.0)


def vehicle_config(case: FlightCase) -> VehicleConfig:
    weather = Weather(wind_m_s=case.wind_m_s, wind_from_deg=case.wind_from_deg, turbulence_w20_m_s=case.wind_m_s)
    inner = AttitudeControllerKind.ADRC if case.controller == "adrc" else AttitudeControllerKind.PID
    return VehicleConfig(
        wind=wind_config(weather),
        disturbance=DisturbanceConfig(*[DISTURBANCE_VARIANCE] * 6),
        control=ControlConfig(attitude_controller=inner),
    )


def fly(case: FlightCase) -> dict:
    """Fly the case in lockstep; the battery's energy (Wh) and the time (s) per mission item, start to disarm."""
    plan, _ = case._plan()
    items = mission_items(
        plan, FlightParams(case.altitude_m, case.speed_m_s, case.dwell_s, ACCEPTANCE_RADIUS_M), DEFAULT_HOME[:2]
    )
    limit = 3.0 * (route_energy(case.route_en(), case.flight, case.forecast, EnergyModel()).time_s + 60.0)
    return fly_items(items, len(plan.order), vehicle_config(case), case.seed, case.controller, limit)


def fly_items(
    items: list,
    n_buoys: int,
    config: VehicleConfig,
    seed: int,
    controller_name: str,
    limit_s: float,
    home: tuple[float, float, float] = DEFAULT_HOME,
) -> dict:
    """Fly a mission (its items, over n_buoys buoys) in lockstep from `home` until the disarm or limit_s of vehicle
    time: the battery's energy (Wh) and the time (s) per mission item, start to disarm (fly's answer)."""
    vehicle = Vehicle(config, home, seed=seed, outer_rate_hz=OUTER_RATE_HZ, attitude_loops=attitude_loops())
    controller = make_controller(controller_name, config) if controller_name != "px4" else None
    harness = LockstepHarness(vehicle, controller, outer_rate_hz=OUTER_RATE_HZ)
    harness.upload_mission(items)
    harness.arm()
    for _ in range(25):
        harness.step()
    harness.start_mission()
    per_item: dict[int, list[float]] = {}
    started_wall, t0 = time.perf_counter(), vehicle.t
    last_wh = vehicle.battery.consumed_wh
    while vehicle.armed and vehicle.t - t0 < limit_s:
        harness.tick()
        item = _model_item(vehicle.navigator.current_seq, n_buoys)
        spent = per_item.setdefault(item, [0.0, 0.0])
        spent[0] += vehicle.outer_dt
        spent[1] += vehicle.battery.consumed_wh - last_wh
        last_wh = vehicle.battery.consumed_wh
        harness.exchange()
    completed = not vehicle.armed and vehicle.navigator.mission_state == "complete"
    return {
        "energy_wh": sum(e for _, e in per_item.values()),
        "time_s": vehicle.t - t0,
        "per_item": {str(k): v for k, v in sorted(per_item.items())},
        "completed": completed,
        "wall_s": time.perf_counter() - started_wall,
    }


def _model_item(seq: int, n_buoys: int) -> int:
    """The energy model's item of a mission sequence number: 0 take-off, 1..n buoys, -1 the return."""
    if seq < FIRST_BUOY_SEQ:
        return 0
    if seq < FIRST_BUOY_SEQ + n_buoys:
        return seq - FIRST_BUOY_SEQ + 1
    return -1


# ----- the fit
FREE_TERMS = ("rotor_hover_w", "drag_scale", "turbulence_w_per_m2s2", "item_overhead_s", "landing_overhead_s")
LOWER = (50.0, 0.2, 0.0, 0.0, -1.0)
UPPER = (400.0, 5.0, 50.0, 5.0, 5.0)


def item_residuals(model: EnergyModel, case: FlightCase, measured: dict, hover_w: float) -> list[float]:
    """Per mission item: predicted - measured energy (Wh), and the time error priced at hover power (Wh)."""
    predicted = route_energy(case.route_en(), case.flight, case.forecast, model).by_item()
    out = []
    for item, (time_s, energy_wh) in measured["per_item"].items():
        p_time, p_energy = predicted[int(item)]
        out += [p_energy - energy_wh, (p_time - time_s) * hover_w / 3600.0]
    return out


def fit(prior: EnergyModel, flights: list[tuple[FlightCase, dict]]) -> tuple[EnergyModel, dict]:
    """Least squares over FREE_TERMS on every training item's energy and duration."""
    from scipy.optimize import least_squares

    turns = [turn for case, _ in flights for turn in turn_angles_deg(case.route_en())]
    prior = prior.with_fitted(mean_turn_deg=float(np.mean(turns)))
    hover_w = prior.vehicle.avionics_w + prior.fitted.rotor_hover_w

    def residuals(theta: np.ndarray) -> np.ndarray:
        model = prior.with_fitted(**dict(zip(FREE_TERMS, theta.tolist(), strict=True)))
        return np.concatenate([item_residuals(model, case, measured, hover_w) for case, measured in flights])

    x0 = np.array([getattr(prior.fitted, name) for name in FREE_TERMS])
    result = least_squares(residuals, np.clip(x0, LOWER, UPPER), bounds=(LOWER, UPPER), x_scale="jac")
    model = prior.with_fitted(**dict(zip(FREE_TERMS, result.x.tolist(), strict=True)))
    return model, {
        "items": int(result.fun.size // 2),
        "rms_item_residual_wh": float(np.sqrt(np.mean(result.fun[0::2] ** 2))),
        "rms_item_time_residual_s": float(np.sqrt(np.mean(result.fun[1::2] ** 2)) * 3600.0 / hover_w),
        "evaluations": int(result.nfev),
        "mean_turn_deg": float(np.mean(turns)),
    }


# ----- evaluation and report
def evaluate(model: EnergyModel, flights: list[tuple[FlightCase, dict]]) -> list[dict]:
    rows = []
    for case, measured in flights:
        predicted = route_energy(case.route_en(), case.flight, case.forecast, model)
        error_pct = 100.0 * (predicted.energy_wh - measured["energy_wh"]) / measured["energy_wh"]
        rows.append(
            {
                **asdict(case),
                "measured_wh": measured["energy_wh"],
                "predicted_wh": predicted.energy_wh,
                "error_pct": error_pct,
                "measured_s": measured["time_s"],
                "predicted_s": predicted.time_s,
                "completed": measured["completed"],
                "wall_s": measured["wall_s"],
            }
        )
    return rows


def summary(rows: list[dict]) -> dict:
    errors = np.abs([r["error_pct"] for r in rows])
    return {
        "flights": len(rows),
        "mean_abs_error_pct": float(errors.mean()),
        "worst_abs_error_pct": float(errors.max()),
        "mean_signed_error_pct": float(np.mean([r["error_pct"] for r in rows])),
    }


def table(title: str, rows: list[dict]) -> str:
    lines = [
        title,
        f"{'flight':<7}{'buoys':>6}{'V m/s':>7}{'alt m':>6}{'dwell':>6}{'wind':>6}{'from':>6}"
        f"{'time s':>8}{'measured Wh':>12}{'predicted':>10}{'error %':>8}",
    ]
    for r in rows:
        lines.append(
            f"{r['name']:<7}{r['n_buoys']:>6}{r['speed_m_s']:>7.1f}{r['altitude_m']:>6.0f}{r['dwell_s']:>6.1f}"
            f"{r['wind_m_s']:>6.1f}{r['wind_from_deg']:>6.0f}{r['measured_s']:>8.0f}{r['measured_wh']:>12.2f}"
            f"{r['predicted_wh']:>10.2f}{r['error_pct']:>+8.1f}"
        )
    s = summary(rows)
    lines.append(
        f"mean |error| {s['mean_abs_error_pct']:.2f} %, worst {s['worst_abs_error_pct']:.2f} %, "
        f"mean signed {s['mean_signed_error_pct']:+.2f} % over {s['flights']} flights"
    )
    return "\n".join(lines)


def draw(train: list[dict], held_out: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (scatter, errors) = plt.subplots(1, 2, figsize=(12, 5.2))
    values = [v for r in train + held_out for v in (r["measured_wh"], r["predicted_wh"])]
    bottom, top = 0.9 * min(values), 1.05 * max(values)
    line = np.array([bottom, top])
    scatter.fill_between(line, 0.9 * line, 1.1 * line, color="0.92", label="+-10 %")
    scatter.fill_between(line, 0.95 * line, 1.05 * line, color="0.82", label="+-5 %")
    scatter.plot(line, line, "k-", lw=0.8)
    for rows, marker, label in ((train, "o", "training"), (held_out, "s", "held-out")):
        scatter.scatter(
            [r["measured_wh"] for r in rows], [r["predicted_wh"] for r in rows], marker=marker, label=label, alpha=0.8
        )
    scatter.set(
        xlim=(bottom, top), ylim=(bottom, top), xlabel="measured (simulated battery), Wh", ylabel="predicted, Wh"
    )
    scatter.set_title("Route energy: predicted vs measured (start to disarm)")
    scatter.legend(loc="upper left")
    for rows, marker, label in ((train, "o", "training"), (held_out, "s", "held-out")):
        errors.scatter(
            [r["wind_m_s"] for r in rows], [r["error_pct"] for r in rows], marker=marker, label=label, alpha=0.8
        )
    for level in (-10, -5, 5, 10):
        errors.axhline(level, color="0.6", lw=0.8, ls="--" if abs(level) == 10 else ":")
    errors.axhline(0.0, color="k", lw=0.8)
    errors.set(xlabel="mean wind, m/s", ylabel="prediction error, % of measured", title="Error against the wind")
    errors.legend(loc="upper left")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def fly_all(cases: list[FlightCase], label: str) -> list[tuple[FlightCase, dict]]:
    out = []
    for case in cases:
        measured = fly(case)
        if not measured["completed"]:
            raise RuntimeError(f"{case} did not complete its mission")
        out.append((case, measured))
        print(
            f"  {label} {case.name}: {measured['energy_wh']:.2f} Wh in {measured['time_s']:.0f} s simulated, "
            f"{measured['wall_s']:.1f} s wall",
            flush=True,
        )
    return out


def compare_controllers(cases: list[FlightCase], adrc: dict[str, dict], model: EnergyModel) -> list[dict]:
    """The same held-out missions flown by the PID cascades: their energy against the ADRC's and the model's."""
    rows = []
    for case in cases:
        for controller in ("pid", "px4"):
            other = FlightCase(**{**asdict(case), "controller": controller})
            measured = fly(other)
            predicted = route_energy(case.route_en(), case.flight, case.forecast, model).energy_wh
            rows.append(
                {
                    "flight": case.name,
                    "controller": controller,
                    "completed": measured["completed"],
                    "energy_wh": measured["energy_wh"],
                    "adrc_wh": adrc[case.name]["energy_wh"],
                    "vs_adrc_pct": 100.0 * (measured["energy_wh"] / adrc[case.name]["energy_wh"] - 1.0),
                    "model_error_pct": 100.0 * (predicted / measured["energy_wh"] - 1.0),
                }
            )
            r = rows[-1]
            print(
                f"  {case.name} {controller}: {r['energy_wh']:.2f} Wh, {r['vs_adrc_pct']:+.1f} % vs ADRC, "
                f"model {r['model_error_pct']:+.1f} %",
                flush=True,
            )
    return rows


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(prog="python -m bench.energy_model", description=__doc__.split("\n\n")[0])
    p.add_argument(
        "--quick",
        action="store_true",
        help="4 + 4 flights of at most 6 buoys, 1 re-flown by the PIDs; writes *_quick results, not the parameters",
    )
    p.add_argument(
        "--validate-only", action="store_true", help="no fit: the committed planner/energy_params.json on held-out"
    )
    p.add_argument("--train", type=int, default=16, help="training flights (default 16)")
    p.add_argument("--held-out", type=int, default=16, help="held-out flights (default 16)")
    p.add_argument("--controllers", type=int, default=3, help="held-out flights re-flown by the PID cascades")
    return p.parse_args(argv)


def vehicle_terms(config: VehicleConfig) -> VehicleTerms:
    """The energy model's physical terms of a simulated vehicle."""
    return VehicleTerms.from_airframe(config.airframe, avionics_w=config.battery.avionics_w)


def fitted_for(config: VehicleConfig, train: list[tuple[FlightCase, dict]], fit_info: dict) -> dict:
    """What the parameters stand for: the pack, the controller, the flights they were fitted on."""
    return {
        "fitted_by": "python -m bench.energy_model",
        "controller": "adrc: ADRC offboard outer loop + ADRC attitude loop (MC_ATT_CTRL = 1), lockstep",
        "battery": asdict(config.battery),
        "navigator": asdict(config.navigator),
        "air": "mean wind + Dryden turbulence W20 = wind speed + D terms of variance "
        f"{DISTURBANCE_VARIANCE} (the paper's weather without its gust)",
        "training_flights": [case.name for case, _ in train],
        **fit_info,
    }


def main(argv: list[str] | None = None) -> None:
    args = parse_args(argv)
    started = time.perf_counter()
    n_train, n_held, max_buoys = (4, 4, 6) if args.quick else (args.train, args.held_out, 15)
    n_controllers = min(args.controllers, 1) if args.quick else args.controllers
    suffix = "_quick" if args.quick else ""
    config = vehicle_config(draw_cases("t", 1, 1, TRAIN_DIRECTIONS, max_buoys)[0])
    train_cases = draw_cases("t", n_train, 1, TRAIN_DIRECTIONS, max_buoys)
    held_cases = draw_cases("h", n_held, 2, HELD_OUT_DIRECTIONS, max_buoys)
    prior = EnergyModel(vehicle=vehicle_terms(config))
    train: list[tuple[FlightCase, dict]] = []
    if args.validate_only:
        model = EnergyModel.load()
        fit_info = {}
    else:
        print(f"training: {n_train} flights", flush=True)
        train = fly_all(train_cases, "train")
        model, fit_info = fit(prior, train)
        model = replace(model, fitted_for=fitted_for(config, train, fit_info))
    problems = model.mismatches(vehicle_terms(config))
    if problems:
        print("warning: the parameters were fitted for another vehicle: " + "; ".join(problems))
    print(f"held-out: {n_held} flights", flush=True)
    held = fly_all(held_cases, "held-out")
    train_rows, held_rows = evaluate(model, train), evaluate(model, held)
    prior_rows = evaluate(prior.with_fitted(mean_turn_deg=model.fitted.mean_turn_deg), held)
    controllers = compare_controllers(held_cases[:n_controllers], {c.name: m for c, m in held}, model)
    print()
    if train_rows:
        print(table("TRAINING (fitted on these)", train_rows))
        print()
    print(table("HELD-OUT (different seeds, wind directions, buoy sets)", held_rows))
    held_summary = summary(held_rows)
    print(
        f"\ntargets on held-out: mean {held_summary['mean_abs_error_pct']:.2f} % (<= {TARGET_MEAN_PCT:g} %), "
        f"worst {held_summary['worst_abs_error_pct']:.2f} % (<= {TARGET_WORST_PCT:g} %); "
        f"physics prior before the fit: mean {summary(prior_rows)['mean_abs_error_pct']:.2f} %, "
        f"worst {summary(prior_rows)['worst_abs_error_pct']:.2f} %"
    )
    print("fitted: " + ", ".join(f"{k} {v:.4g}" for k, v in asdict(model.fitted).items()))
    RESULTS.mkdir(parents=True, exist_ok=True)
    if not args.validate_only and not args.quick:
        PARAMS_PATH.write_text(json.dumps(model.to_dict(), indent=2) + "\n")
        print(f"wrote {PARAMS_PATH.relative_to(REPO)}")
    result = {
        "what": "route energy model (planner.energy) fitted on simulated ADRC flights, validated on held-out ones",
        "targets": {"mean_abs_error_pct": TARGET_MEAN_PCT, "worst_abs_error_pct": TARGET_WORST_PCT},
        "held_out": held_summary,
        "training": summary(train_rows) if train_rows else None,
        "physics_prior_held_out": summary(prior_rows),
        "fitted": asdict(model.fitted),
        "fit": fit_info,
        "controllers": controllers,
        "held_out_flights": held_rows,
        "training_flights": train_rows,
        "cores": os.cpu_count(),
        "wall_s": time.perf_counter() - started,
    }
    json_path = RESULTS / f"energy_model{suffix}.json"
    json_path.write_text(json.dumps(result, indent=2) + "\n")
    figure = RESULTS / f"energy_model{suffix}.png"
    draw(train_rows, held_rows, figure)
    print(f"wrote {json_path.relative_to(REPO)}, {figure.relative_to(REPO)} ({result['wall_s']:.0f} s)")


if __name__ == "__main__":
    main()
