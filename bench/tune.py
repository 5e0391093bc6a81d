"""Fair tuning: every controller family tuned over both loops by the same optimiser with the same flight budget.

    .venv/bin/python -m bench.tune                          # all families, resumable: bench/results/tune/
    .venv/bin/python -m bench.tune --write                  # ... and ship the winners (adrc_offboard/gains/)
    .venv/bin/python -m bench.tune --address auto           # the flights on a Ray cluster (docs/campaigns.md)

Method:
1. What is tuned: each family's design numbers (adrc_offboard.design: attitude bandwidth as a share of what the
   motors allow, yaw ratio, cascade separation, vertical ratio, and the family's own: observer ratios for the ADRC,
   the TD's bound for the paper-literal ADRC, integrator and rate-loop ratios for the PID). Every gain of both
   loops follows from them and the airframe, so the search covers the outer and the inner loop together.
2. The flight: `bench.control.scenario.short_scenario`, the reference route's longest leg and the next (the turn
   between them, the 4 m/s gust halfway along the first, 5 m/s crosswind, Dryden turbulence, D terms, sensor
   noise), flown in the in-process lockstep harness, each flight a task on Ray (bench.campaign).
3. The optimiser: Optuna's TPE (multivariate, seeded), the same number of trials for every family (--trials), each
   trial flown on the same training seeds (--train-seeds); trials are asked in batches (--batch) with the
   constant liar so parallel trials spread out. Each family's first trial is its shipped design (a warm start, the
   same for every family: the tuning can only keep or beat what shipped), then 11 random trials, then TPE.
4. Constraints, the same for all: the flight completes on every seed, its largest error stays under
   MAX_ERROR_M (no divergence), the mixer clips in at most MAX_SATURATED of the tracking ticks, the thrust command's
   tick-to-tick RMS change stays under MAX_THRUST_STEP (no chatter). A trial that breaks one scores PENALTY plus its
   error; a design that cannot be built (an unstable discrete ESO) scores PENALTY * 2.
5. Choice and report: each family's best admissible trial, flown again on held-out seeds (--holdout-seeds) with the
   previously shipped design beside it; its position inside the search space (log scale, 0 = lower bound, 1 =
   upper): a value within BOUND_MARGIN of a bound is reported as on the bound, unless the bound is physical
   (SPACE's note says why), and the command exits 3 so the space gets widened.

Results: bench/results/tune/studies.db (Optuna, one study per family: every trial's parameters and value),
bench/results/tune/flights.jsonl (every flight's metrics, by trial and seed), bench/results/tune.json (summary).
Interrupted, the command resumes: finished flights are not flown again, and a trial left running is completed from
its stored flights.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from adrc_offboard.adrc import AdrcParameterError
from adrc_offboard.design import DESIGN_PARAMETERS, Design, describe, gains_files, load_designs
from bench.campaign import load_store, run_tasks
from bench.control import RESULTS
from bench.control.flight import fly
from bench.control.scenario import short_reference_scenario
from uavcore.airframe import Airframe

FAMILIES = ("adrc", "adrc_paper", "pid", "geometric")
MAX_ERROR_M = 10.0
MAX_SATURATED = 0.15
MAX_THRUST_STEP = 0.05
PENALTY = 100.0
BOUND_MARGIN = 0.03
OUT_DIR = RESULTS / "tune"
GAINS_DIR = Path(__file__).resolve().parents[1] / "adrc_offboard" / "gains"

# name -> (low, high, why the bounds are where they are); every parameter is searched on a log scale
SPACE: dict[str, tuple[float, float, str]] = {
    "attitude_bandwidth": (0.25, 2.5, "x 1/(4 tau): 2.5 puts the attitude loop at 1.6 times the motors' corner"),
    "yaw_ratio": (0.08, 1.5, "yaw bandwidth / attitude bandwidth"),
    "separation": (1.5, 25.0, "attitude bandwidth / horizontal position bandwidth"),
    "vertical_ratio": (0.4, 4.0, "vertical / horizontal position bandwidth"),
    "observer_ratio": (1.2, 20.0, "outer ESO bandwidth / loop bandwidth"),
    "attitude_observer_ratio": (1.2, 20.0, "inner ESO bandwidth / loop bandwidth"),
    "td_ratio": (0.05, 5.0, "outer TD acceleration bound / envelope acceleration"),
    "integral_ratio": (0.01, 3.0, "PID integrator pole / bandwidth"),
    "rate_ratio": (1.2, 15.0, "PID rate-loop bandwidth / attitude P"),
    "rate_integral": (0.003, 1.0, "rate I / (P w_r)"),
    "rate_derivative": (0.005, 2.0, "rate D w_r / P"),
    "attitude_damping": (0.3, 3.0, "geometric attitude damping ratio"),
}
PHYSICAL_BOUNDS: dict[tuple[str, str], str] = {}  # (parameter, "low"|"high") -> why a best point there is accepted


def flight_task(family: str, design: dict[str, float], seed: int) -> dict[str, Any]:
    """One tuning flight (a Ray task): the short scenario at `design`, seed `seed`; the metrics the score needs."""
    scenario = short_reference_scenario()
    try:
        built = Design(family, design)
        metrics, _ = fly(family, seed, scenario, design=built, items=scenario.items)
    except AdrcParameterError as exc:
        return {"buildable": False, "reason": str(exc)[:200]}
    keep = ("rms_error_m", "max_error_m", "gust_peak_m", "saturated_fraction", "thrust_step_rms", "completed")
    return {"buildable": True} | {k: _finite(metrics[k]) for k in keep}


def _finite(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return bool(value) if isinstance(value, bool | np.bool_) else value


def score(flights: list[dict]) -> dict[str, Any]:
    """A trial's value from its flights (module docstring, 4): mean RMS error, or a penalty naming what broke."""
    if not all(f.get("buildable", False) for f in flights):
        reasons = [f.get("reason") or f.get("error") or "failed" for f in flights if not f.get("buildable")]
        return {"value": 2 * PENALTY, "admissible": False, "reason": reasons[0]}
    rms = [f["rms_error_m"] for f in flights]
    mean = {
        k: float(np.mean([f[k] if f[k] is not None else math.inf for f in flights]))
        for k in ("rms_error_m", "max_error_m", "gust_peak_m", "saturated_fraction", "thrust_step_rms")
    }
    reasons = []
    if not all(f["completed"] for f in flights):
        reasons.append("did not complete")
    if not all(f["max_error_m"] is not None and f["max_error_m"] < MAX_ERROR_M for f in flights):
        reasons.append(f"error over {MAX_ERROR_M:g} m")
    if mean["saturated_fraction"] > MAX_SATURATED:
        reasons.append(f"saturated {mean['saturated_fraction']:.2f}")
    if mean["thrust_step_rms"] > MAX_THRUST_STEP:
        reasons.append(f"thrust chatter {mean['thrust_step_rms']:.3f}")
    value = mean["rms_error_m"] if all(r is not None for r in rms) else math.inf
    admissible = not reasons and math.isfinite(value)
    if not admissible:
        value = PENALTY + min(value, PENALTY)
    return {"value": value, "admissible": admissible, "reason": "; ".join(reasons)} | mean


