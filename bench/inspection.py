"""Buoy inspection through the whole stack: seeded worlds flown as real processes, the verdicts against the truth.

    .venv/bin/python -m bench.inspection                          # 30 worlds (seeds 0-29), the first 3 flown again
    .venv/bin/python -m bench.inspection --worlds 2 --baseline 1  # a quick check
    .venv/bin/python -m bench.inspection --worlds 10 --first-seed 30 --keep-misses /tmp/misses
    .venv/bin/python -m bench.inspection --jobs 2                 # two worlds at a time (see below)

Per world (seed S): the reference scenario (planner.scenario.reference_scenario(1): 13 buoys in 1200 m x 700 m,
depot (269, 293)) made a world by uavcore.buoy_world.World.random(S, ...): each buoy a kind with its default
light, and with probability 0.2 one fault (off station by 2-5 swing radii, light out, or another character).
The world file is given to the vehicle (`sitl_quad --lockstep --seed S --world FILE --image-dir DIR`: the camera
on its gimbal renders what the world really is), flown by its ADRC offboard controller (`adrc_offboard`), and
the same file is posted to the service (`gcs serve`) through POST /imports, so the buoys go to it as charted
(kind, light, swing radius) and the faults do not. The demo's request (stack.demo.reference_request: 5 m, 10 m/s,
1 s dwell, CHNN-GA seed 1) with those buoys is flown to the end; GET /missions/{id}/inspections is then set
against the world file's truth. Still air and no current: the buoys wander in 30 % of their swing circle.

Measured:
- defects: a buoy is truly defective when the world gave it a fault, found when its verdict is `defect`;
  precision and recall over every buoy of every world (not_inspected counts as not found, never as a false
  defect; listed with its reason). Per fault kind, the finding codes the defective buoys got ("right code": the
  fault's own code, any of wrong_character / wrong_period / wrong_colour for another character); every false
  defect with its findings.
- observed position error: for every buoy with an `observed` position, its distance from where the buoy truly
  floated while it was seen: the world's mooring (charted + offset_m) plus World.positions' swing, averaged over
  the capture times (vehicle time, the frames table's `t_s`) of the frames it was found in. RMS and max.
- light: on buoys whose light was judged (verdict not not_inspected, and not `not_found`), whether the reading
  matches what the light really shows: no light finding when it shows the charted character, light_out when it
  is dark, wrong_character / wrong_period / wrong_colour when it shows another.
- time: the mission's flight time (tracking.flight_time_s, vehicle time); for the first --baseline worlds the
  same request flown again on the same vehicle after a battery swap with "inspect": false (no camera items), and
  the difference per buoy; the wall time of each world (start-up, flight, evaluation).

Each world gets its own free ports and temporary directory; the processes are stopped at the end of each world
and on an error, Ctrl-C or SIGTERM. --jobs N flies N worlds at a time: a world's vehicle renders its frames in its
lockstep loop, one core, while the service analyses them on others, so on two cores two worlds at a time finish
the campaign sooner; each world's wall times then include the other's load (its verdicts do not: lockstep).
Results are written after every world (bench/results/inspection.json, with the command line, the git commit and
the machine's load), so a stopped campaign keeps what it measured.
--keep-misses DIR keeps, for every buoy judged wrongly or not inspected, its record, its frames' analysis and a
dozen of its frames (JPEG) plus the world file, for diagnosis.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import platform
import shlex
import signal
import sqlite3
import subprocess
import sys
import tempfile
import threading
import time
from collections import Counter, defaultdict
from concurrent.futures import ThreadPoolExecutor, as_completed
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import httpx
import numpy as np

from bench.processes import free_tcp_port, free_udp_port, stop_process
from planner.scenario import reference_scenario
from stack.demo import reference_request
from stack.options import UpOptions
from uavcore.buoy_world import World
from uavcore.geodesy import LocalFrame
from uavcore.light_character import burst_for, parse

REPO = Path(__file__).resolve().parents[1]
RESULTS = REPO / "bench" / "results" / "inspection.json"
SCENARIO_SEED = 1  # the demo's reference scenario
TERMINAL = ("completed", "failed", "aborted")
START_TIMEOUT_S = 180.0
FLIGHT_TIMEOUT_S = 2400.0  # wall clock: a backstop against a hang (lockstep runs at the machine's pace)
LIGHT_CODES = ("light_out", "wrong_character", "wrong_period", "wrong_colour")
WRONG_LIGHT = frozenset({"wrong_character", "wrong_period", "wrong_colour"})
FAULT_KINDS = ("off_station", "light_out", "wrong_character")
TARGETS = {"precision": 0.95, "recall": 0.95, "position_rms_m": 1.0, "light_right": 0.95}
KEPT_FRAMES = 12
STOPPING = threading.Event()  # Ctrl-C or SIGTERM: every world's waits end, and its processes are stopped


class TerminatedError(Exception):
    """SIGTERM: stop the worlds' processes and write what was measured."""


