"""Fleet missions flown through the whole stack: the planned makespan against the flown one, and the separation.

    .venv/bin/python -m bench.fleet_flown                          # 3 vehicles x 30 buoys, 5 x 60, seed 0
    .venv/bin/python -m bench.fleet_flown --cases 10x100@1.5       # 10 x 100 at 1.5 x real time
    .venv/bin/python -m bench.fleet_flown --cases 3x30 5x60 --seeds 0 1 --pace 3

Per case: `buoy-gcs up --vehicles K` in lockstep (stack.children under stack.supervisor: K vehicles on pads 3 m
apart at the reference depot, each with its ADRC offboard controller, and the service), every vehicle paced at
the same multiple of real time (SIM_SPEEDUP: the case's @pace, else --pace), then POST /missions with n buoys
uniform in the reference area (planner.scenario.random_area_points), `vehicles: "fleet"`, 10 m/s, 1 s dwell,
layers 3 m apart, 5 m separation. Planned: the service's makespan (planner.fleet_time's calibrated model, the
take-offs in turn and the holds before the landings: planner.fleet_schedule). Flown: for each part, its flight
time as recorded (first to last airborne sample, in its vehicle's simulated time), placed on one clock by the
two vehicles' clocks the service noted when it started a vehicle in its turn (flown_makespan_s): first take-off
to last landing, every piece in vehicle time (the wall clock plays no part; the pace reached is reported). The
separation is the fleet
mission's (gcs.missions.fleet_missions.SeparationMonitor: every pair at every position report, both in the air).
Writes bench/results/fleet_flown.json.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
import urllib.request
from datetime import datetime
from pathlib import Path
from tempfile import TemporaryDirectory

import numpy as np

from bench.fleet_scale import get_json, wait_for_fleet
from gcs.missions.results import airborne
from gcs.settings import Settings
from planner.scenario import random_area_points
from stack.children import children
from stack.options import UpOptions
from stack.sim_speed import set_sim_speedup
from stack.supervisor import Supervisor, SupervisorError
from uavcore.geodesy import DEFAULT_HOME, LocalFrame

REPO = Path(__file__).resolve().parents[1]
RESULTS = REPO / "bench" / "results" / "fleet_flown.json"
FLIGHT_TIMEOUT_S = 1800.0


def post_json(url: str, body: dict) -> dict:
    request = urllib.request.Request(
        url, data=json.dumps(body).encode(), method="POST", headers={"Content-Type": "application/json"}
    )
    with urllib.request.urlopen(request, timeout=120) as response:
        return json.load(response)


def _wall(at: str) -> float:
    return datetime.fromisoformat(at).timestamp()


def _flying_at(part: dict) -> float:
    """The service's wall time of the part turning `flying` (its launch)."""
    return next(_wall(e["at"]) for e in part["events"] if e["status"] == "flying")


def flown_makespan_s(shares: list[dict]) -> float:
    """First take-off to last landing on one clock, from the vehicles' own: a vehicle started in its turn has its
    clock and the one it waited for's read at that instant (started_t_s, ahead_t_s), so its clock's origin sits at
    the other's + ahead_t_s - started_t_s; the first of a depot's is the origin (0). Each flight is its first to
    last airborne sample (as flight_time_s)."""
    origin: dict[int, float] = {}
    for share in sorted(shares, key=lambda s: s["launched_wall"]):
        ahead = share["depart_after"]
        if ahead is None or ahead not in origin or share["ahead_t_s"] is None:
            origin[share["sysid"]] = 0.0
        else:
            origin[share["sysid"]] = origin[ahead] + share["ahead_t_s"] - share["started_t_s"]
    for share in shares:
        share["flown_start_s"] = origin[share["sysid"]] + share["airborne_t_s"][0]
    first = min(s["flown_start_s"] for s in shares)
    for share in shares:
        share["flown_start_s"] -= first
    return max(s["flown_start_s"] + s["airborne_t_s"][1] - s["airborne_t_s"][0] for s in shares)