def space_position(name: str, value: float) -> float:
    """Where `value` sits in SPACE[name] on the log scale: 0 at the lower bound, 1 at the upper."""
    low, high, _ = SPACE[name]
    return (math.log(value) - math.log(low)) / (math.log(high) - math.log(low))


def bound_check(design: dict[str, float]) -> dict[str, Any]:
    """Each parameter's position in the space; those within BOUND_MARGIN of a bound that is not physical."""
    positions = {name: space_position(name, value) for name, value in design.items()}
    on_bound = {}
    for name, x in positions.items():
        side = "low" if x < BOUND_MARGIN else "high" if x > 1 - BOUND_MARGIN else None
        if side is not None and (name, side) not in PHYSICAL_BOUNDS:
            on_bound[name] = side
    return {"positions": positions, "on_bound": on_bound, "bracketed": not on_bound}


class FamilyStudy:
    """One family's Optuna study, its trials' flights in the shared store."""

    def __init__(self, family: str, storage: str, seed: int) -> None:
        import optuna

        self.family = family
        sampler = optuna.samplers.TPESampler(seed=seed, multivariate=True, constant_liar=True, n_startup_trials=12)
        self.study = optuna.create_study(
            study_name=family, storage=storage, direction="minimize", sampler=sampler, load_if_exists=True
        )
        self.start = load_designs()[family].values  # the shipped design: every family's first trial
        if not self.study.trials:
            self.study.enqueue_trial(self.start)

    def ask(self) -> Any:
        trial = self.study.ask()
        for name in DESIGN_PARAMETERS[self.family]:
            low, high, _ = SPACE[name]
            trial.suggest_float(name, low, high, log=True)
        return trial

    def record(self, number: int, value: float) -> None:
        """A trial's value (a trial asked now or left running earlier: Optuna's tell takes either by number). What
        the value is made of is not stored in the study: summarise_study scores the trial's flights again."""
        self.study.tell(number, value)

    def running(self) -> list[Any]:
        import optuna

        return self.study.get_trials(deepcopy=False, states=(optuna.trial.TrialState.RUNNING,))

    def finished(self) -> int:
        import optuna

        return len(self.study.get_trials(deepcopy=False, states=(optuna.trial.TrialState.COMPLETE,)))