# ----- processes
class Child:
    """One process of the stack, its output in a log file."""

    def __init__(self, name: str, args: list[str], workdir: Path, env: dict[str, str]) -> None:
        self.name, self.args, self.env = name, [sys.executable, "-m", *args], env
        self.log_path = workdir / f"{name}.log"
        self.process: subprocess.Popen | None = None

    def start(self, ready) -> None:
        with open(self.log_path, "a") as log:
            # its own session: a Ctrl-C reaches the bench only, which stops the children in order
            self.process = subprocess.Popen(
                self.args, cwd=REPO, stdout=log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                env=self.env, start_new_session=True,
            )  # fmt: skip
        deadline = time.monotonic() + START_TIMEOUT_S
        while not ready():
            if STOPPING.is_set():
                raise RuntimeError(f"{self.name}: the campaign was stopped")
            if self.process.poll() is not None:
                raise RuntimeError(f"{self.name} exited while starting:\n{self.log()[-3000:]}")
            if time.monotonic() > deadline:
                raise RuntimeError(f"{self.name} not ready in {START_TIMEOUT_S:.0f} s:\n{self.log()[-3000:]}")
            time.sleep(0.1)

    def log(self) -> str:
        return self.log_path.read_text(errors="replace") if self.log_path.exists() else ""

    def check(self) -> None:
        if self.process is not None and self.process.poll() is not None:
            raise RuntimeError(f"{self.name} exited ({self.process.returncode}):\n{self.log()[-3000:]}")

    def stop(self) -> None:
        if self.process is not None:
            stop_process(self.process)
            # what it left behind in its session (the service's analysis workers): its process group, only ours
            with contextlib.suppress(ProcessLookupError, PermissionError):
                os.killpg(self.process.pid, signal.SIGKILL)


