"""AIS feed benchmark (issue 22): what 200 AtoNs at realistic rates, in a harbour receiver's traffic, cost the service.

    .venv/bin/python -m bench.ais_feed [--quick] [--compression N]

Prints a table and writes bench/results/ais_feed.json (--quick: shorter phases, nothing written). Runs the real
service, `python -m gcs serve --ais udp://127.0.0.1:PORT` with no vehicle (it links to a UDP port nobody holds; the
AIS feed needs none) and the rate bound as deployed (500 lines a second per source), and sends it NMEA over real
UDP, one sentence per datagram as receivers do. The traffic, at the real rate (lines a second):

- 200 AtoNs each reporting every 180 s (message 21, IALA A-126), at random phases: 1.11; 5 fast ones every 30 s:
  0.17; some names long enough for the name extension;
- what a busy harbour's receiver hears besides: 100 vessels' position reports (messages 1 and 3) every 5 s: 20;
  their static data (message 5, two parts) every 6 min, two vessels' parts interleaved, one out of order: 0.56;
- noise: bad checksums 0.2, lines that are no AIS 0.2, undefined message types 0.05.

Phases, each measured on the service's process from /proc/PID (utime + stime over the wall time; VmRSS, VmHWM):
1. idle: the service with its feed listening and nothing sent: its own baseline (the vehicle link's heartbeats,
   the event loop);
2. compressed: the traffic above with simulated time running `--compression` times the wall clock (default 15:
   351 lines/s, under the rate bound, so every line is parsed), for enough samples: 1800 s simulated in 120 s of
   wall time, every AtoN reporting 10 times. Halfway one AtoN is dragged 60 m off station: its next report carries
   the off-position flag, and GET /ais/atons must show it flagged at that very report (its report count). At the end
   every AtoN must be listed (none stale, no conflict) and the source's counts must match what was sent;
3. real rate: a minute of the same traffic at the real rate (~22 lines/s): measured directly, and compared with
   the estimate from phase 2 (baseline + CPU per line x the real line rate), which is the figure for the target;
4. flood: 5 s of as many lines as one sender process gets out (tens of thousands a second), to show the bound: the
   service's CPU during it, how many lines it parsed (at most the bucket's rate), and the latency of GET
   /ais/sources meanwhile.
Target (issue 22): under 5 % of one core at 200 AtoNs.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import multiprocessing
import multiprocessing.sharedctypes
import os
import random
import socket
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import httpx

from bench.ais_sentences import (
    POSITION_REPORT_1,
    aton_line,
    bad_checksum,
    message_type_line,
    sentence,
    static_data_parts,
)
from bench.processes import free_tcp_port, free_udp_port, stop_process
from uavcore.ais import AID_TYPE_OF_KIND, REPORT_INTERVAL_S, AtonReport
from uavcore.geodesy import DEFAULT_HOME

REPO = Path(__file__).resolve().parents[1]
RESULTS = REPO / "bench" / "results"
ATONS, FAST_ATONS, FAST_INTERVAL_S = 200, 5, 30.0
VESSELS, POSITION_INTERVAL_S, STATIC_INTERVAL_S = 100, 5.0, 360.0
NOISE_PER_S = {"bad_checksum": 0.2, "malformed": 0.2, "unknown_type": 0.05}
DRAG_M = 60.0
TARGET_PCT = 5.0


@dataclass(frozen=True)
class Mode:
    idle_s: float
    compressed_sim_s: float
    real_s: float
    flood_s: float


FULL = Mode(idle_s=30.0, compressed_sim_s=1800.0, real_s=60.0, flood_s=5.0)
QUICK = Mode(idle_s=5.0, compressed_sim_s=300.0, real_s=10.0, flood_s=2.0)


@dataclass(order=True)
class Event:
    t_s: float  # simulated seconds from the phase's start
    kind: str = field(compare=False)  # what the service should count it as
    lines: tuple[bytes, ...] = field(compare=False)  # one datagram each


def aton_reports(rng: random.Random) -> list[AtonReport]:
    """The 200 + 5 AtoNs around the default home, every kind, a few names needing the extension."""
    kinds = list(AID_TYPE_OF_KIND.values())
    reports = []
    for i in range(ATONS + FAST_ATONS):
        name = f"BUOY {i:03d}" if i % 20 else f"OUTER HARBOUR APPROACH BUOY {i:03d}"
        lat = DEFAULT_HOME[0] + rng.uniform(-0.03, 0.03)
        lon = DEFAULT_HOME[1] + rng.uniform(-0.04, 0.04)
        reports.append(AtonReport(992190000 + i, name, kinds[i % len(kinds)], lat, lon, False, False, False, i % 60))
    return reports


def traffic(duration_s: float, seed: int, atons: list[AtonReport], drag_at_s: float | None) -> list[Event]:
    """The module docstring's traffic over duration_s simulated seconds, sorted by time. The first AtoN's reports
    from drag_at_s on come from 60 m north, off-position flagged."""
    rng = random.Random(seed)
    events = []
    lines = [aton_line(r, "AB"[i % 2]) for i, r in enumerate(atons)]
    dragged = replace(atons[0], lat=atons[0].lat + DRAG_M / 111_200, off_position=True)
    for i, line in enumerate(lines):
        interval = REPORT_INTERVAL_S if i < ATONS else FAST_INTERVAL_S
        t = rng.uniform(0, interval)
        while t < duration_s:
            moved = i == 0 and drag_at_s is not None and t >= drag_at_s
            events.append(Event(t, "aton", (aton_line(dragged) if moved else line,)))
            t += interval
    positions = [POSITION_REPORT_1, *(message_type_line(1 + 2 * (v % 2), 211000000 + v) for v in range(VESSELS))]
    for _ in range(int(duration_s * VESSELS / POSITION_INTERVAL_S)):
        events.append(Event(rng.uniform(0, duration_s), "other_type", (rng.choice(positions),)))
    for n in range(int(duration_s * VESSELS / STATIC_INTERVAL_S / 2)):  # two vessels' messages at a time
        a = static_data_parts(211000000 + 2 * n % VESSELS, seq_id=n % 10, channel="A")
        b = static_data_parts(211000001 + 2 * n % VESSELS, seq_id=(n + 1) % 10, channel="A")
        events.append(Event(rng.uniform(0, duration_s), "static_pair", (a[0], b[1], b[0], a[1])))
    for kind, per_s in NOISE_PER_S.items():
        for n in range(int(duration_s * per_s)):
            if kind == "bad_checksum":
                line = bad_checksum(rng.choice(lines))
            elif kind == "malformed":
                noise = bytes(rng.randrange(32, 127) for _ in range(40))  # printable: no line end inside
                line = f"$GPXXX,noise {n}".encode() if n % 2 else b"x" + noise
            else:
                line = sentence(rng.choice("NOPQR") + "0" * 20).encode()  # message types 30-34
            events.append(Event(rng.uniform(0, duration_s), kind, (line,)))
    return sorted(events)


def expected_counts(events: list[Event]) -> dict[str, int]:
    """What the service's counts of the source should rise by."""
    count = {"decoded": 0, "other_type": 0, "bad_checksum": 0, "malformed": 0, "unknown_type": 0, "parts": 0}
    for event in events:
        if event.kind == "aton":
            count["decoded"] += 1
        elif event.kind == "static_pair":
            count["other_type"] += 2
            count["parts"] += 4
        else:
            count[event.kind] += len(event.lines)
    count["lines"] = sum(len(e.lines) for e in events)
    return count


