"""Energy-planned missions flown through the whole stack: the service's predictions against the battery.

    .venv/bin/python -m bench.energy_missions           # every case; prints a table, writes
                                                        # bench/results/energy_missions.json and .png
    .venv/bin/python -m bench.energy_missions --quick   # one mission (development); writes *_quick

Each mission runs on its own stack of real processes on free loopback ports: the vehicle (`python -m sitl_quad
--lockstep --seed S`, its pack and air set by `--param`), the ADRC outer loop (`python -m adrc_offboard`) and the
service (`python -m gcs serve`, a fresh SQLite file). The mission is posted over HTTP with `battery` options
(reserve and pack: the vehicle's own BAT_LOW_THR and BAT1_*) and the `wind` forecast the vehicle's SIM_WIND_SPD,
SIM_WIND_DIR and SIM_TURB_W20 are set to; the service splits the buoys into sorties that each fit one battery
(gcs.missions.energy_planning) and flies them one after another with a battery swap between them
(gcs.missions.lifecycle).

Cases: (a) the ring: 9 buoys on a 150 m circle round the depot, 5 s inspections, a 500 mAh pack (the energy
test of tests/test_e2e_stack.py); (b) the paper's reference scenario (13 buoys, stack.demo.reference_request with
demo seed 1, 1 s dwell) on a 1200 mAh pack (2 sorties in these winds; 1000 mAh would make 3, 1500 mAh a short
and a full one). Each in calm air, 3 m/s from 250 deg and 6 m/s from 60 deg, on two vehicle seeds. Then the
ring forced into one sortie (battery split = false) with COM_LOW_BAT_ACT = 1: the vehicle's battery failsafe
ends the mission aborted, naming the buoys not inspected.

Per mission, from GET /missions/{id}: per sortie the predicted energy against the energy the vehicle's
BATTERY_STATUS counted (error in % of used), the predicted landing charge against the measured one, the worst
battery warning; the status, the flight time predicted (sum of the sorties') against flown
(gcs.domain.tracking_metrics.flight_time_s, airborne samples, vehicle time) and the wall time from POST to the end.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import httpx
import numpy as np

from bench.failover import poll, rounded
from bench.processes import free_tcp_port, free_udp_port
from stack.demo import reference_request
from stack.options import UpOptions
from stack.supervisor import ChildSpec, Supervisor, SupervisorError, python_module
from uavcore.geodesy import DEFAULT_HOME, LocalFrame

REPO = Path(__file__).resolve().parents[1]
RESULTS = REPO / "bench" / "results"
START_TIMEOUT_S = 120.0  # a loaded 2-core machine takes long to import numpy, numba and FastAPI
MISSION_TIMEOUT_S = 900.0  # a backstop only: lockstep flies as fast as the machine lets it
TERMINAL = {"completed", "failed", "aborted"}
ERROR_REPORT_PCT = 10.0  # a sortie predicted further off than this is kept whole in the results (its mission JSON)
RING_BUOYS, RING_RADIUS_M, RING_DWELL_S, RING_CAPACITY_MAH = 9, 150.0, 5.0, 500.0
REFERENCE_CAPACITY_MAH = 1200.0
SEEDS = (1, 2)


@dataclass(frozen=True)
class Wind:
    """The forecast given in the request and the vehicle's air set to match it (turbulence W20 = the mean wind,
    the forecast's usual reading)."""

    speed_m_s: float
    from_deg: float

    @property
    def label(self) -> str:
        return "calm" if self.speed_m_s == 0 else f"{self.speed_m_s:g} m/s from {self.from_deg:g}"

    def request(self) -> dict[str, float]:
        return {"speed_m_s": self.speed_m_s, "from_deg": self.from_deg, "turbulence_w20_m_s": self.speed_m_s}

    def vehicle_params(self) -> dict[str, float]:
        return {"SIM_WIND_SPD": self.speed_m_s, "SIM_WIND_DIR": self.from_deg, "SIM_TURB_W20": self.speed_m_s}


WINDS = (Wind(0.0, 0.0), Wind(3.0, 250.0), Wind(6.0, 60.0))


