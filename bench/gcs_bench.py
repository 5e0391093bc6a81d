"""GCS benchmark (issue 13's speed targets): reads under concurrency, mission creation quiet and loaded, the /ws
fan-out, and a 2-hour mission's track.

    .venv/bin/python -m bench.gcs_bench [--quick] [--vehicle-speed N] [--live-rate-hz HZ]

Prints a table and writes bench/results/gcs.json; about 2-3 minutes. --quick (under a minute, fewer runs and
requests) writes nothing: it is a check while developing. Runs the real stack on free loopback ports: the vehicle
(`python -m sitl_quad --speed N`, default 1: the telemetry rate a ground station sees in the field) and the
service (`python -m gcs serve`, uvicorn, SQLite), whose database is given a stored 2-hour mission
(bench.long_mission: 72 000 samples) first.
Measured like a client, each figure with the 1-minute load average (`os.getloadavg()`) at the time:

- GET /missions/{id} and GET /missions?limit=50: p50 / p99 with 50 concurrent keep-alive clients (40 requests
  each) while a mission flies, and the service's CPU time per request (from /proc: robust to a busy machine).
  The clients are raw HTTP/1.1 on asyncio streams: httpx spends about a millisecond of CPU per request, so 50
  httpx clients in one process measured the client more than the service.
- POST /missions, 13 buoys: the POST round trip (plan + store), the upload (server timestamps of uploading ->
  uploaded) and the total to `uploaded`; quiet, then with two CPU burners (`python -c "while True: pass"`, one
  per core) running. Each mission is aborted and landed before the next.
- /ws: 200 clients for 10 s during a flight: messages per second per client against the service's live rate,
  and the p99 / longest gap between two messages of a client.
- The 2-hour mission's display track (GET /missions/{id}/track, first request and cached) against its full
  telemetry (GET /missions/{id}/telemetry): time to first byte, total, size.
"""

from __future__ import annotations

import asyncio
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path

import httpx
import numpy as np
import websockets

from bench.long_mission import SAMPLES, store_long_mission
from bench.processes import free_tcp_port, free_udp_port, stop_process
from gcs.storage import open_storage
from planner.scenario import reference_scenario

REPO = Path(__file__).resolve().parents[1]
RESULTS = REPO / "bench" / "results"
TERMINAL = {"completed", "failed", "aborted"}
READ_CLIENTS, READ_REQUESTS = 50, 40
WS_CLIENTS = 200


@dataclass(frozen=True)
class Mode:
    runs: int  # POST /missions runs, quiet and loaded each
    read_requests: int  # per client
    ws_seconds: float
    track_repeats: int


FULL = Mode(runs=3, read_requests=READ_REQUESTS, ws_seconds=10.0, track_repeats=5)
QUICK = Mode(runs=1, read_requests=10, ws_seconds=3.0, track_repeats=2)


def load() -> float:
    return round(os.getloadavg()[0], 2)


def percentiles(seconds: list[float]) -> dict[str, float]:
    ms = np.array(seconds) * 1000
    return {"p50_ms": float(np.percentile(ms, 50)), "p99_ms": float(np.percentile(ms, 99)), "max_ms": float(ms.max())}