def _key(family: str, number: int, seed: int) -> str:
    return f"{family}/trial{number}/seed{seed}"


def tune(args: argparse.Namespace) -> dict[str, Any]:
    import optuna

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    args.out_dir.mkdir(parents=True, exist_ok=True)
    storage = f"sqlite:///{args.out_dir / 'studies.db'}"
    store = args.out_dir / "flights.jsonl"
    studies = {family: FamilyStudy(family, storage, args.sampler_seed) for family in args.families}
    run = {"workers": args.workers, "address": args.address, "progress": not args.quiet}
    # Round-robin over the families, one batch each, so an interruption leaves them with equal budgets spent.
    while True:
        batch: list[tuple[FamilyStudy, Any]] = []
        for study in studies.values():
            pending = list(study.running())  # left running by an interrupted run: finished from the store first
            want = min(args.batch, args.trials - study.finished() - len(pending))
            batch += [(study, trial) for trial in pending]
            batch += [(study, study.ask()) for _ in range(max(0, want))]
        if not batch:
            break
        tasks = [
            (_key(s.family, t.number, seed), {"family": s.family, "design": dict(t.params), "seed": seed})
            for s, t in batch
            for seed in args.train_seeds
        ]
        flights = run_tasks(flight_task, tasks, store, desc="tuning flights", **run)
        for s, t in batch:
            s.record(t.number, score([flights[_key(s.family, t.number, seed)] for seed in args.train_seeds])["value"])
        done = {f: s.finished() for f, s in studies.items()}
        print(f"  trials finished: {done}", flush=True)
    flights = load_store(store)
    return {family: summarise_study(s, flights, args.train_seeds) for family, s in studies.items()}


def summarise_study(study: FamilyStudy, flights: dict[str, dict], train_seeds: list[int]) -> dict[str, Any]:
    """Each completed trial's design and score (from its flights in the store, the same `score` its value came
    from), the admissible ones counted and the best of them."""
    import optuna

    trials = study.study.get_trials(deepcopy=False, states=(optuna.trial.TrialState.COMPLETE,))
    rows = [
        {"number": t.number, "params": t.params}
        | score([flights[_key(study.family, t.number, seed)] for seed in train_seeds])
        for t in trials
    ]
    admissible = [r for r in rows if r.get("admissible")]
    best = min(admissible, key=lambda r: r["value"]) if admissible else None
    return {"start": study.start, "trials": rows, "admissible": len(admissible), "best": best}