@dataclass(frozen=True)
class Case:
    """One mission: which buoys, the pack, the air, the vehicle's seed, split into sorties or not."""

    name: str  # "ring" or "reference"
    capacity_mah: float
    wind: Wind
    seed: int
    split: bool = True

    @property
    def label(self) -> str:
        forced = ", forced single sortie" if not self.split else ""
        return f"{self.name} {self.capacity_mah:g} mAh, {self.wind.label}, seed {self.seed}{forced}"

    def request(self) -> dict[str, Any]:
        """The POST /missions body: the case's buoys and flight, the vehicle's pack and reserve, the forecast."""
        body = reference_request(UpOptions(demo_seed=1))
        if self.name == "ring":
            body = {**body, "buoys": ring_buoys(), "dwell_s": RING_DWELL_S}
        # forced into one sortie: short of charge by design, so the pre-flight check is overridden (and recorded)
        battery = {"reserve_pct": "vehicle", "split": self.split}
        return {**body, "battery": battery, "wind": self.wind.request(), "override": not self.split}

    def vehicle_params(self) -> dict[str, float]:
        # COM_LOW_BAT_ACT = 1: at the critical level the vehicle returns (PX4's "return" battery failsafe)
        return {"BAT1_CAPACITY": self.capacity_mah, "COM_LOW_BAT_ACT": 1, **self.wind.vehicle_params()}


def ring_buoys() -> list[dict[str, float | str]]:
    """RING_BUOYS buoys evenly on a circle of RING_RADIUS_M round the depot (the vehicle's home)."""
    angles = 0.3 + np.arange(RING_BUOYS) * 2.0 * np.pi / RING_BUOYS
    east_north = RING_RADIUS_M * np.column_stack([np.cos(angles), np.sin(angles)])
    lat_lon = LocalFrame(*DEFAULT_HOME).unproject(east_north)
    return [{"id": f"R{i + 1}", "lat": float(lat), "lon": float(lon)} for i, (lat, lon) in enumerate(lat_lon)]


def all_cases(quick: bool) -> tuple[list[Case], Case]:
    """The split missions and the forced single sortie."""
    forced = Case("ring", RING_CAPACITY_MAH, WINDS[1], SEEDS[0], split=False)
    if quick:
        return [Case("ring", RING_CAPACITY_MAH, WINDS[1], SEEDS[0])], forced
    split = [
        Case(name, capacity, wind, seed)
        for name, capacity in (("ring", RING_CAPACITY_MAH), ("reference", REFERENCE_CAPACITY_MAH))
        for wind in WINDS
        for seed in SEEDS
    ]
    return split, forced


# ----- one stack per mission
class MissionStack:
    """Vehicle (lockstep), ADRC offboard and service for one case on free loopback ports; `close()` stops them."""

    def __init__(self, case: Case, logs: Path) -> None:
        vehicle_port = free_udp_port()
        http_port = free_tcp_port()
        self.api = httpx.Client(base_url=f"http://127.0.0.1:{http_port}", timeout=60.0)
        self.logs = logs
        params = [arg for name, value in case.vehicle_params().items() for arg in ("--param", f"{name}={value:g}")]
        vehicle = ["--port", str(vehicle_port), "--lockstep", "--seed", str(case.seed), *params]
        link = f"udpout:127.0.0.1:{vehicle_port}"
        serve = ["serve", "--vehicle", link, "--port", str(http_port), "--db", str(logs / "gcs.sqlite")]
        # the vehicle first (the others talk to its port); the controller and the service start side by side
        self.specs = [
            ChildSpec(
                "vehicle", python_module("sitl_quad", *vehicle), ready=lambda: "listening" in self.log("vehicle")
            ),
            ChildSpec("offboard", python_module("adrc_offboard", "--connect", link)),
            ChildSpec("gcs", python_module("gcs", *serve, "--vehicle-wait", "60")),
        ]
        self.supervisor = Supervisor(self.specs, logs, REPO, say=lambda _: None)

    def start(self) -> MissionStack:
        try:
            self.supervisor.start_all()
            poll(lambda: "outer loop at" in self.log("offboard") or None, bool, START_TIMEOUT_S, "offboard loop")
            poll(self._vehicle, lambda v: v["connected"], START_TIMEOUT_S, "the service hearing the vehicle")
        except (SupervisorError, RuntimeError) as error:  # say why: the logs' ends
            tails = "\n".join(f"--- {spec.name}:\n{self.log(spec.name)[-2000:]}" for spec in self.specs)
            raise RuntimeError(f"{error}\n{tails}") from None
        return self

    def _vehicle(self) -> dict[str, Any] | None:
        try:
            response = self.api.get("/vehicle", timeout=2.0)
        except httpx.HTTPError:
            return None
        return response.json() if response.status_code == 200 else None

    def log(self, name: str) -> str:
        path = self.logs / f"{name}.log"
        return path.read_text(errors="replace") if path.exists() else ""

    def fly(self, request: dict[str, Any]) -> tuple[dict[str, Any], float]:
        """POST the mission and follow it to its end: the final GET /missions/{id} and the wall seconds taken."""
        started = time.monotonic()
        created = self.api.post("/missions", json=request)
        if created.status_code != 201:
            raise RuntimeError(f"POST /missions: {created.status_code} {created.text}")
        mission_id = created.json()["id"]
        while True:
            mission = poll(
                lambda: self.api.get(f"/missions/{mission_id}").json(),
                lambda m: m["status"] in (*TERMINAL, "waiting_for_battery"),
                MISSION_TIMEOUT_S,
                f"mission {mission_id} ending",
                interval_s=0.25,
            )
            if mission["status"] in TERMINAL:
                return mission, time.monotonic() - started
            # between sorties: the crew swaps the pack, and the operator confirms it (the service never does)
            swapped = self.api.post("/vehicle/battery-swap")
            if swapped.status_code != 200:
                raise RuntimeError(f"POST /vehicle/battery-swap: {swapped.status_code} {swapped.text}")
            poll(
                lambda: self.api.get(f"/missions/{mission_id}").json(),
                lambda m: m["status"] != "waiting_for_battery",
                MISSION_TIMEOUT_S,
                f"mission {mission_id} going on after the swap",
                interval_s=0.25,
            )

    def close(self) -> None:
        self.api.close()
        self.supervisor.stop_all()