# ----- a minimal keep-alive HTTP/1.1 client: what a fast client costs, so the figures are the service's
class RawHttp:
    """One keep-alive connection; GET only, answers with a Content-Length or chunked (a streamed one)."""

    def __init__(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        self.reader, self.writer = reader, writer

    @classmethod
    async def connect(cls, port: int) -> RawHttp:
        return cls(*await asyncio.open_connection("127.0.0.1", port, limit=2**24))

    async def get(self, path: str) -> tuple[float, float, bytes]:
        """(time to the first byte, total time, body) of one GET; raises on a status other than 200."""
        started = time.perf_counter()
        self.writer.write(f"GET {path} HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n".encode())
        first = await self.reader.read(1)
        ttfb = time.perf_counter() - started
        head = first + await self.reader.readuntil(b"\r\n\r\n")
        lines = head.decode("latin-1").split("\r\n")
        if lines[0].split(" ")[1] != "200":
            raise RuntimeError(f"GET {path}: {lines[0]}")
        lengths = [int(line.split(":")[1]) for line in lines if line.lower().startswith("content-length:")]
        body = await self.reader.readexactly(lengths[0]) if lengths else await self._chunked()
        return ttfb, time.perf_counter() - started, body

    async def _chunked(self) -> bytes:
        parts = []
        while size := int((await self.reader.readuntil(b"\r\n"))[:-2], 16):
            parts.append(await self.reader.readexactly(size))
            await self.reader.readexactly(2)
        await self.reader.readexactly(2)  # the empty trailer
        return b"".join(parts)

    def close(self) -> None:
        self.writer.close()


def service_cpu_s(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")  # utime + stime


async def read_latency(port: int, path: str, service_pid: int, requests: int) -> dict:
    """GET path by READ_CLIENTS concurrent keep-alive clients, `requests` each."""
    latencies: list[float] = []
    connections = [await RawHttp.connect(port) for _ in range(READ_CLIENTS)]
    await asyncio.gather(*(c.get(path) for c in connections))  # warm-up: connection set-up is not the read

    async def one_client(connection: RawHttp) -> None:
        for _ in range(requests):
            latencies.append((await connection.get(path))[1])

    cpu, started = service_cpu_s(service_pid), time.perf_counter()
    await asyncio.gather(*(one_client(c) for c in connections))
    wall, cpu = time.perf_counter() - started, service_cpu_s(service_pid) - cpu
    for connection in connections:
        connection.close()
    return {
        "path": path,
        "clients": READ_CLIENTS,
        "requests": len(latencies),
        **percentiles(latencies),
        "throughput_per_s": len(latencies) / wall,
        "service_cpu_ms_per_request": 1000 * cpu / len(latencies),
        "loadavg_1min": load(),
    }


# ----- /ws
async def ws_fanout(base: str, rate_hz: float, duration_s: float) -> dict:
    url = base.replace("http://", "ws://") + "/ws"
    clients = [await websockets.connect(url, max_queue=None) for _ in range(WS_CLIENTS)]

    # The window opens a second after the last connection: by then every client has read what queued while the
    # others connected, so the arrivals counted are the service's pace, not a backlog read at once.
    opens = time.monotonic() + 1.0
    closes = opens + duration_s

    async def listen(ws) -> tuple[list[float], float]:
        arrivals, heartbeat_age = [], 0.0
        while (now := time.monotonic()) < closes:
            async with asyncio.timeout(5):
                message = json.loads(await ws.recv())
            if now >= opens:
                arrivals.append(time.monotonic())
                heartbeat_age = max(heartbeat_age, message["vehicle"]["heartbeat_age_s"] or 0.0)
        return arrivals, heartbeat_age

    try:
        results = await asyncio.gather(*(listen(ws) for ws in clients))
    finally:
        await asyncio.gather(*(ws.close() for ws in clients))
    rates = [len(arrivals) / duration_s for arrivals, _ in results]
    gaps = np.concatenate([np.diff(arrivals) for arrivals, _ in results])
    return {
        "clients": WS_CLIENTS,
        "live_rate_hz": rate_hz,
        "duration_s": duration_s,
        "min_rate_hz": min(rates),
        "mean_rate_hz": statistics.fmean(rates),
        "p99_gap_ms": float(np.percentile(gaps, 99) * 1000),
        "max_gap_ms": float(gaps.max() * 1000),
        # the state pushed is live: the vehicle's last heartbeat (1 Hz) was at most this old in any message
        "max_heartbeat_age_s": max(age for _, age in results),
        "loadavg_1min": load(),
    }


# ----- the 2-hour mission's track
async def track_times(port: int, mission_id: int, repeats: int) -> dict:
    connection = await RawHttp.connect(port)
    bodies: list[bytes] = []

    async def timed(path: str) -> dict:
        ttfb, total, body = await connection.get(path)
        bodies.append(body)
        return {"ttfb_ms": ttfb * 1000, "total_ms": total * 1000, "bytes": len(body), "loadavg_1min": load()}

    try:
        display = f"/missions/{mission_id}/track"
        first = await timed(display)  # built now: every sample read, simplified, encoded
        cached = [await timed(display) for _ in range(repeats)]
        full = [await timed(f"/missions/{mission_id}/telemetry") for _ in range(max(1, repeats // 2))]
    finally:
        connection.close()
    track = json.loads(bodies[0])

    def median(runs: list[dict]) -> dict:
        return {key: statistics.median(run[key] for run in runs) for key in runs[0]}

    return {
        "samples": SAMPLES,
        "display_points": len(track["points"]),
        "display_tolerance_m": track["tolerance_m"],
        "display_first": first,
        "display_cached_median": median(cached),
        "full_telemetry_median": median(full),
    }


# ----- POST /missions
def buoys() -> list[dict]:
    return [{"lat": float(lat), "lon": float(lon)} for lat, lon in reference_scenario(1).buoys_lat_lon]


def seconds_between(a: str, b: str) -> float:
    return (datetime.fromisoformat(b) - datetime.fromisoformat(a)).total_seconds()


def wait(client: httpx.Client, mission_id: int, done: Callable[[dict], bool], timeout_s: float) -> dict:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        mission = client.get(f"/missions/{mission_id}").json()
        if done(mission):
            return mission
        time.sleep(0.02)
    raise RuntimeError(f"mission {mission_id} stuck in {mission['status']}")


def create_latency(client: httpx.Client) -> dict:
    started = time.perf_counter()
    response = client.post("/missions", json={"buoys": buoys(), "planner": {"method": "auto", "time_limit_s": 2.0}})
    post_s = time.perf_counter() - started
    response.raise_for_status()
    mission = wait(client, response.json()["id"], lambda m: m["status"] not in ("planned", "uploading"), 60)
    at = {event["status"]: event["at"] for event in mission["events"]}
    if "uploaded" not in at:
        raise RuntimeError(f"upload failed: {mission['reason']}")
    return {
        "id": mission["id"],
        "post_ms": post_s * 1000,
        "plan_ms": mission["elapsed_s"] * 1000,
        "method": mission["method"],
        "upload_ms": seconds_between(at["uploading"], at["uploaded"]) * 1000,
        "to_uploaded_ms": (seconds_between(at["planned"], at["uploaded"]) + post_s) * 1000,
        "loadavg_1min": load(),
    }


def end_mission(client: httpx.Client, mission_id: int) -> None:
    wait(client, mission_id, lambda m: m["status"] in ("flying", *TERMINAL), 60)
    if client.get(f"/missions/{mission_id}").json()["status"] not in TERMINAL:
        client.post(f"/missions/{mission_id}/abort")
    # an aborted mission keeps recording until the vehicle has landed; the vehicle is free when none is active
    wait(client, mission_id, lambda m: client.get("/vehicle").json()["active_mission"] is None, 300)


class CpuBurners:
    """One busy-looping process per core while inside the `with`."""

    def __enter__(self) -> CpuBurners:
        code = "while True: pass"
        self.processes = [subprocess.Popen([sys.executable, "-c", code]) for _ in range(os.cpu_count() or 2)]
        time.sleep(1.0)  # let the scheduler see them
        return self

    def __exit__(self, *_: object) -> None:
        for process in self.processes:
            process.kill()
            process.wait()


# ----- the run
def start_stack(tmp: Path, speed: str, live_rate_hz: float, log) -> tuple[subprocess.Popen, subprocess.Popen, int]:
    udp, http = free_udp_port(), free_tcp_port()
    vehicle = subprocess.Popen(
        [sys.executable, "-m", "sitl_quad", "--port", str(udp), "--speed", speed],
        stdout=log,
        stderr=subprocess.STDOUT,
        cwd=REPO,
    )
    serve = [sys.executable, "-m", "gcs", "serve", "--vehicle", f"udpout:127.0.0.1:{udp}", "--port", str(http)]
    service = subprocess.Popen(
        [*serve, "--db", str(tmp / "gcs.sqlite")],
        stdout=log,
        stderr=subprocess.STDOUT,
        cwd=REPO,
        env=os.environ | {"BUOY_GCS_LIVE_RATE_HZ": str(live_rate_hz)},
    )
    return vehicle, service, http


def wait_connected(client: httpx.Client) -> None:
    deadline = time.monotonic() + 30
    while True:
        try:
            if client.get("/vehicle").json()["connected"]:
                return
        except httpx.HTTPError:
            pass
        if time.monotonic() > deadline:
            raise RuntimeError("the stack did not come up")
        time.sleep(0.2)


def measure(mode: Mode, speed: str, live_rate_hz: float) -> dict:
    results: dict = {"vehicle_speed": float(speed), "cpus": os.cpu_count()}
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        storage = open_storage(tmp / "gcs.sqlite")
        long_mission = store_long_mission(storage)
        storage.close()
        with open(tmp / "stack.log", "w") as log:
            vehicle, service, port = start_stack(tmp, speed, live_rate_hz, log)
            base = f"http://127.0.0.1:{port}"
            try:
                with httpx.Client(base_url=base, timeout=30) as client:
                    wait_connected(client)
                    quiet = []
                    for run in range(mode.runs):
                        quiet.append(create_latency(client))
                        if run == 0:  # reads and the fan-out while a mission flies (the recorder writing)
                            wait(client, quiet[0]["id"], lambda m: m["status"] == "flying", 60)
                            mission_path = f"/missions/{quiet[0]['id']}"
                            results["get_mission"] = asyncio.run(
                                read_latency(port, mission_path, service.pid, mode.read_requests)
                            )
                            results["list_missions"] = asyncio.run(
                                read_latency(port, "/missions?limit=50", service.pid, mode.read_requests)
                            )
                            results["ws_fanout"] = asyncio.run(ws_fanout(base, live_rate_hz, mode.ws_seconds))
                        end_mission(client, quiet[-1]["id"])
                    results["track_2h"] = asyncio.run(track_times(port, long_mission, mode.track_repeats))
                    loaded = []
                    with CpuBurners():
                        for _ in range(mode.runs):
                            loaded.append(create_latency(client))
                            end_mission(client, loaded[-1]["id"])
                    results["create_mission_13"] = {"quiet": quiet, "loaded": loaded}
            finally:
                for process in (service, vehicle):
                    stop_process(process, 10)
    return results


def report(results: dict) -> None:
    for name in ("get_mission", "list_missions"):
        r = results[name]
        print(
            f"GET {r['path']}, {r['clients']} clients: p50 {r['p50_ms']:.1f} ms, p99 {r['p99_ms']:.1f} ms, "
            f"{r['throughput_per_s']:.0f} req/s, service CPU {r['service_cpu_ms_per_request']:.2f} ms/request "
            f"(load {r['loadavg_1min']})"
        )
    print(
        f"{'POST /missions 13 buoys':<24} {'POST ms':>8} {'plan ms':>8} {'upload ms':>10} {'to uploaded ms':>15} load"
    )
    for condition, runs in results["create_mission_13"].items():
        for run in runs:
            print(
                f"{condition:<24} {run['post_ms']:>8.1f} {run['plan_ms']:>8.1f} {run['upload_ms']:>10.1f} "
                f"{run['to_uploaded_ms']:>15.1f} {run['loadavg_1min']}"
            )
    ws = results["ws_fanout"]
    print(
        f"/ws, {ws['clients']} clients at {ws['live_rate_hz']:g} Hz: min {ws['min_rate_hz']:.1f} Hz, mean "
        f"{ws['mean_rate_hz']:.1f} Hz, gap p99 {ws['p99_gap_ms']:.0f} ms / max {ws['max_gap_ms']:.0f} ms, heartbeat "
        f"age at most {ws['max_heartbeat_age_s']:.2f} s (load {ws['loadavg_1min']})"
    )
    track = results["track_2h"]
    print(
        f"2-hour track ({track['samples']} samples): display {track['display_points']} points within "
        f"{track['display_tolerance_m']:.2f} m"
    )
    for name in ("display_first", "display_cached_median", "full_telemetry_median"):
        t = track[name]
        print(
            f"  {name:<22} first byte {t['ttfb_ms']:8.1f} ms, total {t['total_ms']:8.1f} ms, "
            f"{t['bytes'] / 1e6:6.2f} MB (load {t['loadavg_1min']})"
        )


def main() -> int:
    quick = "--quick" in sys.argv
    speed = sys.argv[sys.argv.index("--vehicle-speed") + 1] if "--vehicle-speed" in sys.argv else "1"
    rate = float(sys.argv[sys.argv.index("--live-rate-hz") + 1]) if "--live-rate-hz" in sys.argv else 10.0
    started = time.monotonic()
    results = measure(QUICK if quick else FULL, speed, rate)
    results["bench_wall_s"] = round(time.monotonic() - started, 1)
    report(results)
    if quick:  # a check while developing: the figures of record come from the full run
        print(f"--quick: nothing written ({results['bench_wall_s']} s)")
        return 0
    path = RESULTS / "gcs.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(results, indent=2) + "\n")
    print(f"written {path.relative_to(REPO)} ({results['bench_wall_s']} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