class Stack:
    """Vehicle (with the world and its camera), ADRC offboard controller and service, on free ports in workdir."""

    def __init__(self, workdir: Path, world_file: Path, vehicle_seed: int) -> None:
        self.dir = workdir
        self.vehicle_port, self.http_port = free_udp_port(), free_tcp_port()
        env = os.environ | {"BUOY_GCS_DATA_DIR": str(workdir / "data"), "MAVLINK20": "1"}
        self.api = httpx.Client(base_url=f"http://127.0.0.1:{self.http_port}", timeout=120.0)
        vehicle = ["sitl_quad", "--port", str(self.vehicle_port), "--lockstep", "--seed", str(vehicle_seed)]
        vehicle += ["--world", str(world_file), "--image-dir", str(workdir / "images")]
        offboard = ["adrc_offboard", "--connect", f"udpout:127.0.0.1:{self.vehicle_port}"]
        gcs = ["gcs", "serve", "--vehicle", f"udpout:127.0.0.1:{self.vehicle_port}", "--port", str(self.http_port)]
        gcs += ["--db", str(self.db_path), "--vehicle-wait", "30"]
        self.children = [Child(n, a, workdir, env) for n, a in
                         (("sitl_quad", vehicle), ("adrc_offboard", offboard), ("gcs", gcs))]  # fmt: skip

    @property
    def db_path(self) -> Path:
        return self.dir / "gcs.sqlite"

    def start(self) -> None:
        vehicle, offboard, gcs = self.children
        vehicle.start(lambda: "listening" in vehicle.log())
        offboard.start(lambda: "outer loop at" in offboard.log())
        gcs.start(self._http_ready)
        deadline = time.monotonic() + START_TIMEOUT_S
        while not self.api.get("/vehicle").json()["connected"]:
            if time.monotonic() > deadline:
                raise RuntimeError("the service never heard the vehicle")
            time.sleep(0.2)

    def _http_ready(self) -> bool:
        try:
            return self.api.get("/vehicle", timeout=1).status_code == 200
        except httpx.HTTPError:
            return False

    def fly(self, request: dict) -> tuple[dict, float]:
        """POST the mission and wait for it to end: the mission, and the wall seconds from POST to the end."""
        started = time.monotonic()
        response = self.api.post("/missions", json=request)
        if response.status_code != 201:
            raise RuntimeError(f"POST /missions: {response.status_code} {response.text}")
        mission_id = response.json()["id"]
        while (mission := self.api.get(f"/missions/{mission_id}").json())["status"] not in TERMINAL:
            if time.monotonic() - started > FLIGHT_TIMEOUT_S:
                raise RuntimeError(f"mission {mission_id} still {mission['status']} after {FLIGHT_TIMEOUT_S:.0f} s")
            if STOPPING.is_set():
                raise RuntimeError(f"mission {mission_id}: the campaign was stopped while it was {mission['status']}")
            for child in self.children:
                child.check()
            time.sleep(1.0)
        return mission, time.monotonic() - started

    def stop(self) -> list[str]:
        """Stop everything; the names of children that logged a traceback."""
        self.api.close()
        for child in reversed(self.children):
            child.stop()
        return [child.name for child in self.children if "Traceback" in child.log()]


# ----- the truth and the verdicts
def make_world(seed: int) -> World:
    scenario = reference_scenario(SCENARIO_SEED)
    ids = [f"B{i + 1}" for i in range(len(scenario.buoys_lat_lon))]
    return World.random(seed, scenario.buoys_lat_lon, ids)


def frames_by_buoy(db_path: Path, mission_id: int) -> dict[int, list[dict]]:
    """The mission's frames' records (the frames table's `captured` JSON: t_s, found, light_on, note...) by buoy
    input index, in capture order, with each one's storage id."""
    frames: dict[int, list[dict]] = defaultdict(list)
    with sqlite3.connect(db_path) as db:
        rows = db.execute("SELECT id, buoy, captured FROM frames WHERE mission_id = ? ORDER BY id", (mission_id,))
        for frame_id, buoy, captured in rows:
            frames[buoy].append(json.loads(captured) | {"id": frame_id})
    for records in frames.values():
        records.sort(key=lambda f: f["t_s"])
    return frames


def expected_frames(buoy) -> int:
    """The burst the buoy's charted light asks for (the mission's capture count)."""
    duration_s, rate_hz = burst_for(buoy.light)
    return math.ceil(duration_s * rate_hz)


def light_right(buoy, codes: set[str]) -> bool:
    """Whether the light findings match what the light really shows (module doc)."""
    light = codes & set(LIGHT_CODES)
    if buoy.actual_light == buoy.light:
        return not light
    if buoy.actual_light is None:
        return "light_out" in light
    return bool(light & WRONG_LIGHT) and "light_out" not in light


def right_code(fault: str, codes: set[str]) -> bool:
    return bool(codes & WRONG_LIGHT) if fault == "wrong_character" else fault in codes