# ----- figures
def sortie_figures(sortie: dict[str, Any]) -> dict[str, Any]:
    """One sortie's prediction against what the vehicle's battery counted (error in % of the energy used)."""
    predicted, used = sortie["predicted_energy_wh"], sortie["used_energy_wh"]
    return {
        "index": sortie["index"],
        "buoys": len(sortie["order"]),
        "predicted_wh": predicted,
        "used_wh": used,
        "error_pct": 100.0 * (predicted - used) / used if used else None,
        "margin_wh": sortie["margin_wh"],
        "predicted_landing_pct": sortie["predicted_landing_charge_pct"],
        "landing_pct": sortie["landing_charge_pct"],
        "warning": sortie["battery_warning"],
        "predicted_time_s": sortie["predicted_time_s"],
    }


def mission_figures(case: Case, mission: dict[str, Any], wall_s: float) -> dict[str, Any]:
    """A flown mission's figures: its sorties, its end, the flight time predicted and flown."""
    sorties = [sortie_figures(sortie) for sortie in mission["sorties"]]
    energy = mission["energy"] or {}
    flown_s = (mission.get("tracking") or {}).get("flight_time_s")
    predicted_s = sum(s["predicted_time_s"] for s in sorties)
    return {
        "case": case.name,
        "wind": case.wind.label,
        "seed": case.seed,
        "capacity_mah": case.capacity_mah,
        "split": case.split,
        "mission": mission["id"],
        "status": mission["status"],
        "reason": mission["reason"],
        "buoys": len(mission["buoys"]),
        "visited": mission["progress"].get("visited"),
        "not_inspected": [r["id"] for r in mission["buoy_results"] if not r["reached"]],
        "usable_wh": energy.get("usable_wh"),
        "budget_wh": energy.get("budget_wh"),
        "reserve_pct": energy.get("reserve_pct"),
        "pack_source": energy.get("pack_source"),
        "sorties": sorties,
        "predicted_flight_s": predicted_s,
        "flown_flight_s": flown_s,
        "flight_time_error_pct": 100.0 * (predicted_s - flown_s) / flown_s if flown_s else None,
        "wall_s": wall_s,
    }


def needs_a_look(run: dict[str, Any]) -> bool:
    """A split mission that did not complete, or a sortie predicted more than ERROR_REPORT_PCT off."""
    off = any(s["error_pct"] is None or abs(s["error_pct"]) > ERROR_REPORT_PCT for s in run["sorties"])
    return run["split"] and (run["status"] != "completed" or off)