def holdout(args: argparse.Namespace, chosen: dict[str, dict[str, float]]) -> dict[str, Any]:
    """The chosen designs and the shipped ones (the reference a tuning must beat) flown on the held-out seeds."""
    shipped = {family: design.values for family, design in load_designs().items() if family in args.families}
    arms = [(f, "shipped", shipped[f]) for f in args.families] + [(f, "tuned", d) for f, d in chosen.items()]

    def key(family: str, which: str, design: dict[str, float], seed: int) -> str:
        return f"holdout/{family}/{which}/{_design_key(design)}/seed{seed}"

    tasks = [
        (key(f, which, d, seed), {"family": f, "design": d, "seed": seed})
        for f, which, d in arms
        for seed in args.holdout_seeds
    ]
    run = {"workers": args.workers, "address": args.address, "progress": not args.quiet}
    flights = run_tasks(flight_task, tasks, args.out_dir / "flights.jsonl", desc="held-out flights", **run)
    out: dict[str, Any] = {f: {} for f in args.families}
    for f, which, d in arms:
        per_seed = [flights[key(f, which, d, seed)] for seed in args.holdout_seeds]
        out[f][which] = score(per_seed) | {"rms_per_seed": [x.get("rms_error_m") for x in per_seed], "design": d}
    return out


def _design_key(design: dict[str, float]) -> str:
    return ",".join(f"{k}={design[k]:.6g}" for k in sorted(design))


def write_designs(result: dict[str, Any], path: Path) -> None:
    """Ship the chosen designs: design.json's families get the tuned numbers and their provenance."""
    data = json.loads(path.read_text())
    for family, chosen in result["chosen"].items():
        best = result["families"][family]["best"]
        held = result["holdout"][family]["tuned"]
        data["families"][family] = {
            "design": {k: round(v, 6) for k, v in chosen.items()},
            "provenance": (
                f"python -m bench.tune: trial {best['number']} of {len(result['families'][family]['trials'])}, "
                f"training RMS {best['value']:.4f} m (seeds {result['train_seeds']}), held-out RMS "
                f"{held['rms_error_m']:.4f} m (seeds {result['holdout_seeds']}); bench/results/tune.json"
            ),
        }
    path.write_text(json.dumps(data, indent=1) + "\n")


def write_gains_files() -> list[Path]:
    """The gains files regenerated from design.json for Table 2 (adrc_offboard.design.gains_files)."""
    written = []
    for name, data in gains_files(Airframe.table2(), load_designs()).items():
        path = GAINS_DIR / name
        path.write_text(json.dumps(data, indent=1) + "\n")
        written.append(path)
    return written