def evaluate(world: World, inspections: list[dict], frames: dict[int, list[dict]]) -> list[dict]:
    """One row per buoy: the truth, the verdict and findings, the position error, the light's reading judged."""
    by_index = {i["index"]: i for i in inspections}
    rows = []
    for index, buoy in enumerate(world.buoys):
        inspection = by_index.get(index)
        codes = {f["code"] for f in inspection["findings"]} if inspection else set()
        verdict = inspection["verdict"] if inspection else "missing"
        burst = frames.get(index, [])
        found = [f for f in burst if f.get("found")]
        row: dict[str, Any] = {
            "id": buoy.id,
            "index": index,
            "kind": buoy.kind,
            "light": None if buoy.light is None else buoy.light.abbreviation(),
            "shows": "dark" if buoy.actual_light is None else buoy.actual_light.abbreviation(),
            "faults": buoy.faults,
            "mooring_offset_m": round(math.hypot(*buoy.offset_m), 2),
            "swing_radius_m": buoy.swing_radius_m,
            "verdict": verdict,
            "findings": inspection["findings"] if inspection else [],
            "reason": inspection["reason"] if inspection else "no record",
            "light_seen": inspection["light_seen"] if inspection else None,
            "frames": len(burst),
            "frames_expected": expected_frames(buoy),
            "frames_found": len(found),
            "position_error_m": None,
            "light_judged": None,
            "light_right": None,
        }
        if inspection and inspection["observed"] is not None:
            times = [f["t_s"] for f in (found or burst)]
            if times:
                truth = np.mean([world.positions(t)[index] for t in times], axis=0)  # north, east from charted
                frame = LocalFrame(*buoy.charted)
                observed = inspection["observed"]
                east, north = frame.project(np.array([[observed["lat"], observed["lon"]]]))[0]
                row["position_error_m"] = round(float(math.hypot(north - truth[0], east - truth[1])), 3)
                row["true_offset_m"] = round(float(math.hypot(*truth)), 2)
                row["observed_offset_m"] = inspection["offset_m"]
        if buoy.light is not None and verdict in ("ok", "defect") and "not_found" not in codes:
            row["light_judged"] = True
            row["light_right"] = light_right(buoy, codes)
        rows.append(row)
    return rows


def keep_misses(keep: Path, seed: int, world: World, stack: Stack, mission_id: int, rows: list[dict],
                inspections: list[dict], frames: dict[int, list[dict]]) -> list[str]:  # fmt: skip
    """For every buoy judged wrongly (a fault missed, a false defect, a wrong light reading, not inspected): its
    record, its frames' analysis and up to KEPT_FRAMES of its frames; the world file beside them."""
    by_index = {i["index"]: i for i in inspections}
    kept = []
    for row in rows:
        defect = row["verdict"] == "defect"
        if bool(row["faults"]) == defect and row["light_right"] is not False and row["verdict"] != "not_inspected":
            continue
        where = keep / f"world{seed}" / row["id"]
        where.mkdir(parents=True, exist_ok=True)
        (keep / f"world{seed}" / "world.geojson").write_text(json.dumps(world.to_geojson(), indent=1))
        burst = frames.get(row["index"], [])
        (where / "record.json").write_text(
            json.dumps({"truth": row, "inspection": by_index.get(row["index"]), "frames": burst}, indent=1)
        )
        picks = sorted({round(k) for k in np.linspace(0, len(burst) - 1, min(KEPT_FRAMES, len(burst)))})
        for k in picks:
            frame = burst[k]
            response = stack.api.get(f"/missions/{mission_id}/frames/{frame['id']}")
            if response.status_code == 200:
                tag = "found" if frame.get("found") else "notfound"
                (where / f"{k:03d}-t{frame['t_s']:.2f}-{tag}.jpg").write_bytes(response.content)
        kept.append(str(where))
    return kept