def summary(runs: list[dict[str, Any]]) -> dict[str, Any]:
    """Over every sortie of the split missions: mean and worst absolute energy error, warnings, completions."""
    sorties = [(run, s) for run in runs for s in run["sorties"] if s["error_pct"] is not None]
    errors = [abs(s["error_pct"]) for _, s in sorties]
    worst_run, worst = max(sorties, key=lambda pair: abs(pair[1]["error_pct"])) if sorties else (None, None)
    landing_errors = [
        abs(s["predicted_landing_pct"] - s["landing_pct"]) for _, s in sorties if s["landing_pct"] is not None
    ]
    return {
        "missions": len(runs),
        "completed": sum(run["status"] == "completed" for run in runs),
        "sorties": len(sorties),
        "mean_abs_energy_error_pct": statistics.fmean(errors) if errors else None,
        "worst_abs_energy_error_pct": max(errors) if errors else None,
        "worst_sortie": None
        if worst is None
        else f"{worst_run['case']}, {worst_run['wind']}, seed {worst_run['seed']}, sortie {worst['index'] + 1}",
        "mean_abs_landing_charge_error_pct_points": statistics.fmean(landing_errors) if landing_errors else None,
        "battery_warnings": [
            f"{run['case']}, {run['wind']}, seed {run['seed']}, sortie {s['index'] + 1}: {s['warning']}"
            for run, s in sorties
            if s["warning"] is not None
        ],
    }


# ----- output
def _num(value: float | None, spec: str) -> str:
    return "-" if value is None else format(value, spec)


def print_table(runs: list[dict[str, Any]]) -> None:
    print(
        f"{'case':<10} {'wind':<14} {'seed':>4} {'sortie':>6} {'pred Wh':>8} {'used Wh':>8} {'err %':>6} "
        f"{'land pred %':>11} {'land %':>6} {'warning':<9} {'status':<9} {'flight pred/flown s':>19} {'wall s':>6}"
    )
    for run in runs:
        flight = f"{run['predicted_flight_s']:.0f}/{_num(run['flown_flight_s'], '.0f')}"
        for k, s in enumerate(run["sorties"]):
            head = (run["case"], run["wind"], str(run["seed"])) if k == 0 else ("", "", "")
            tail = (run["status"], flight, f"{run['wall_s']:.0f}") if k == 0 else ("", "", "")
            print(
                f"{head[0]:<10} {head[1]:<14} {head[2]:>4} {s['index'] + 1:>6} {s['predicted_wh']:>8.2f} "
                f"{_num(s['used_wh'], '.2f'):>8} {_num(s['error_pct'], '+.1f'):>6} "
                f"{s['predicted_landing_pct']:>11.1f} {_num(s['landing_pct'], '.1f'):>6} {s['warning'] or '-':<9} "
                f"{tail[0]:<9} {tail[1]:>19} {tail[2]:>6}"
            )


def commit() -> str:
    """HEAD, and whether the working tree differed from it (other work in progress) when the bench ran."""
    head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=REPO, capture_output=True, text=True).stdout.strip()
    status = subprocess.run(["git", "status", "--porcelain"], cwd=REPO, capture_output=True, text=True).stdout
    return f"{head}{' (working tree modified)' if status.strip() else ''}"


def document(runs: list[dict[str, Any]], forced: dict[str, Any], command: str, load: dict, wall_s: float) -> dict:
    """The results file: what ran, where, the summary, every mission, and the missions to look at in full."""
    return {
        "what": "energy-planned multi-sortie missions through the whole stack (lockstep vehicle, ADRC offboard, "
        "gcs serve over HTTP): the service's per-sortie predictions against the vehicle's battery",
        "command": command,
        "commit": commit(),
        "cores": os.cpu_count(),
        "load_average": load,
        "wall_s": wall_s,
        "cases": {
            "ring": f"{RING_BUOYS} buoys on a {RING_RADIUS_M:g} m circle, dwell {RING_DWELL_S:g} s, "
            f"BAT1_CAPACITY {RING_CAPACITY_MAH:g} mAh",
            "reference": "stack.demo.reference_request(UpOptions(demo_seed=1)): 13 buoys, dwell 1 s, "
            f"BAT1_CAPACITY {REFERENCE_CAPACITY_MAH:g} mAh",
            "air": "vehicle SIM_WIND_SPD/SIM_WIND_DIR/SIM_TURB_W20 = the request's wind forecast (W20 = mean wind)",
            "battery_options": "reserve_pct 'vehicle' (BAT_LOW_THR), margin 5 %, objective time",
        },
        "summary": summary(runs),
        "forced_single_sortie": forced,
        "missions": runs,
    }


