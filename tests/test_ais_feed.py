"""The AIS feed (gcs.ais) over real loopback sockets: a UDP listener and a TCP client that reconnects, staleness of
a silent feed, duplicate MMSIs reported apart, and a flood that leaves the event loop responsive. The AtoN table's
rules are also checked alone (gcs.domain.aton_table). No mocks: datagrams and connections are real."""

from __future__ import annotations

import asyncio
import contextlib
import random
import socket
import time
from collections.abc import Awaitable, Callable

import pytest

from bench.ais_sentences import (
    DFO2_PARTS,
    POSITION_REPORT_1,
    SF_BAY_BRIDGE_VIRTUAL,
    aton_line,
    bad_checksum,
    sentence,
    tag_block,
)
from bench.processes import free_port
from gcs.ais.feed import AisFeed
from gcs.domain.ais import AisSourceError, parse_ais_source
from gcs.domain.aton_table import MAX_PER_MMSI, AtonTable, HeardReport, distance_m
from uavcore.ais import AtonReport
from uavcore.ais_stream import StreamLimits

WAIT_S = 20.0  # a deadline only a failure reaches


def buoy(mmsi: int, name: str = "", lat: float = 55.7, lon: float = 12.6, off: bool = False) -> AtonReport:
    return AtonReport(mmsi, name or f"BUOY {mmsi % 1000}", 24, lat, lon, False, off, False, 7)


async def until(condition: Callable[[], bool], what: str, timeout_s: float = WAIT_S) -> None:
    deadline = time.monotonic() + timeout_s
    while not condition():
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        await asyncio.sleep(0.02)


async def with_feed(sources: list[str], body: Callable[[AisFeed], Awaitable[None]], **options) -> None:
    feed = AisFeed(sources, **options)
    await feed.start()
    try:
        await body(feed)
    finally:
        await feed.stop()


def mmsis(feed: AisFeed) -> list[int]:
    return [aton.mmsi for aton in feed.atons().atons]


# ----- sources
def test_ais_sources_as_receivers_and_shore_stations_are_named():
    assert str(parse_ais_source("udp://0.0.0.0:10110")) == "udp://0.0.0.0:10110"
    assert str(parse_ais_source("udp://:10110")) == "udp://0.0.0.0:10110"
    assert str(parse_ais_source("TCP://ais.example.org:5631")) == "tcp://ais.example.org:5631"
    assert str(parse_ais_source("tcp://[::1]:5631")) == "tcp://[::1]:5631"
    for bad, why in [("udp://0.0.0.0", "port"), ("tcp://:5631", "host"), ("http://x:1", "scheme"), ("x", "scheme")]:
        with pytest.raises(AisSourceError, match=why):
            parse_ais_source(bad)


# ----- the table's rules, alone
def heard(report: AtonReport, at: float, source: str = "udp://0.0.0.0:10110") -> HeardReport:
    return HeardReport(report, source, 1.7e9 + at, at)


def test_a_buoy_drifting_in_its_swing_circle_stays_one_aton_and_goes_stale_when_silent():
    table = AtonTable(stale_after_s=420.0)
    table.add(heard(buoy(992191001), 0.0))
    table.add(heard(buoy(992191001, lat=55.70005), 180.0))  # 5.6 m further: the same buoy
    (state,) = table.atons(200.0)
    assert (state.reports, state.age_s, state.stale, state.conflict) == (2, 20.0, False, False)
    assert state.latest.report.lat == 55.70005
    (state,) = table.atons(181.0 + 420.0)
    assert state.stale and state.age_s == pytest.approx(421.0)