def fly_world(seed: int, baseline: bool, keep: Path | None) -> dict:
    world = make_world(seed)
    world_started = time.monotonic()
    with tempfile.TemporaryDirectory(prefix=f"bench-inspection-{seed}-") as tmp:
        workdir = Path(tmp)
        world_file = workdir / "world.geojson"
        world_file.write_text(json.dumps(world.to_geojson()))
        stack = Stack(workdir, world_file, seed)
        problems: list[str] = []
        try:
            stack.start()
            startup_s = time.monotonic() - world_started
            imported = stack.api.post("/imports?filename=world.geojson", content=world_file.read_bytes())
            imported.raise_for_status()
            buoys = imported.json()["buoys"]
            request = reference_request(UpOptions(demo_seed=SCENARIO_SEED)) | {"buoys": buoys}
            mission, flight_wall_s = stack.fly(request)
            inspections = stack.api.get(f"/missions/{mission['id']}/inspections").json()
            frames = frames_by_buoy(stack.db_path, mission["id"])
            rows = evaluate(world, inspections, frames)
            kept = keep_misses(keep, seed, world, stack, mission["id"], rows, inspections, frames) if keep else []
            flight_s = (mission.get("tracking") or {}).get("flight_time_s")
            result: dict[str, Any] = {
                "seed": seed,
                "status": mission["status"],
                "reason": mission.get("reason"),
                "camera": mission["progress"].get("camera"),
                "flight_time_s": flight_s,
                "flight_wall_s": round(flight_wall_s, 1),
                "startup_wall_s": round(startup_s, 1),
                "lockstep_speed": None if not flight_s else round(flight_s / flight_wall_s, 2),
                "frames": sum(len(f) for f in frames.values()),
                "frames_expected": sum(expected_frames(b) for b in world.buoys),
                "images_captured": len(list((workdir / "images").glob("*.jpg"))),
                "events": mission.get("events"),
                "buoys": rows,
                "kept": kept,
            }
            if baseline:
                swap = stack.api.post("/vehicle/battery-swap", json={})
                if swap.status_code >= 300:
                    raise RuntimeError(f"battery swap: {swap.status_code} {swap.text}")
                plain, plain_wall_s = stack.fly(request | {"inspect": False})
                plain_s = (plain.get("tracking") or {}).get("flight_time_s")
                result["baseline"] = {
                    "status": plain["status"],
                    "reason": plain.get("reason"),
                    "flight_time_s": plain_s,
                    "flight_wall_s": round(plain_wall_s, 1),
                    "events": None if plain["status"] == "completed" else plain.get("events"),
                    "added_per_buoy_s": None
                    if not (plain_s and flight_s)
                    else round((flight_s - plain_s) / len(world.buoys), 2),
                }
        finally:
            problems = stack.stop()
    result["tracebacks"] = problems
    result["wall_s"] = round(time.monotonic() - world_started, 1)
    result["git_commit"] = _git_commit()  # merges between --resume runs change it
    result["load_average"] = [round(x, 1) for x in os.getloadavg()]  # 1, 5, 15 min, at the world's end
    return result