# ----- the service's process
def cpu_s(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")  # utime + stime


def memory_mb(pid: int) -> dict[str, float]:
    status = dict(
        line.split(":", 1) for line in Path(f"/proc/{pid}/status").read_text().splitlines() if line.startswith("Vm")
    )
    return {key: round(int(status[key].split()[0]) / 1024, 1) for key in ("VmRSS", "VmHWM")}


@dataclass
class Service:
    process: subprocess.Popen
    base: str
    ais_port: int

    @property
    def pid(self) -> int:
        return self.process.pid


def start_service(tmp: Path, log) -> Service:
    http, ais, vehicle = free_tcp_port(), free_udp_port(), free_udp_port()
    argv = [sys.executable, "-m", "gcs", "serve", "--vehicle", f"udpout:127.0.0.1:{vehicle}", "--port", str(http)]
    argv += ["--db", str(tmp / "gcs.sqlite"), "--ais", f"udp://127.0.0.1:{ais}"]
    process = subprocess.Popen(argv, stdout=log, stderr=subprocess.STDOUT, cwd=REPO)
    return Service(process, f"http://127.0.0.1:{http}", ais)


async def wait_ready(client: httpx.AsyncClient, service: Service) -> None:
    deadline = time.monotonic() + 300  # the planner's kernels load (or compile, on a cold cache) first
    while time.monotonic() < deadline:
        assert service.process.poll() is None, "the service exited"
        try:
            if (await client.get("/ais/sources")).json()[0]["connected"]:
                return
        except (httpx.HTTPError, IndexError, KeyError):
            pass
        await asyncio.sleep(0.3)
    raise TimeoutError("the service did not start")


async def source_counts(client: httpx.AsyncClient) -> dict[str, int]:
    return (await client.get("/ais/sources")).json()[0]["counts"]


# ----- the phases
@dataclass
class Measure:
    wall_s: float
    cpu_s: float

    @property
    def cpu_pct(self) -> float:
        return 100.0 * self.cpu_s / self.wall_s


async def measured(pid: int, work) -> tuple[Measure, object]:
    cpu0, wall0 = cpu_s(pid), time.monotonic()
    result = await work
    return Measure(time.monotonic() - wall0, cpu_s(pid) - cpu0), result


async def send_traffic(sock: socket.socket, port: int, events: list[Event], compression: float, on_sent=None) -> None:
    """Each event's datagrams at its simulated time divided by the compression (wall seconds from now)."""
    start = time.monotonic()
    for event in events:
        delay = start + event.t_s / compression - time.monotonic()
        if delay > 0.002:
            await asyncio.sleep(delay)
        for line in event.lines:
            sock.sendto(line, ("127.0.0.1", port))
        if on_sent is not None:
            await on_sent(event)


class DragWatch:
    """After the dragged AtoN's first off-position report is sent: poll GET /ais/atons until it shows flagged."""

    def __init__(self, client: httpx.AsyncClient, mmsi: int) -> None:
        self.client, self.mmsi = client, mmsi
        self.sent = 0  # its reports sent so far
        self.result: dict | None = None

    async def on_sent(self, event: Event) -> None:
        if event.kind != "aton" or event.lines[0] not in self._lines:
            return
        self.sent += 1
        if self.result is None and event.lines[0] == self._off_line:
            sent_at = time.monotonic()
            while time.monotonic() - sent_at < 10:
                atons = (await self.client.get("/ais/atons")).json()["atons"]
                row = next((a for a in atons if a["mmsi"] == self.mmsi), None)
                if row is not None and row["off_position"]:
                    self.result = {
                        "flagged": True,
                        "reports_sent": self.sent,
                        "reports_seen": row["reports"],
                        "within_one_report": row["reports"] == self.sent,
                        "off_position_valid": row["off_position_valid"],
                        "latency_ms": round(1000 * (time.monotonic() - sent_at), 1),
                    }
                    return
                await asyncio.sleep(0.02)
            self.result = {"flagged": False, "reports_sent": self.sent}

    def watch(self, normal: bytes, off: bytes) -> DragWatch:
        self._lines, self._off_line = {normal, off}, off
        return self


def flood_sender(port: int, seconds: float, sent: multiprocessing.sharedctypes.Synchronized) -> None:
    """In a process of its own (so the probes' latency is the service's, not this sender's): as many datagrams as
    it gets out for `seconds`."""
    count, end = 0, time.monotonic() + seconds
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.setblocking(False)
        while time.monotonic() < end:
            for _ in range(1000):
                try:
                    sock.sendto(POSITION_REPORT_1, ("127.0.0.1", port))
                    count += 1
                except BlockingIOError:
                    break
    sent.value = count


async def probe_latency(client: httpx.AsyncClient, seconds: float) -> list[float]:
    """GET /ais/sources every 100 ms for `seconds`: each request's round trip."""
    latencies, end = [], time.monotonic() + seconds
    while time.monotonic() < end:
        started = time.perf_counter()
        await client.get("/ais/sources")
        latencies.append(time.perf_counter() - started)
        await asyncio.sleep(0.1)
    return latencies


def latency_ms(latencies: list[float]) -> dict[str, float]:
    return {
        "probe_ms_p50": round(1000 * statistics.median(latencies), 1),
        "probe_ms_max": round(1000 * max(latencies), 1),
    }


async def flood(port: int, seconds: float, client: httpx.AsyncClient) -> dict:
    """The flood from a sender process, GET /ais/sources timed every 100 ms beside it."""
    sent = multiprocessing.Value("q", 0)
    sender = multiprocessing.Process(target=flood_sender, args=(port, seconds, sent))
    sender.start()
    latencies = await probe_latency(client, seconds)
    await asyncio.to_thread(sender.join)
    return {"lines_sent": sent.value, "lines_per_s": round(sent.value / seconds)} | latency_ms(latencies)


def diff(after: dict[str, int], before: dict[str, int]) -> dict[str, int]:
    return {key: after[key] - before[key] for key in after}


async def run(mode: Mode, compression: float, seed: int, tmp: Path) -> dict:
    rng = random.Random(seed)
    atons = aton_reports(rng)
    real_lines_s = sum(len(e.lines) for e in traffic(3600.0, seed, atons, None)) / 3600.0
    results: dict = {"compression": compression, "cpus": os.cpu_count(), "atons": ATONS + FAST_ATONS}
    results["traffic_real_lines_per_s"] = round(real_lines_s, 2)
    with open(tmp / "service.log", "w") as log:
        service = start_service(tmp, log)
        try:
            async with httpx.AsyncClient(base_url=service.base, timeout=30) as client:
                await wait_ready(client, service)
                results["memory_start_mb"] = memory_mb(service.pid)
                with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
                    sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, 1 << 20)
                    # 1. idle (then GET /ais/sources' latency when nothing else happens, for the flood's)
                    idle, _ = await measured(service.pid, asyncio.sleep(mode.idle_s))
                    results["idle"] = {"wall_s": round(idle.wall_s, 1), "cpu_pct": round(idle.cpu_pct, 3)}
                    results["idle"] |= latency_ms(await probe_latency(client, 2.0))
                    # 2. compressed
                    events = traffic(mode.compressed_sim_s, seed, atons, drag_at_s=mode.compressed_sim_s / 2)
                    dragged = replace(atons[0], lat=atons[0].lat + DRAG_M / 111_200, off_position=True)
                    watch = DragWatch(client, atons[0].mmsi).watch(aton_line(atons[0], "A"), aton_line(dragged))
                    before = await source_counts(client)
                    work = send_traffic(sock, service.ais_port, events, compression, watch.on_sent)
                    compressed, _ = await measured(service.pid, work)
                    await asyncio.sleep(0.5)
                    got = diff(await source_counts(client), before)
                    want = expected_counts(events)
                    lines = want["lines"]
                    per_line_ms = (compressed.cpu_s - idle.cpu_s / idle.wall_s * compressed.wall_s) / lines * 1000
                    document = (await client.get("/ais/atons")).json()
                    listed = {a["mmsi"] for a in document["atons"]}
                    results["compressed"] = {
                        "simulated_s": mode.compressed_sim_s,
                        "wall_s": round(compressed.wall_s, 1),
                        "lines": lines,
                        "lines_per_s": round(lines / compressed.wall_s, 1),
                        "cpu_pct": round(compressed.cpu_pct, 2),
                        "cpu_ms_per_line": round(per_line_ms, 4),
                        "counts_expected": want,
                        "counts_seen": {k: got[k] for k in (*want, "rate_dropped", "parts_dropped")},
                        "counts_match": all(got[k] == v for k, v in want.items()) and got["rate_dropped"] == 0,
                        "every_aton_listed": listed == {a.mmsi for a in atons},
                        "stale": sum(a["stale"] for a in document["atons"]),
                        "conflicts": len(document["conflicts"]),
                        "off_position": watch.result,
                        "memory_mb": memory_mb(service.pid),
                    }
                    idle_pct = idle.cpu_pct
                    results["estimate_real_rate_cpu_pct"] = round(idle_pct + per_line_ms / 1000 * real_lines_s * 100, 3)
                    # 3. real rate
                    events = traffic(mode.real_s, seed + 1, atons, None)
                    real, _ = await measured(service.pid, send_traffic(sock, service.ais_port, events, 1.0))
                    results["real_rate"] = {
                        "wall_s": round(real.wall_s, 1),
                        "lines": sum(len(e.lines) for e in events),
                        "cpu_pct": round(real.cpu_pct, 3),
                        "cpu_pct_above_idle": round(real.cpu_pct - idle_pct, 3),
                    }
                    # 4. flood
                    before = await source_counts(client)
                    flooded, probe = await measured(service.pid, flood(service.ais_port, mode.flood_s, client))
                    await asyncio.sleep(0.5)
                    got = diff(await source_counts(client), before)
                    results["flood"] = probe | {
                        "wall_s": round(flooded.wall_s, 1),
                        "cpu_pct": round(flooded.cpu_pct, 1),
                        "lines_parsed": got["lines"] - got["rate_dropped"],
                        "rate_dropped": got["rate_dropped"],
                        "kernel_dropped": got["kernel_dropped"],
                        "memory_mb": memory_mb(service.pid),
                    }
        finally:
            stop_process(service.process, 15)
    results["target_pct"] = TARGET_PCT
    results["meets_target"] = results["estimate_real_rate_cpu_pct"] < TARGET_PCT
    return results


