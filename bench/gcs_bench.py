"""GCS benchmark: mission creation latency, read latency under concurrency, WebSocket fan-out.

    .venv/bin/python -m bench.gcs_bench [--vehicle-speed N]   # prints a table, writes bench/results/gcs.json

Runs the real stack on free loopback ports: the vehicle (`python -m sitl_quad --speed N`, default 1: real
time, the telemetry rate a GCS sees in the field; faster speeds multiply the MAVLink traffic the service
parses) and the service
(`python -m gcs serve`, uvicorn), and measures through HTTP/WebSocket like a client:
- POST /missions (plan + upload) for 13 and 100 buoys: the POST round trip (planning included), the upload
  (server timestamps of the uploading -> uploaded transitions) and the total to `uploaded`; 3 runs each,
  each mission aborted (return to launch) and landed before the next one.
- GET /missions/{id}: p50 / p99 latency with 50 concurrent clients (40 requests each).
- /ws: 20 clients for 5 s during a flight: messages per second per client and the longest gap.
"""

from __future__ import annotations

import asyncio
import json
import socket
import statistics
import subprocess
import sys
import tempfile
import time
from datetime import datetime
from pathlib import Path

import httpx
import numpy as np
import websockets

from planner.scenario import (
    DEFAULT_HOME,
    random_area_points,
    reference_scenario,
)
from uavcore.geodesy import LocalFrame

REPO = Path(__file__).resolve().parents[1]
RESULTS = REPO / "bench" / "results" / "gcs.json"
TERMINAL = {"completed", "failed", "aborted"}


def free_port(kind: int) -> int:
    with socket.socket(socket.AF_INET, kind) as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def buoys(n: int) -> list[dict]:
    if n == 13:
        lat_lon = reference_scenario(1).buoys_lat_lon
    else:
        lat_lon = LocalFrame(*DEFAULT_HOME).unproject(random_area_points(n, np.random.default_rng(7)))
    return [{"lat": float(lat), "lon": float(lon)} for lat, lon in lat_lon]


def seconds_between(a: str, b: str) -> float:
    return (datetime.fromisoformat(b) - datetime.fromisoformat(a)).total_seconds()


def wait(client: httpx.Client, mission_id: int, done, timeout_s: float) -> dict:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        mission = client.get(f"/missions/{mission_id}").json()
        if done(mission):
            return mission
        time.sleep(0.02)
    raise RuntimeError(f"mission {mission_id} stuck in {mission['status']}")


def create_latency(client: httpx.Client, n: int) -> dict:
    started = time.perf_counter()
    response = client.post("/missions", json={"buoys": buoys(n), "planner": {"method": "auto", "time_limit_s": 2.0}})
    post_s = time.perf_counter() - started
    response.raise_for_status()
    mission = response.json()
    mission = wait(client, mission["id"], lambda m: m["status"] not in ("planned", "uploading"), 60)
    at = {event["status"]: event["at"] for event in mission["events"]}
    if "uploaded" not in at:
        raise RuntimeError(f"upload failed: {mission['reason']}")
    return {
        "id": mission["id"],
        "post_s": post_s,
        "plan_s": mission["elapsed_s"],
        "method": mission["method"],
        "upload_s": seconds_between(at["uploading"], at["uploaded"]),
        "to_uploaded_s": seconds_between(at["planned"], at["uploaded"]) + post_s,
    }


def end_mission(client: httpx.Client, mission_id: int) -> None:
    wait(client, mission_id, lambda m: m["status"] in ("flying", *TERMINAL), 60)
    if client.get(f"/missions/{mission_id}").json()["status"] not in TERMINAL:
        client.post(f"/missions/{mission_id}/abort")
    # an aborted mission keeps recording until the vehicle has landed; the vehicle is free when none is active
    wait(client, mission_id, lambda m: client.get("/vehicle").json()["active_mission"] is None, 300)


async def read_latency(base: str, mission_id: int, clients: int = 50, requests: int = 40) -> dict:
    latencies: list[float] = []

    async def one_client() -> None:
        async with httpx.AsyncClient(base_url=base) as client:
            await client.get(f"/missions/{mission_id}")  # warm-up: connection set-up is not the read latency
            for _ in range(requests):
                started = time.perf_counter()
                (await client.get(f"/missions/{mission_id}")).raise_for_status()
                latencies.append(time.perf_counter() - started)

    started = time.perf_counter()
    await asyncio.gather(*(one_client() for _ in range(clients)))
    wall = time.perf_counter() - started
    ms = np.array(latencies) * 1000
    return {
        "clients": clients,
        "requests": len(ms),
        "p50_ms": float(np.percentile(ms, 50)),
        "p99_ms": float(np.percentile(ms, 99)),
        "throughput_per_s": len(ms) / wall,
    }