def fly_case(
    vehicles: int, n_buoys: int, seed: int, pace: float, workdir: Path, first_port: int, http_port: int
) -> dict:
    settings = Settings(
        data_dir=workdir, vehicle_url=f"udpout:127.0.0.1:{first_port}", port=http_port, db_path=workdir / "gcs.sqlite"
    )
    supervisor = Supervisor(
        children(UpOptions(settings=settings, vehicles=vehicles)), workdir / "logs", REPO, say=lambda _: None
    )
    base = f"http://127.0.0.1:{http_port}"
    frame = LocalFrame(*DEFAULT_HOME)
    east_north = random_area_points(n_buoys, np.random.default_rng(seed))
    buoys = [
        {"id": f"B{i + 1}", "lat": float(lat), "lon": float(lon)}
        for i, (lat, lon, _) in enumerate(frame.from_ned(n, e, 0.0) for e, n in east_north)
    ]
    try:
        supervisor.start_all()
        wait_for_fleet(base, supervisor)
        for sysid in range(1, vehicles + 1):
            set_sim_speedup(first_port + sysid - 1, sysid, pace)
        request = {
            "vehicles": "fleet", "buoys": buoys, "speed_m_s": 10.0, "dwell_s": 1.0, "layer_gap_m": 3.0,
            "separation_m": 5.0,
        }  # fmt: skip
        request["planner"] = {"seed": seed, "time_limit_s": 5.0}
        started = time.monotonic()
        mission = post_json(f"{base}/missions", request)
        while mission["status"] not in ("completed", "failed", "aborted"):
            if time.monotonic() - started > FLIGHT_TIMEOUT_S:
                raise SupervisorError(f"fleet mission still {mission['status']} after {FLIGHT_TIMEOUT_S:.0f} s")
            supervisor.poll()
            time.sleep(1.0)
            mission = get_json(f"{base}/missions/{mission['id']}")
        wall_s = time.monotonic() - started
        shares = []
        for share in mission["fleet"]["shares"]:
            part = get_json(f"{base}/missions/{share['mission_id']}")
            flown = (part["tracking"] or {}).get("flight_time_s")
            ended = next((_wall(e["at"]) for e in part["events"] if e["status"] == part["status"]), None)
            up = [s["t_s"] for s in get_json(f"{base}/missions/{share['mission_id']}/telemetry") if airborne(s)]
            shares.append(
                {
                    "sysid": share["sysid"],
                    "buoys": len(share["buoys"]),
                    "planned_start_s": share["start_s"],
                    "planned_s": share["predicted_time_s"],
                    "final_hold_s": share["final_hold_s"],
                    "flown_s": flown,
                    "launched_wall": _flying_at(part),
                    "airborne_t_s": [up[0], up[-1]] if up else None,  # its first and last airborne sample
                    "depart_after": share["depart_after"],
                    "started_t_s": share["started_t_s"],
                    "ahead_t_s": share["ahead_t_s"],
                    "ended_wall": ended,
                    "status": part["status"],
                }
            )
    finally:
        supervisor.stop_all()
    complete = all(s["airborne_t_s"] is not None and s["ended_wall"] is not None for s in shares)
    lead = min(shares, key=lambda s: s["launched_wall"])
    reached = lead["flown_s"] / (lead["ended_wall"] - lead["launched_wall"]) if complete else None
    planned = mission["fleet"]["makespan_s"]
    flown = flown_makespan_s(shares) if complete else None
    return {
        "vehicles": vehicles,
        "n_buoys": n_buoys,
        "seed": seed,
        "pace": pace,
        "pace_reached": reached,
        "status": mission["status"],
        "planned_makespan_s": planned,
        "flown_makespan_s": flown,
        "flown_vs_planned_pct": None if flown is None else 100.0 * (flown / planned - 1.0),
        "separation": mission["fleet"]["separation"],
        "wall_s": wall_s,
        "shares": shares,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--cases", nargs="+", default=["3x30", "5x60"], help="VEHICLESxBUOYS[@PACE]")
    parser.add_argument("--pace", type=float, default=2.0, help="the vehicles' SIM_SPEEDUP (x real time)")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0])
    parser.add_argument("--first-port", type=int, default=25540)
    parser.add_argument("--http-port", type=int, default=18090)
    args = parser.parse_args(argv)
    rows = []
    print(
        f"{'K':>3} {'n':>4} {'seed':>4} {'status':>10} {'planned s':>10} {'flown s':>9} {'diff %':>7} {'sep m':>6} pace"
    )
    for case in args.cases:
        size, _, pace = case.partition("@")
        vehicles, n_buoys = (int(x) for x in size.split("x"))
        for seed in args.seeds:
            with TemporaryDirectory(prefix="fleet-flown-") as tmp:
                row = fly_case(
                    vehicles, n_buoys, seed, float(pace or args.pace), Path(tmp), args.first_port, args.http_port
                )
            rows.append(row)
            flown = row["flown_makespan_s"]
            separation = row["separation"]["min_distance_m"]
            print(
                f"{vehicles:>3} {n_buoys:>4} {seed:>4} {row['status']:>10} {row['planned_makespan_s']:>10.1f} "
                f"{flown if flown is not None else float('nan'):>9.1f} "
                f"{row['flown_vs_planned_pct'] if flown is not None else float('nan'):>+7.1f} "
                f"{separation if separation is not None else float('nan'):>6.1f} "
                f"{row['pace']:g}/{row['pace_reached'] or float('nan'):.2f}",
                flush=True,
            )
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    machine = {"platform": platform.platform(), "cpus": os.cpu_count(), "python": platform.python_version()}
    RESULTS.write_text(json.dumps({"machine": machine, "load_average": os.getloadavg(), "cases": rows}, indent=2))
    print(f"wrote {RESULTS.relative_to(REPO)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
