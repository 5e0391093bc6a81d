"""Fleet missions flown through the whole stack: the planned makespan against the flown one.

    .venv/bin/python -m bench.fleet_flown                      # 3 vehicles x 30 buoys, 5 x 60, seeds 0
    .venv/bin/python -m bench.fleet_flown --cases 3x30 5x60 --seeds 0 1

Per case: `buoy-gcs up --vehicles K` in lockstep (stack.children under stack.supervisor: K vehicles on pads 3 m
apart at the reference depot, each with its ADRC offboard controller, and the service), then POST /missions
with n buoys uniform in the reference area (planner.scenario.random_area_points), `vehicles: "fleet"`, 10 m/s,
1 s dwell, layers 3 m apart. Planned: the fleet planner's makespan (take-off and landing 24 s, legs at cruise
speed, dwells: planner.fleet's model). Flown: each part mission's flight time as recorded (first to last
sample, in the vehicle's simulated time: lockstep runs each vehicle at its own pace, so vehicle time is the
honest clock), the longest of them; with the separation the fleet mission measured. Writes
bench/results/fleet_flown.json.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
import urllib.request
from pathlib import Path
from tempfile import TemporaryDirectory

import numpy as np

from bench.fleet_scale import get_json, wait_for_fleet
from gcs.settings import Settings
from planner.scenario import random_area_points
from stack.children import children
from stack.options import UpOptions
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


def fly_case(vehicles: int, n_buoys: int, seed: int, workdir: Path, first_port: int, http_port: int) -> dict:
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
        request = {"vehicles": "fleet", "buoys": buoys, "speed_m_s": 10.0, "dwell_s": 1.0, "layer_gap_m": 3.0}
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
            shares.append(
                {
                    "sysid": share["sysid"],
                    "buoys": len(share["buoys"]),
                    "planned_s": share["predicted_time_s"],
                    "flown_s": flown,
                    "status": part["status"],
                }
            )
    finally:
        supervisor.stop_all()
    flown_times = [s["flown_s"] for s in shares if s["flown_s"] is not None]
    planned = mission["fleet"]["makespan_s"]
    flown = max(flown_times) if len(flown_times) == len(shares) else None
    return {
        "vehicles": vehicles,
        "n_buoys": n_buoys,
        "seed": seed,
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
    parser.add_argument("--cases", nargs="+", default=["3x30", "5x60"], help="VEHICLESxBUOYS")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0])
    parser.add_argument("--first-port", type=int, default=25540)
    parser.add_argument("--http-port", type=int, default=18090)
    args = parser.parse_args(argv)
    rows = []
    print(f"{'K':>3} {'n':>4} {'seed':>4} {'status':>10} {'planned s':>10} {'flown s':>9} {'diff %':>7} {'sep m':>6}")
    for case in args.cases:
        vehicles, n_buoys = (int(x) for x in case.split("x"))
        for seed in args.seeds:
            with TemporaryDirectory(prefix="fleet-flown-") as tmp:
                row = fly_case(vehicles, n_buoys, seed, Path(tmp), args.first_port, args.http_port)
            rows.append(row)
            flown = row["flown_makespan_s"]
            separation = row["separation"]["min_distance_m"]
            print(
                f"{vehicles:>3} {n_buoys:>4} {seed:>4} {row['status']:>10} {row['planned_makespan_s']:>10.1f} "
                f"{flown if flown is not None else float('nan'):>9.1f} "
                f"{row['flown_vs_planned_pct'] if flown is not None else float('nan'):>+7.1f} "
                f"{separation if separation is not None else float('nan'):>6.1f}",
                flush=True,
            )
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    machine = {"platform": platform.platform(), "cpus": os.cpu_count(), "python": platform.python_version()}
    RESULTS.write_text(json.dumps({"machine": machine, "load_average": os.getloadavg(), "cases": rows}, indent=2))
    print(f"wrote {RESULTS.relative_to(REPO)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