def draw(runs: list[dict[str, Any]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(figsize=(6.4, 5.6))
    points = [(run, s) for run in runs for s in run["sorties"] if s["used_wh"] is not None]
    values = [v for _, s in points for v in (s["used_wh"], s["predicted_wh"])]
    line = np.array([0.9 * min(values), 1.05 * max(values)])
    axes.fill_between(line, 0.9 * line, 1.1 * line, color="0.92", label="+-10 %")
    axes.fill_between(line, 0.95 * line, 1.05 * line, color="0.82", label="+-5 %")
    axes.plot(line, line, "k-", lw=0.8, label="y = x")
    markers = {"ring": "o", "reference": "s"}
    colours = {wind.label: f"C{i}" for i, wind in enumerate(WINDS)}
    for (case, wind), group in _groups(points).items():
        axes.scatter(
            [s["used_wh"] for s in group],
            [s["predicted_wh"] for s in group],
            marker=markers.get(case, "^"),
            color=colours.get(wind, "k"),
            label=f"{case}, {wind}",
            alpha=0.85,
        )
    axes.set(xlim=tuple(line), ylim=tuple(line), xlabel="used (vehicle BATTERY_STATUS), Wh", ylabel="predicted, Wh")
    axes.set_title("Energy per sortie: the service's prediction vs the battery")
    axes.legend(loc="upper left", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _groups(points: list[tuple[dict, dict]]) -> dict[tuple[str, str], list[dict]]:
    groups: dict[tuple[str, str], list[dict]] = {}
    for run, sortie in points:
        groups.setdefault((run["case"], run["wind"]), []).append(sortie)
    return groups


# ----- the run
def fly_case(case: Case, logs: Path) -> tuple[dict[str, Any], dict[str, Any]]:
    """Start a stack for the case, fly its mission: (figures, the mission JSON)."""
    stack = MissionStack(case, logs)
    try:
        stack.start()
        mission, wall_s = stack.fly(case.request())
    finally:
        stack.close()
    figures = mission_figures(case, mission, wall_s)
    figures["tracebacks"] = [spec.name for spec in stack.specs if "Traceback" in stack.log(spec.name)]
    return figures, mission


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench.energy_missions", description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="one split mission and the forced one (development)")
    parser.add_argument("--logs", type=Path, help="the processes' logs and databases (default: a temporary directory)")
    args = parser.parse_args(argv)
    logs = args.logs or Path(tempfile.mkdtemp(prefix="bench-energy-missions-"))
    started, load_before = time.monotonic(), os.getloadavg()
    split_cases, forced_case = all_cases(args.quick)
    runs, to_look_at = [], []
    for i, case in enumerate([*split_cases, forced_case], 1):
        print(f"[{i}/{len(split_cases) + 1}] {case.label}", flush=True)
        figures, mission = fly_case(case, logs / f"mission-{i}")
        runs.append(figures)
        if needs_a_look(figures):
            to_look_at.append(mission)
        print(
            f"    {figures['status']}, {len(figures['sorties'])} sorties, {figures['wall_s']:.0f} s wall",
            flush=True,
        )
    *runs, forced = runs
    forced["note"] = (
        "one tour over the budget (margin_wh < 0), stopped by the vehicle's battery failsafe: its used energy is "
        "what the battery gave until the landing, not the planned route's, so it is not in the summary"
    )
    print()
    print_table(runs)
    figures = summary(runs)
    mean, worst = figures["mean_abs_energy_error_pct"], figures["worst_abs_energy_error_pct"]
    print(
        f"\n{figures['completed']}/{figures['missions']} completed; {figures['sorties']} sorties: energy error mean "
        f"{_num(mean, '.2f')} %, worst {_num(worst, '.2f')} % ({figures['worst_sortie']}); "
        f"battery warnings: {figures['battery_warnings'] or 'none'}"
    )
    print(
        f"forced single sortie ({forced['wind']}): {forced['status']}, {forced['reason']}; "
        f"warning {forced['sorties'][0]['warning']}"
    )
    wall_s = time.monotonic() - started
    load = {"before": load_before, "after": os.getloadavg()}
    command = " ".join([".venv/bin/python -m bench.energy_missions", *(argv if argv is not None else sys.argv[1:])])
    result = document(runs, forced, command, load, wall_s)
    result["missions_to_look_at"] = to_look_at
    suffix = "_quick" if args.quick else ""
    json_path, figure = RESULTS / f"energy_missions{suffix}.json", RESULTS / f"energy_missions{suffix}.png"
    RESULTS.mkdir(parents=True, exist_ok=True)
    json_path.write_text(json.dumps(rounded(result), indent=2) + "\n")
    draw(runs, figure)
    print(f"wrote {json_path.relative_to(REPO)}, {figure.relative_to(REPO)} ({wall_s:.0f} s wall, logs in {logs})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