def _seeds(text: str) -> list[int]:
    if "-" in text and "," not in text:
        first, last = (int(x) for x in text.split("-"))
        return list(range(first, last + 1))
    return [int(x) for x in text.split(",")]


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m bench.tune", description=__doc__.split("\n")[0])
    p.add_argument("--families", default=",".join(FAMILIES), help=f"comma-separated, from {', '.join(FAMILIES)}")
    p.add_argument("--trials", type=int, default=80, help="trials per family (the same budget for every family)")
    p.add_argument("--batch", type=int, default=4, help="trials per family asked at once (flown in parallel)")
    p.add_argument("--train-seeds", type=_seeds, default=[0, 1, 2], help="e.g. 0,1,2 or 0-2")
    p.add_argument("--holdout-seeds", type=_seeds, default=list(range(100, 110)), help="e.g. 100-109")
    p.add_argument("--sampler-seed", type=int, default=0)
    p.add_argument("--workers", choices=("ray", "serial"), default="ray")
    p.add_argument("--address", help="a Ray cluster (auto, or ray://HEAD:10001); default: a local Ray")
    p.add_argument("--out-dir", type=Path, default=OUT_DIR, help="studies.db and flights.jsonl (resumable)")
    p.add_argument("--out", type=Path, default=RESULTS / "tune.json")
    p.add_argument("--write", action="store_true", help="ship the chosen designs (adrc_offboard/gains/design.json)")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    p.add_argument(
        "--regenerate", action="store_true", help="only rewrite the gains files from design.json (no campaign)"
    )
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    args.families = args.families.split(",")
    if any(f not in FAMILIES for f in args.families) or len(set(args.families)) < len(args.families):
        print(f"bench.tune: error: --families: each once, from {', '.join(FAMILIES)}", file=sys.stderr)
        return 2
    if args.trials < 1 or args.batch < 1 or not args.train_seeds or not args.holdout_seeds:
        print("bench.tune: error: --trials and --batch must be >= 1, and the seed lists non-empty", file=sys.stderr)
        return 2
    if set(args.train_seeds) & set(args.holdout_seeds):
        print("bench.tune: error: the held-out seeds must differ from the training seeds", file=sys.stderr)
        return 2
    if args.regenerate:
        for path in write_gains_files():
            print(f"wrote {path}")
        return 0
    started = time.perf_counter()
    families = tune(args)
    chosen = {f: s["best"]["params"] for f, s in families.items() if s["best"] is not None}
    if len(chosen) < len(families):
        missing = sorted(set(families) - set(chosen))
        print(f"bench.tune: no admissible trial for {', '.join(missing)}", file=sys.stderr)
    held = holdout(args, chosen)
    checks = {family: bound_check(design) for family, design in chosen.items()}
    airframe = Airframe.table2()
    result = {
        "command": "python -m bench.tune " + " ".join(argv if argv is not None else sys.argv[1:]),
        "elapsed_s": time.perf_counter() - started,
        "method": __doc__,
        "space": {k: {"low": v[0], "high": v[1], "meaning": v[2]} for k, v in SPACE.items()},
        "physical_bounds": {f"{k[0]}.{k[1]}": v for k, v in PHYSICAL_BOUNDS.items()},
        "constraints": {"max_error_m": MAX_ERROR_M, "max_saturated": MAX_SATURATED, "max_thrust_step": MAX_THRUST_STEP},
        "trials_per_family": args.trials,
        "train_seeds": args.train_seeds,
        "holdout_seeds": args.holdout_seeds,
        "families": families,
        "chosen": chosen,
        "chosen_described": {f: describe(airframe, Design(f, d)) for f, d in chosen.items()},
        "holdout": held,
        "bound_check": checks,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=1, default=float))
    print_summary(result)
    if args.write:
        write_designs(result, GAINS_DIR / "design.json")
        written = write_gains_files()
        print("wrote adrc_offboard/gains/design.json and " + ", ".join(p.name for p in written))
    print(f"wrote {args.out} ({result['elapsed_s']:.0f} s)")
    return 3 if any(not c["bracketed"] for c in checks.values()) else 0


def print_summary(result: dict[str, Any]) -> None:
    print(f"\n{'family':12}{'trials':>7}{'ok':>5}{'train rms':>11}{'held-out':>10}{'shipped':>10}  bound check")
    for family, s in result["families"].items():
        best, held = s["best"], result["holdout"].get(family)
        check = result["bound_check"].get(family)
        tuned = f"{held['tuned']['rms_error_m']:.4f}" if "tuned" in held else "-"
        shipped = f"{held['shipped']['rms_error_m']:.4f}"
        on = "-" if check is None else ("bracketed" if check["bracketed"] else f"ON BOUND {check['on_bound']}")
        train = f"{best['value']:.4f}" if best else "-"
        print(f"{family:12}{len(s['trials']):>7}{s['admissible']:>5}{train:>11}{tuned:>10}{shipped:>10}  {on}")
    for family, design in result["chosen"].items():
        print(f"  {family}: " + ", ".join(f"{k} {v:.3g}" for k, v in design.items()))


if __name__ == "__main__":
    sys.exit(main())