# ----- totals
def totals(worlds: list[dict]) -> dict:
    rows = [row for w in worlds for row in w["buoys"]]
    defective = [r for r in rows if r["faults"]]
    sound = [r for r in rows if not r["faults"]]
    tp = sum(r["verdict"] == "defect" for r in defective)
    fp = sum(r["verdict"] == "defect" for r in sound)
    fn = len(defective) - tp

    def codes(row: dict) -> set[str]:
        return {f["code"] for f in row["findings"]}

    per_fault = {}
    for fault in FAULT_KINDS:
        these = [r for r in defective if fault in r["faults"]]
        per_fault[fault] = {
            "buoys": len(these),
            "found": sum(r["verdict"] == "defect" for r in these),
            "right_code": sum(r["verdict"] == "defect" and right_code(fault, codes(r)) for r in these),
            "not_inspected": sum(r["verdict"] == "not_inspected" for r in these),
            "codes": dict(Counter(",".join(sorted(codes(r))) or r["verdict"] for r in these)),
        }
    false_defects = [
        {"seed": w["seed"], "buoy": r["id"], "kind": r["kind"], "light": r["light"], "findings": r["findings"],
         "light_seen": r["light_seen"], "frames": r["frames"], "frames_found": r["frames_found"]}
        for w in worlds for r in w["buoys"] if not r["faults"] and r["verdict"] == "defect"
    ]  # fmt: skip
    missed = [
        {"seed": w["seed"], "buoy": r["id"], "kind": r["kind"], "faults": r["faults"], "shows": r["shows"],
         "mooring_offset_m": r["mooring_offset_m"], "verdict": r["verdict"], "findings": r["findings"],
         "light_seen": r["light_seen"], "reason": r["reason"]}
        for w in worlds for r in w["buoys"] if r["faults"] and r["verdict"] != "defect"
    ]  # fmt: skip
    not_inspected = [
        {"seed": w["seed"], "buoy": r["id"], "kind": r["kind"], "faults": r["faults"], "reason": r["reason"]}
        for w in worlds for r in w["buoys"] if r["verdict"] == "not_inspected"
    ]  # fmt: skip
    errors = [r["position_error_m"] for r in rows if r["position_error_m"] is not None]
    judged = [r for r in rows if r["light_judged"]]
    wrong_light = [
        {"seed": w["seed"], "buoy": r["id"], "kind": r["kind"], "light": r["light"], "shows": r["shows"],
         "light_seen": r["light_seen"], "codes": sorted(codes(r) & set(LIGHT_CODES))}
        for w in worlds for r in w["buoys"] if r["light_judged"] and not r["light_right"]
    ]  # fmt: skip
    added = [w["baseline"]["added_per_buoy_s"] for w in worlds if (w.get("baseline") or {}).get("added_per_buoy_s")]
    return {
        "worlds": len(worlds),
        "completed": sum(w["status"] == "completed" for w in worlds),
        "buoys": len(rows),
        "defective": len(defective),
        "true_defects": tp,
        "false_defects": fp,
        "missed_defects": fn,
        "precision": tp / (tp + fp) if tp + fp else None,
        "recall": tp / len(defective) if defective else None,
        "per_fault": per_fault,
        "false_defect_list": false_defects,
        "missed_list": missed,
        "not_inspected": len(not_inspected),
        "not_inspected_list": not_inspected,
        "position_errors": len(errors),
        "position_rms_m": float(np.sqrt(np.mean(np.square(errors)))) if errors else None,
        "position_max_m": max(errors) if errors else None,
        "position_p95_m": float(np.percentile(errors, 95)) if errors else None,
        "light_judged": len(judged),
        "light_right": sum(bool(r["light_right"]) for r in judged),
        "light_right_fraction": sum(bool(r["light_right"]) for r in judged) / len(judged) if judged else None,
        "wrong_light_list": wrong_light,
        "added_per_buoy_s": added,
        "added_per_buoy_mean_s": float(np.mean(added)) if added else None,
        "flight_time_mean_s": _mean(w["flight_time_s"] for w in worlds),
        "frames_stored": sum(r["frames"] for r in rows),
        "frames_expected": sum(r["frames_expected"] for r in rows),
        "wall_per_world_mean_s": _mean(w["wall_s"] for w in worlds),
        "wall_per_world_max_s": max((w["wall_s"] for w in worlds), default=None),
    }


def _mean(values) -> float | None:
    values = [v for v in values if v is not None]
    return float(np.mean(values)) if values else None


def _git_commit() -> str | None:
    try:
        commit = subprocess.run(["git", "rev-parse", "HEAD"], cwd=REPO, capture_output=True, text=True, check=True)
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=REPO,
                               capture_output=True, text=True, check=True)  # fmt: skip
        return commit.stdout.strip() + ("+dirty" if dirty.stdout.strip() else "")
    except (OSError, subprocess.CalledProcessError):
        return None


def _fmt(value: float | None, spec: str) -> str:
    return "-" if value is None else format(value, spec)


def world_line(w: dict) -> str:
    rows = w["buoys"]
    faulty = sum(bool(r["faults"]) for r in rows)
    tp = sum(bool(r["faults"]) and r["verdict"] == "defect" for r in rows)
    fp = sum(not r["faults"] and r["verdict"] == "defect" for r in rows)
    ni = sum(r["verdict"] == "not_inspected" for r in rows)
    errors = [r["position_error_m"] for r in rows if r["position_error_m"] is not None]
    rms = float(np.sqrt(np.mean(np.square(errors)))) if errors else None
    judged = [r for r in rows if r["light_judged"]]
    light = f"{sum(bool(r['light_right']) for r in judged)}/{len(judged)}"
    base = (w.get("baseline") or {}).get("flight_time_s")
    added = (w.get("baseline") or {}).get("added_per_buoy_s")
    return (
        f"{w['seed']:>4} {w['status']:>9} {faulty:>6} {tp:>5} {fp:>5} {ni:>4} {_fmt(rms, '.2f'):>6} "
        f"{_fmt(max(errors, default=None), '.2f'):>6} {light:>6} {_fmt(w['flight_time_s'], '.0f'):>7} "
        f"{_fmt(base, '.0f'):>7} {_fmt(added, '.1f'):>6} {w['frames']:>6} {w['wall_s']:>7.0f}"
    )