def test_an_mmsi_two_atons_report_is_a_conflict_not_a_merge():
    table = AtonTable(stale_after_s=420.0, conflict_distance_m=500.0)
    table.add(heard(buoy(992191001, "NORTH PIER"), 0.0))
    table.add(heard(buoy(992191001, "SOUTH PIER"), 1.0))  # another name
    table.add(heard(buoy(992191002, "WRECK", lat=55.70), 2.0))
    table.add(heard(buoy(992191002, "WRECK", lat=55.71), 3.0))  # 1.1 km away: another transmitter
    table.add(heard(buoy(992191003), 4.0))
    states = table.atons(10.0)
    assert [(s.latest.report.mmsi, s.latest.report.name, s.conflict) for s in states] == [
        (992191001, "SOUTH PIER", True),
        (992191001, "NORTH PIER", True),
        (992191002, "WRECK", True),
        (992191002, "WRECK", True),
        (992191003, "BUOY 3", False),
    ]
    assert sorted(AtonTable.conflicts(states)) == [992191001, 992191002]
    # once one of them falls silent past the stale limit, the other is no longer in conflict with a live one
    table.add(heard(buoy(992191001, "SOUTH PIER"), 425.0))
    assert [s.conflict for s in table.atons(430.0) if s.latest.report.mmsi == 992191001] == [False, False]


def test_the_table_is_bounded_whatever_mmsis_arrive():
    table = AtonTable(max_atons=100, forget_after_s=3600.0)
    for n in range(5000):  # a flood of invented MMSIs
        table.add(heard(buoy(200000000 + n), n * 0.01))
    assert len(table) == 100 and table.evicted == 4900
    assert [s.latest.report.mmsi for s in table.atons(50.0)] == list(range(200004900, 200005000))  # the newest
    for n in range(10):  # names that keep changing under one MMSI
        table.add(heard(buoy(992191009, f"NAME {n}"), 60.0 + n))
    assert sum(s.latest.report.mmsi == 992191009 for s in table.atons(80.0)) == MAX_PER_MMSI
    assert len(table.atons(60.0 + 3601.0 + 10)) == 0  # none heard for forget_after_s: forgotten


def test_distances_for_the_conflict_check():
    assert distance_m((55.0, 12.0), (55.01, 12.0)) == pytest.approx(1111.95, abs=0.1)
    assert distance_m((55.0, 12.0), (55.0, 12.0)) == 0.0


# ----- UDP
def send_udp(port: int, *datagrams: bytes, sock: socket.socket | None = None) -> None:
    with contextlib.ExitStack() as stack:
        if sock is None:
            sock = stack.enter_context(socket.socket(socket.AF_INET, socket.SOCK_DGRAM))
        for datagram in datagrams:
            sock.sendto(datagram, ("127.0.0.1", port))


@pytest.mark.integration  # loopback UDP
def test_the_udp_listener_decodes_what_receivers_send_and_counts_the_rest():
    port = free_port(socket.SOCK_DGRAM)
    off_station = buoy(992191001, "PORT NO 1 <B>", off=True)

    async def body(feed: AisFeed) -> None:
        await until(lambda: feed.sources()[0].connected, "the listener")
        with (
            socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as a,
            socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as b,
        ):
            # two receivers: the same two-part message id interleaved, each peer's parts apart, last part first
            send_udp(port, DFO2_PARTS[1], sock=a)
            send_udp(port, DFO2_PARTS[1], sock=b)
            send_udp(port, DFO2_PARTS[0], sock=b)
            send_udp(port, DFO2_PARTS[0], sock=a)
            # several sentences in one datagram, CR LF ended, noise among them
            noise = [bad_checksum(SF_BAY_BRIDGE_VIRTUAL), POSITION_REPORT_1, b"garbage", sentence("N00").encode()]
            send_udp(port, b"\r\n".join([*noise, aton_line(off_station), SF_BAY_BRIDGE_VIRTUAL]) + b"\r\n", sock=a)
        await until(lambda: mmsis(feed) == [316021442, 992191001, 993692028], "the AtoNs")
        await until(lambda: feed.atons().atons[0].reports == 2, "both peers' DFO2")
        dfo2, mine, bay = feed.atons().atons
        assert dfo2.off_position and dfo2.off_position_valid is False  # a reference point is no floating aid
        assert bay.virtual and not bay.stale and bay.source == f"udp://127.0.0.1:{port}"
        assert mine.name == "PORT NO 1 <B>" and mine.off_position and mine.off_position_valid and not mine.conflict
        (source,) = feed.sources()
        assert source.connected and source.kind == "udp" and source.last_line_age_s < 5 and not source.silent
        counts = source.counts
        assert (counts.decoded, counts.bad_checksum, counts.other_type, counts.malformed) == (4, 1, 1, 1)
        assert counts.unknown_type == 1 and counts.lines == 4 + 4 + 2
        assert counts.parts == 4 and counts.parts_dropped == 0 and counts.rate_dropped == 0

    asyncio.run(with_feed([f"udp://127.0.0.1:{port}"], body))


