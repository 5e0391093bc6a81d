"""How much faster a campaign of flights runs on Ray than one after another in one process.

    .venv/bin/python -m bench.campaign_speedup [--flights 24] [--cpus 2] [--address ADDR]

The same N short flights (bench.control.scenario.short_scenario: two legs with a turn and the gust; "adrc" and "pid"
alternating at their shipped gains, seeds 0..N/2-1) are run serially in this process and then on Ray
(bench.campaign.run_tasks, a local Ray with --cpus CPUs unless --address names a cluster). Both runs start cold:
the serial one in a fresh process pays the numba cache load once, each Ray worker pays it once too. Prints
flights, wall seconds, speed-up and flights per minute; writes bench/results/campaign_speedup.json with the
machine's CPU count and load average before and after.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

from bench.campaign import run_tasks, start_ray
from bench.control import RESULTS


def short_flight(kind: str, seed: int) -> dict:
    """One short lockstep flight at the shipped gains; its headline metrics and the process's wall time for it."""
    from bench.control.flight import fly
    from bench.control.scenario import short_reference_scenario

    started = time.perf_counter()
    scenario = short_reference_scenario()
    metrics, _ = fly(kind, seed, scenario, items=scenario.items)
    keep = ("rms_error_m", "max_error_m", "gust_peak_m", "saturated_fraction", "completed", "flight_s")
    return {k: metrics[k] for k in keep} | {"wall_s": time.perf_counter() - started, "pid": os.getpid()}


def tasks(n: int) -> list[tuple[str, dict]]:
    return [
        (f"{('adrc', 'pid')[i % 2]}/seed{i // 2}", {"kind": ("adrc", "pid")[i % 2], "seed": i // 2}) for i in range(n)
    ]


def _serial_in_fresh_process(n: int) -> float:
    """Wall seconds of the serial run, in a new interpreter (cold, like a Ray worker)."""
    code = (
        "import time, sys; t = time.perf_counter(); from bench.campaign import run_tasks, start_ray; "
        "from bench.campaign_speedup import short_flight, tasks; "
        f"run_tasks(short_flight, tasks({n}), workers='serial', progress=False); "
        "print(time.perf_counter() - t)"
    )
    out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True)
    return float(out.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--flights", type=int, default=24)
    p.add_argument("--cpus", type=int, default=2, help="CPUs of the local Ray (ignored with --address)")
    p.add_argument("--address", default=None, help='an existing Ray cluster: "auto" or "ray://HOST:10001"')
    p.add_argument("--out", type=Path, default=RESULTS / "campaign_speedup.json")
    args = p.parse_args(argv)
    load_before = os.getloadavg()
    serial_s = _serial_in_fresh_process(args.flights)
    load_between = os.getloadavg()
    started = time.perf_counter()
    start_ray(args.address, args.cpus)  # timed apart: the cluster's start (or connection) is paid once per campaign
    ray_start_s = time.perf_counter() - started
    results = run_tasks(
        short_flight, tasks(args.flights), workers="ray", address=args.address, num_cpus=args.cpus, desc="ray flights"
    )
    ray_s = time.perf_counter() - started
    load_after = os.getloadavg()
    import ray

    cluster_cpus = float(ray.cluster_resources().get("CPU", 0.0))
    errors = {k: r["error"] for k, r in results.items() if "error" in r}
    flight_wall = [r["wall_s"] for r in results.values() if "wall_s" in r]
    n = args.flights
    row = {
        "flights": n,
        "wall_s_serial": serial_s,
        "wall_s_ray": ray_s,
        "ray_start_s": ray_start_s,
        "speed_up_excluding_ray_start": serial_s / (ray_s - ray_start_s),
        "speed_up": serial_s / ray_s,
        "flights_per_min_serial": 60.0 * n / serial_s,
        "flights_per_min_ray": 60.0 * n / ray_s,
        "ray_cpus": cluster_cpus,
        "flights_per_core_min_ray": 60.0 * n / ray_s / max(cluster_cpus, 1.0),
        "flight_wall_s_mean_in_worker": sum(flight_wall) / max(len(flight_wall), 1),
        "worker_processes": len({r["pid"] for r in results.values() if "pid" in r}),
    }
    print(f"{'flights':>8}{'serial s':>10}{'ray s':>8}{'speed-up':>10}{'fl/min serial':>15}{'fl/min ray':>12}")
    print(
        f"{n:>8}{serial_s:>10.1f}{ray_s:>8.1f}{row['speed_up']:>10.2f}"
        f"{row['flights_per_min_serial']:>15.1f}{row['flights_per_min_ray']:>12.1f}"
    )
    print(
        f"Ray: {cluster_cpus:g} CPUs, started in {ray_start_s:.1f} s (speed-up without it "
        f"{row['speed_up_excluding_ray_start']:.2f}), {row['worker_processes']} worker processes, "
        f"{row['flights_per_core_min_ray']:.1f} flights per core-minute; load average "
        f"{load_before[0]:.2f} before, {load_after[0]:.2f} after; errors: {len(errors)}"
    )
    result = {
        "command": "python -m bench.campaign_speedup " + " ".join(argv if argv is not None else sys.argv[1:]),
        "method": __doc__,
        "cpu_count": os.cpu_count(),
        "load_average_before": load_before,
        "load_average_between": load_between,
        "load_average_after": load_after,
        **row,
        "errors": errors,
        "flights_detail": results,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=1))
    print(f"wrote {args.out}")
    return 1 if errors else 0


if __name__ == "__main__":
    sys.exit(main())
