"""How fast the whole stack flies the reference mission in lockstep: `buoy-gcs up --demo --exit-after-demo`.

    .venv/bin/python -m bench.lockstep_mission     # prints a table, writes bench/results/lockstep_mission.json

For the cascade dual ADRC (ADRC offboard outer loop over the vehicle's ADRC attitude loop, MC_ATT_CTRL=1) and
the PID cascade, in that order, `stack.up.run_up` starts the vehicle (--lockstep), the offboard controller and the
service, flies the reference scenario through POST /missions in the paper's weather on its route, and stops
them. Per run:
- lockstep: simulated s / wall s from POST to landed, as the demo prints it (its "lockstep" line);
- start-up: wall s from run_up's call until every child is ready (the demo's "map page" line);
- total: wall s of the whole run_up call (start-up, planning, flight, report, shut-down);
- the machine's 1-minute load average before and after (2 cores here, shared with whatever else runs).
Targets (issue): lockstep >= 20x with the ADRC cascade, the demo with its start-up within 60 s wall.
"""

from __future__ import annotations

import json
import os
import re
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

from bench.processes import free_tcp_port, free_udp_port
from gcs.settings import Settings
from stack.options import CASCADE_NAMES, UpOptions
from stack.up import run_up

REPO = Path(__file__).resolve().parents[1]
RESULTS = REPO / "bench" / "results" / "lockstep_mission.json"
CONTROLLERS = ("adrc", "pid")
TARGET_LOCKSTEP_X = 20.0
TARGET_DEMO_WALL_S = 60.0
# what demo_report prints: "sim speed  438.7 s of vehicle time (upload to landed) in 26.8 s of wall-clock time
# (POST to landed): 16.4 times real time"
LOCKSTEP_LINE = re.compile(r"sim speed\s+([\d.]+) s of vehicle time \(upload to landed\) in ([\d.]+) s of wall")
READY_LINE = "map page:"


@dataclass
class Transcript:
    """What run_up says, each line with its wall time since the start."""

    start: float = field(default_factory=time.monotonic)
    lines: list[tuple[float, str]] = field(default_factory=list)

    def __call__(self, text: str) -> None:
        at = time.monotonic() - self.start
        for line in str(text).splitlines():
            self.lines.append((at, line))

    def first(self, marker: str) -> tuple[float, str]:
        found = next(((at, line) for at, line in self.lines if marker in line), None)
        if found is None:
            raise RuntimeError(f"the demo never said {marker!r}:\n" + "\n".join(line for _, line in self.lines))
        return found


def fly(controller: str, data_dir: Path) -> dict:
    """One `up --demo --exit-after-demo` run with this cascade; its figures."""
    settings = Settings(
        port=free_tcp_port(),
        vehicle_url=f"udpout:127.0.0.1:{free_udp_port()}",
        data_dir=data_dir,
    )
    options = UpOptions(settings=settings, demo=True, exit_after_demo=True, controller=controller)
    load_before = os.getloadavg()[0]
    transcript = Transcript()
    code = run_up(options, say=transcript)
    total_s = time.monotonic() - transcript.start
    load_after = os.getloadavg()[0]
    if code != 0:
        raise RuntimeError(f"the {controller} demo failed (exit {code}):\n" + "\n".join(t for _, t in transcript.lines))
    ready_s, _ = transcript.first(READY_LINE)
    _, line = transcript.first("s of wall-clock time (POST to landed)")
    simulated_s, wall_s = (float(x) for x in LOCKSTEP_LINE.search(line).groups())
    return {
        "controller": controller,
        "cascade": CASCADE_NAMES[controller],
        "simulated_s": simulated_s,
        "flight_wall_s": wall_s,
        "lockstep_x": round(simulated_s / wall_s, 2),
        "startup_s": round(ready_s, 2),
        "total_s": round(total_s, 2),
        "load_before": load_before,
        "load_after": load_after,
    }


def table(rows: list[dict]) -> str:
    header = (
        f"{'cascade':<18} {'simulated s':>11} {'wall POST->landed s':>19} {'lockstep':>9} {'start-up s':>10} "
        f"{'total s':>8} {'load 1 min before/after':>24}"
    )
    lines = [header]
    for r in rows:
        lines.append(
            f"{r['cascade']:<18} {r['simulated_s']:>11.1f} {r['flight_wall_s']:>19.1f} {r['lockstep_x']:>8.1f}x "
            f"{r['startup_s']:>10.1f} {r['total_s']:>8.1f} {r['load_before']:>13.2f} / {r['load_after']:<8.2f}"
        )
    return "\n".join(lines)


def main() -> None:
    rows = []
    with tempfile.TemporaryDirectory(prefix="lockstep-mission-") as tmp:
        for controller in CONTROLLERS:
            rows.append(fly(controller, Path(tmp) / controller))
            print(table(rows[-1:]).splitlines()[-1], flush=True)
    print()
    print(table(rows))
    adrc = rows[0]
    print(
        f"targets: ADRC cascade lockstep {adrc['lockstep_x']:.1f}x (>= {TARGET_LOCKSTEP_X:g}x), "
        f"demo incl. start-up {adrc['total_s']:.1f} s (<= {TARGET_DEMO_WALL_S:g} s wall); cores: {os.cpu_count()}"
    )
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    result = {
        "what": "python -m stack up --demo --exit-after-demo: reference mission, paper's weather, lockstep",
        "cores": os.cpu_count(),
        "targets": {"lockstep_x_min": TARGET_LOCKSTEP_X, "demo_wall_s_max": TARGET_DEMO_WALL_S},
        "runs": rows,
    }
    RESULTS.write_text(json.dumps(result, indent=2) + "\n")
    print(f"wrote {RESULTS.relative_to(REPO)}")


if __name__ == "__main__":
    main()