@pytest.mark.integration  # loopback UDP
def test_a_silent_feed_ages_and_its_reports_go_stale():
    port = free_port(socket.SOCK_DGRAM)

    async def body(feed: AisFeed) -> None:
        await until(lambda: feed.sources()[0].connected, "the listener")
        assert feed.sources()[0].silent and feed.sources()[0].last_line_age_s is None  # nothing heard yet
        send_udp(port, SF_BAY_BRIDGE_VIRTUAL)
        await until(lambda: bool(feed.atons().atons), "the report")
        assert not feed.atons().atons[0].stale and not feed.sources()[0].silent
        await asyncio.sleep(0.8)
        (aton,) = feed.atons().atons
        assert aton.stale and aton.age_s > 0.5
        (source,) = feed.sources()
        assert source.silent and source.last_line_age_s > 0.5

    asyncio.run(with_feed([f"udp://127.0.0.1:{port}"], body, stale_after_s=0.5))


@pytest.mark.integration  # loopback UDP
def test_a_udp_port_taken_is_an_error_the_listener_retries():
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as holder:
        holder.bind(("127.0.0.1", 0))
        port = holder.getsockname()[1]

        async def body(feed: AisFeed) -> None:
            await until(lambda: feed.sources()[0].error is not None, "the bind error")
            assert not feed.sources()[0].connected and "in use" in feed.sources()[0].error
            holder.close()
            await until(lambda: feed.sources()[0].connected, "the listener once the port is free")
            assert feed.sources()[0].error is None

        asyncio.run(with_feed([f"udp://127.0.0.1:{port}"], body))


async def loop_lag_during(work: Awaitable[None]) -> float:
    """The worst delay of a 10 ms ticker on the loop while work runs: how long the loop was kept busy."""
    worst = 0.0
    running = True

    async def ticker() -> None:
        nonlocal worst
        while running:
            before = time.monotonic()
            await asyncio.sleep(0.01)
            worst = max(worst, time.monotonic() - before - 0.01)

    task = asyncio.create_task(ticker())
    await work
    running = False
    await task
    return worst


@pytest.mark.integration  # loopback UDP
def test_a_udp_flood_is_bounded_to_the_rate_and_does_not_stall_the_loop():
    port = free_port(socket.SOCK_DGRAM)
    limits = StreamLimits(rate_lines_s=200.0, burst_lines=100.0)

    async def flood() -> None:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
            sock.setblocking(False)
            line = aton_line(buoy(992191001))
            for n in range(40_000):
                with contextlib.suppress(BlockingIOError):
                    sock.sendto(line, ("127.0.0.1", port))
                if n % 500 == 0:
                    await asyncio.sleep(0)  # the sender shares the loop: give the feed its turns
            await asyncio.sleep(1.0)

    async def body(feed: AisFeed) -> None:
        await until(lambda: feed.sources()[0].connected, "the listener")
        started = time.monotonic()
        lag = await loop_lag_during(flood())
        elapsed = time.monotonic() - started
        counts = feed.sources()[0].counts
        assert counts.decoded <= limits.burst_lines + limits.rate_lines_s * elapsed + 1
        assert counts.decoded >= 100  # it did decode: the bound is a rate, not a stop
        # what was read beyond the bucket was dropped unparsed; the rest the kernel dropped while reading paused
        assert counts.rate_dropped + feed.sources()[0].counts.kernel_dropped > 0
        assert counts.lines < 40_000  # reading paused: most of the flood never reached the loop
        assert lag < 0.5, f"the loop stalled {lag:.3f} s"  # a loaded machine delays a wake-up, never this long

    asyncio.run(with_feed([f"udp://127.0.0.1:{port}"], body, limits=limits))