HEADER = (
    f"{'seed':>4} {'status':>9} {'faulty':>6} {'found':>5} {'false':>5} {'n/i':>4} {'posRMS':>6} {'posMax':>6} "
    f"{'light':>6} {'flight':>7} {'plain':>7} {'+s/by':>6} {'frames':>6} {'wall s':>7}"
)


def write_results(
    args: argparse.Namespace, argv: list[str], worlds: list[dict], failures: list[dict], started: float
) -> dict:
    summary = totals(worlds)
    machine = {"platform": platform.platform(), "cpus": os.cpu_count(), "python": platform.python_version()}
    document = {
        "command": "python -m bench.inspection " + shlex.join(argv),
        "git_commit": _git_commit(),
        "machine": machine,
        "load_average_at_end": os.getloadavg(),
        "note": args.note,
        "setup": {
            "scenario": f"planner.scenario.reference_scenario({SCENARIO_SEED}), stack.demo.reference_request",
            "worlds": "uavcore.buoy_world.World.random(seed, ...), fault probability 0.2",
            "weather": "still air, no current",
            "first_seed": args.first_seed,
            "worlds_asked": args.worlds,
            "baseline_worlds": args.baseline,
        },
        "targets": TARGETS,
        "campaign_wall_s": round(time.monotonic() - started, 1),
        "earlier_commands": getattr(args, "earlier", []),  # --resume: the runs whose worlds were kept
        "earlier_wall_s": getattr(args, "earlier_wall_s", 0.0),
        "totals": summary,
        "failed_worlds": failures,
        "worlds": worlds,
    }
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    tmp = RESULTS.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(document, indent=1) + "\n")
    tmp.replace(RESULTS)
    return summary