def report(r: dict) -> None:
    c, real, fl = r["compressed"], r["real_rate"], r["flood"]
    print(f"AIS feed: {r['atons']} AtoNs + a harbour receiver's traffic, {r['traffic_real_lines_per_s']} lines/s real")
    rows = [
        ("idle (feed listening, nothing sent)", f"{r['idle']['cpu_pct']:.3f} %", f"{r['idle']['wall_s']} s", ""),
        (
            f"compressed x{r['compression']:g} ({c['simulated_s']:g} s simulated)",
            f"{c['cpu_pct']:.2f} %",
            f"{c['wall_s']} s",
            f"{c['lines_per_s']} lines/s, {c['cpu_ms_per_line']} ms CPU/line",
        ),
        ("estimate at the real rate", f"{r['estimate_real_rate_cpu_pct']:.3f} %", "", f"target < {r['target_pct']} %"),
        ("real rate, measured", f"{real['cpu_pct']:.3f} %", f"{real['wall_s']} s", f"{real['lines']} lines"),
        (
            "flood",
            f"{fl['cpu_pct']:.1f} %",
            f"{fl['wall_s']} s",
            f"{fl['lines_per_s']} lines/s sent, {fl['lines_parsed']} parsed, GET p50/max "
            f"{fl['probe_ms_p50']}/{fl['probe_ms_max']} ms (idle {r['idle']['probe_ms_p50']}/"
            f"{r['idle']['probe_ms_max']})",
        ),
    ]
    print(f"{'phase':44} {'CPU (1 core)':>12} {'wall':>8}  notes")
    for row in rows:
        print(f"{row[0]:44} {row[1]:>12} {row[2]:>8}  {row[3]}")
    drag = c["off_position"] or {}
    print(
        f"every AtoN listed: {c['every_aton_listed']}, counts match: {c['counts_match']}, stale: {c['stale']}, "
        f"conflicts: {c['conflicts']}; off position flagged within one report: {drag.get('within_one_report')} "
        f"({drag.get('latency_ms')} ms after sending)"
    )
    print(
        f"memory: RSS {r['memory_start_mb']['VmRSS']} MB at start, {c['memory_mb']['VmRSS']} after the compressed "
        f"run, {fl['memory_mb']['VmRSS']} after the flood (peak {fl['memory_mb']['VmHWM']} MB)"
    )


def main() -> int:
    parser = argparse.ArgumentParser(prog="python -m bench.ais_feed", description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="short phases; writes nothing")
    parser.add_argument("--compression", type=float, default=15.0, help="simulated time / wall time (default 15)")
    parser.add_argument("--seed", type=int, default=22)
    args = parser.parse_args()
    started = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="bench_ais_") as tmp:
        results = asyncio.run(run(QUICK if args.quick else FULL, args.compression, args.seed, Path(tmp)))
    results["bench_wall_s"] = round(time.monotonic() - started, 1)
    results["load_average_1min"] = round(os.getloadavg()[0], 2)
    report(results)
    if args.quick:
        print(f"--quick: nothing written ({results['bench_wall_s']} s)")
        return 0
    RESULTS.mkdir(exist_ok=True)
    path = RESULTS / "ais_feed.json"
    path.write_text(json.dumps(results, indent=2) + "\n")
    print(f"written {path.relative_to(REPO)} ({results['bench_wall_s']} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
