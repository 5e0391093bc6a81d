"""The AIS feed: every --ais source's receiver, and the table of the AtoNs they heard (gcs.domain.aton_table), as the
service starts, stops and shows them (GET /ais/atons, GET /ais/sources). Runs on the service's event loop."""

from __future__ import annotations

import time
from collections.abc import Sequence
from datetime import UTC, datetime

from gcs.ais.receivers import AisReceiver, TcpReceiver, UdpReceiver
from gcs.domain.ais import AisConflictOut, AisCountsOut, AisSourceOut, AtonOut, AtonsOut, parse_ais_source
from gcs.domain.aton_table import AtonState, AtonTable, HeardReport
from uavcore.ais import AtonReport
from uavcore.ais_stream import StreamLimits


def _utc(unix_s: float | None) -> datetime | None:
    return None if unix_s is None else datetime.fromtimestamp(unix_s, UTC)


class AisFeed:
    """Listens to the sources given (udp://HOST:PORT, tcp://HOST:PORT; none: a feed that hears nothing)."""

    def __init__(
        self, sources: Sequence[str], stale_after_s: float = 420.0, limits: StreamLimits | None = None
    ) -> None:
        self.stale_after_s = stale_after_s
        self.table = AtonTable(stale_after_s)
        limits = limits or StreamLimits()
        self.receivers: list[AisReceiver] = []
        for text in sources:
            source = parse_ais_source(text)
            url = str(source)

            def heard(report: AtonReport, url: str = url) -> None:
                self.table.add(HeardReport(report, url, time.time(), time.monotonic()))

            if source.kind == "udp":
                self.receivers.append(UdpReceiver(source, limits, heard))
            else:  # a TCP feed silent for two stale periods is taken for a dead connection and reopened
                self.receivers.append(TcpReceiver(source, limits, heard, idle_timeout_s=2 * stale_after_s))

    async def start(self) -> None:
        for receiver in self.receivers:
            await receiver.start()

    async def stop(self) -> None:
        for receiver in self.receivers:
            await receiver.stop()

    def atons(self) -> AtonsOut:
        """Each AtoN's latest report with its age (stale past stale_after_s), and the MMSIs in conflict."""
        states = self.table.atons(time.monotonic())
        conflicts = AtonTable.conflicts(states)
        return AtonsOut(
            stale_after_s=self.stale_after_s,
            atons=[_aton_out(state) for state in states],
            conflicts=[
                AisConflictOut(mmsi=mmsi, atons=[_aton_out(s) for s in same]) for mmsi, same in conflicts.items()
            ],
        )

    def sources(self) -> list[AisSourceOut]:
        now = time.monotonic()
        return [self._source_out(receiver, now) for receiver in self.receivers]

    def _source_out(self, receiver: AisReceiver, now: float) -> AisSourceOut:
        age = None if receiver.last_line_mono is None else max(0.0, now - receiver.last_line_mono)
        return AisSourceOut(
            url=str(receiver.source),
            kind=receiver.source.kind,
            connected=receiver.connected,
            error=None if receiver.connected else receiver.error,
            connections=receiver.connections,
            last_line_at=_utc(receiver.last_line_at),
            last_line_age_s=age,
            silent=age is None or age > self.stale_after_s,
            counts=AisCountsOut(**receiver.decoder.counts.as_dict(), kernel_dropped=receiver.kernel_dropped),
        )


def _aton_out(state: AtonState) -> AtonOut:
    heard, report = state.latest, state.latest.report
    return AtonOut(
        mmsi=report.mmsi,
        name=report.name,
        aid_type=report.aid_type,
        aid_type_name=report.aid_type_name,
        lat=report.lat,
        lon=report.lon,
        position_accuracy=report.position_accuracy,
        off_position=report.off_position,
        off_position_valid=report.off_position_valid,
        virtual=report.virtual,
        second=report.second,
        dimensions_m=report.dimensions_m,
        station=report.station,
        station_time=_utc(report.station_time),
        source=heard.source,
        received_at=datetime.fromtimestamp(heard.received_at, UTC),
        age_s=state.age_s,
        stale=state.stale,
        reports=state.reports,
        conflict=state.conflict,
    )