# ----- TCP
class LineServer:
    """A TCP server as a shore station is: every client that connects gets the lines written to `send`."""

    def __init__(self, port: int = 0) -> None:
        self.port = port
        self.clients: list[asyncio.StreamWriter] = []
        self.server: asyncio.base_events.Server | None = None

    async def start(self) -> LineServer:
        self.server = await asyncio.start_server(self._client, "127.0.0.1", self.port, reuse_address=True)
        self.port = self.server.sockets[0].getsockname()[1]
        return self

    async def _client(self, _: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        self.clients.append(writer)

    async def send(self, *lines: bytes) -> None:
        for writer in self.clients:
            writer.write(b"".join(line + b"\r\n" for line in lines))
            await writer.drain()

    async def drop_clients(self) -> None:
        for writer in self.clients:
            writer.close()
        self.clients = []

    async def stop(self) -> None:
        await self.drop_clients()
        if self.server is not None:
            self.server.close()
            await self.server.wait_closed()


@pytest.mark.integration  # loopback TCP
def test_the_tcp_client_reads_a_shore_station_and_reconnects_when_dropped():
    async def scenario() -> None:
        server = await LineServer().start()
        url = f"tcp://127.0.0.1:{server.port}"

        async def body(feed: AisFeed) -> None:
            await until(lambda: bool(server.clients), "the connection")
            await server.send(
                DFO2_PARTS[1], tag_block("s:station,c:1700000000").encode() + SF_BAY_BRIDGE_VIRTUAL, DFO2_PARTS[0]
            )
            await until(lambda: len(feed.atons().atons) == 2, "both AtoNs")
            (source,) = feed.sources()
            assert source.connected and source.kind == "tcp" and source.connections == 1
            bay = next(a for a in feed.atons().atons if a.mmsi == 993692028)
            assert bay.source == url
            await server.drop_clients()  # the station drops us: we connect again, after a back-off
            await until(lambda: not feed.sources()[0].connected, "the drop noticed")
            assert "closed" in feed.sources()[0].error
            await until(lambda: bool(server.clients), "the reconnect")
            await server.send(aton_line(buoy(992191001)))
            await until(lambda: 992191001 in mmsis(feed), "a report over the new connection")
            assert feed.sources()[0].connections == 2
            await server.stop()  # the station goes away: refused, retried with growing back-off
            await until(lambda: not feed.sources()[0].connected and feed.sources()[0].error is not None, "refused")
            restarted = await LineServer(server.port).start()
            try:
                await until(lambda: bool(restarted.clients), "the reconnect to the restarted station")
                await restarted.send(aton_line(buoy(992191002)))
                await until(lambda: 992191002 in mmsis(feed), "a report from the restarted station")
                assert feed.sources()[0].connections == 3 and feed.sources()[0].error is None
            finally:
                await restarted.stop()

        await with_feed([url], body)

    asyncio.run(scenario())


@pytest.mark.integration  # loopback TCP
def test_a_tcp_flood_is_dropped_a_chunk_at_a_time_and_the_loop_stays_responsive():
    limits = StreamLimits(rate_lines_s=200.0, burst_lines=100.0)

    async def scenario() -> None:
        server = await LineServer().start()

        async def body(feed: AisFeed) -> None:
            await until(lambda: bool(server.clients), "the connection")
            lines = [aton_line(buoy(992191000 + random.Random(n).randrange(300))) for n in range(400)]

            async def flood() -> None:
                for _ in range(100):  # 40 000 lines, about 3.2 MB
                    await server.send(*lines)
                await until(lambda: feed.sources()[0].counts.lines >= 40_000, "every line counted")

            lag = await loop_lag_during(flood())
            counts = feed.sources()[0].counts
            assert counts.lines == 40_000 and counts.rate_dropped >= 35_000
            assert counts.decoded + counts.rate_dropped == counts.lines
            assert lag < 0.5, f"the loop stalled {lag:.3f} s"  # a loaded machine delays a wake-up, never this long

        try:
            await with_feed([f"tcp://127.0.0.1:{server.port}"], body, limits=limits)
        finally:
            await server.stop()

    asyncio.run(scenario())