def print_totals(summary: dict, wall_s: float) -> None:
    def pct(x: float | None) -> str:
        return "-" if x is None else f"{100 * x:.1f} %"

    print(f"\n{summary['worlds']} worlds ({summary['completed']} completed), {summary['buoys']} buoys, "
          f"{summary['defective']} defective")  # fmt: skip
    print(f"defects: precision {pct(summary['precision'])} (target >= 95 %), recall {pct(summary['recall'])} "
          f"(target >= 95 %): {summary['true_defects']} found, {summary['false_defects']} false, "
          f"{summary['missed_defects']} missed, {summary['not_inspected']} not inspected")  # fmt: skip
    for fault, figures in summary["per_fault"].items():
        print(f"  {fault:>16}: {figures['found']}/{figures['buoys']} found, {figures['right_code']} with its own code; "
              f"codes {figures['codes']}")  # fmt: skip
    for false in summary["false_defect_list"]:
        print(f"  false defect: world {false['seed']} {false['buoy']} ({false['kind']}, {false['light']}): "
              f"{[f['code'] for f in false['findings']]} seen {false['light_seen']}")  # fmt: skip
    for miss in summary["missed_list"]:
        print(f"  missed: world {miss['seed']} {miss['buoy']} ({miss['kind']}, {miss['faults']}, "
              f"shows {miss['shows']}, mooring {miss['mooring_offset_m']} m): {miss['verdict']} "
              f"{[f['code'] for f in miss['findings']]} seen {miss['light_seen']} {miss['reason'] or ''}")  # fmt: skip
    for item in summary["not_inspected_list"]:
        print(f"  not inspected: world {item['seed']} {item['buoy']} ({item['kind']}): {item['reason']}")
    print(f"observed position error: RMS {_fmt(summary['position_rms_m'], '.3f')} m (target <= 1.0 m), "
          f"max {_fmt(summary['position_max_m'], '.2f')} m over {summary['position_errors']} buoys")  # fmt: skip
    print(f"light read right: {summary['light_right']}/{summary['light_judged']} = "
          f"{pct(summary['light_right_fraction'])} (target >= 95 %)")  # fmt: skip
    for wrong in summary["wrong_light_list"]:
        print(f"  light wrong: world {wrong['seed']} {wrong['buoy']} ({wrong['kind']}, charted {wrong['light']}, "
              f"shows {wrong['shows']}): seen {wrong['light_seen']}, {wrong['codes']}")  # fmt: skip
    print(f"mission time added per buoy by the inspection: {_fmt(summary['added_per_buoy_mean_s'], '.1f')} s "
          f"(worlds {summary['added_per_buoy_s']}); "
          f"flight time mean {_fmt(summary['flight_time_mean_s'], '.0f')} s")  # fmt: skip
    print(f"wall per world mean {_fmt(summary['wall_per_world_mean_s'], '.0f')} s, max "
          f"{_fmt(summary['wall_per_world_max_s'], '.0f')} s; campaign {wall_s / 60:.1f} min")  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--worlds", type=int, default=30, help="how many seeded worlds (default 30)")
    parser.add_argument("--first-seed", type=int, default=0, help="the first world's seed (default 0)")
    parser.add_argument("--baseline", type=int, default=3, help="fly the first N worlds again without inspection")
    parser.add_argument("--keep-misses", type=Path, metavar="DIR", help="keep the frames of buoys judged wrongly")
    parser.add_argument("--note", default="", help="a note for the results (e.g. the machine's other work)")
    parser.add_argument("--jobs", type=int, default=1, help="worlds flown at a time (default 1)")
    parser.add_argument(
        "--resume", action="store_true", help="keep the worlds of these seeds already in the results file, fly the rest"
    )
    args = parser.parse_args(argv)

    def terminate(*_: object) -> None:
        raise TerminatedError()

    signal.signal(signal.SIGTERM, terminate)
    started = time.monotonic()
    worlds: list[dict] = []
    failures: list[dict] = []
    seeds = range(args.first_seed, args.first_seed + args.worlds)
    if args.resume and RESULTS.exists():
        before = json.loads(RESULTS.read_text())
        worlds = [{"git_commit": before.get("git_commit")} | w for w in before["worlds"] if w["seed"] in seeds]
        args.earlier = before.get("commands", [before.get("command")]) + before.get("earlier_commands", [])
        args.earlier_wall_s = before.get("campaign_wall_s", 0.0) + before.get("earlier_wall_s", 0.0)
    for row in (row for w in worlds for row in w["buoys"]):  # worlds measured before frames_expected was recorded
        row.setdefault("frames_expected", expected_frames(SimpleNamespace(light=row["light"] and parse(row["light"]))))
    done = {w["seed"] for w in worlds}
    print(HEADER, flush=True)
    for world in worlds:
        print(world_line(world) + "  (earlier run)", flush=True)
    pool = ThreadPoolExecutor(max_workers=max(1, args.jobs))
    try:
        futures = {
            pool.submit(fly_world, seed, k < args.baseline, args.keep_misses): seed
            for k, seed in enumerate(seeds)
            if seed not in done
        }
        for future in as_completed(futures):
            seed = futures[future]
            try:
                world = future.result()
            except (RuntimeError, httpx.HTTPError) as error:
                failures.append({"seed": seed, "error": str(error)[-2000:]})
                print(f"{seed:>4} failed: {str(error)[:500]}", flush=True)
                continue
            worlds.append(world)
            worlds.sort(key=lambda w: w["seed"])
            print(world_line(world), flush=True)
            write_results(args, argv, worlds, failures, started)
    except (KeyboardInterrupt, TerminatedError):
        print(f"stopped after {len(worlds)} worlds", flush=True)
        STOPPING.set()  # the worlds in flight stop their processes; the others are not started
    finally:
        pool.shutdown(wait=True, cancel_futures=True)
    summary = write_results(args, argv, worlds, failures, started)
    print_totals(summary, time.monotonic() - started)
    print(f"wrote {RESULTS.relative_to(REPO)}")
    return 0 if worlds else 1


if __name__ == "__main__":
    raise SystemExit(main())