async def ws_fanout(base: str, clients: int = 20, duration_s: float = 5.0) -> dict:
    url = base.replace("http://", "ws://") + "/ws"

    async def one_client() -> tuple[int, float, float]:
        arrivals, stale = [], 0.0
        async with websockets.connect(url) as ws:
            end = time.monotonic() + duration_s
            while time.monotonic() < end:
                message = json.loads(await asyncio.wait_for(ws.recv(), 5))
                arrivals.append(time.monotonic())
                stale = max(stale, message["vehicle"]["heartbeat_age_s"] or 0.0)
        return len(arrivals), float(np.diff(arrivals).max()), stale

    results = await asyncio.gather(*(one_client() for _ in range(clients)))
    rates = [count / duration_s for count, _, _ in results]
    return {
        "clients": clients,
        "duration_s": duration_s,
        "min_rate_hz": min(rates),
        "mean_rate_hz": statistics.fmean(rates),
        "max_gap_s": max(gap for _, gap, _ in results),
        # the state pushed is live: the vehicle's last heartbeat (1 Hz) was at most this old in any message
        "max_heartbeat_age_s": max(age for _, _, age in results),
    }


def main() -> int:
    speed = sys.argv[sys.argv.index("--vehicle-speed") + 1] if "--vehicle-speed" in sys.argv else "1"
    udp, http = free_port(socket.SOCK_DGRAM), free_port(socket.SOCK_STREAM)
    base = f"http://127.0.0.1:{http}"
    with tempfile.TemporaryDirectory() as tmp:
        log = open(Path(tmp) / "stack.log", "w")  # noqa: SIM115
        vehicle = subprocess.Popen(
            [sys.executable, "-m", "sitl_quad", "--port", str(udp), "--speed", speed],
            stdout=log,
            stderr=subprocess.STDOUT,
            cwd=REPO,
        )
        service = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "gcs",
                "serve",
                "--vehicle",
                f"udpout:127.0.0.1:{udp}",
                "--port",
                str(http),
                "--db",
                str(Path(tmp) / "gcs.sqlite"),
            ],
            stdout=log,
            stderr=subprocess.STDOUT,
            cwd=REPO,
        )
        try:
            with httpx.Client(base_url=base, timeout=30) as client:
                deadline = time.monotonic() + 30
                while True:
                    try:
                        if client.get("/vehicle").json()["connected"]:
                            break
                    except httpx.HTTPError:
                        pass
                    if time.monotonic() > deadline:
                        raise RuntimeError("the stack did not come up")
                    time.sleep(0.2)
                creation, reads, fanout = {}, None, None
                for n in (13, 100):
                    runs = []
                    for _ in range(3):
                        run = create_latency(client, n)
                        runs.append(run)
                        if reads is None:  # measure reads and fan-out while the first mission flies
                            wait(client, run["id"], lambda m: m["status"] == "flying", 60)
                            reads = asyncio.run(read_latency(base, run["id"]))
                            fanout = asyncio.run(ws_fanout(base))
                        end_mission(client, run["id"])
                    creation[n] = runs
        finally:
            for process in (service, vehicle):
                process.terminate()
                process.wait(10)
            log.close()

    print(f"{'buoys':>5} {'method':>8} {'POST s':>8} {'plan s':>8} {'upload s':>9} {'to uploaded s':>14}")
    for n, runs in creation.items():
        for run in runs:
            print(
                f"{n:>5} {run['method']:>8} {run['post_s']:>8.3f} {run['plan_s']:>8.3f} {run['upload_s']:>9.3f} "
                f"{run['to_uploaded_s']:>14.3f}"
            )
    print(
        f"GET /missions/{{id}}, {reads['clients']} clients: p50 {reads['p50_ms']:.1f} ms, "
        f"p99 {reads['p99_ms']:.1f} ms, "
        f"{reads['throughput_per_s']:.0f} req/s"
    )
    print(
        f"/ws, {fanout['clients']} clients during a flight: min {fanout['min_rate_hz']:.1f} Hz, mean "
        f"{fanout['mean_rate_hz']:.1f} Hz, longest gap {fanout['max_gap_s'] * 1000:.0f} ms, heartbeat age at most "
        f"{fanout['max_heartbeat_age_s']:.2f} s"
    )
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text(
        json.dumps(
            {
                "vehicle_speed": float(speed),
                "create_mission": {str(n): runs for n, runs in creation.items()},
                "get_mission": reads,
                "ws_fanout": fanout,
            },
            indent=2,
        )
    )
    print(f"written {RESULTS.relative_to(REPO)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
