"""AIS decoding (uavcore.ais, uavcore.ais_stream): real-world message 21s, multi-part assembly in any order, tag
blocks, every fault counted and none raised, the memory and rate bounds. Pure: no sockets."""

from __future__ import annotations

import random
from dataclasses import replace

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bench.ais_sentences import (
    DFO2_PARTS,
    POSITION_REPORT_1,
    POSITION_REPORT_3,
    SF_BAY_BRIDGE_VIRTUAL,
    STATIC_DATA_5_PARTS,
    bad_checksum,
    fragments,
    sentence,
    tag_block,
)
from uavcore.ais import AID_TYPE_OF_KIND, AtonReport, ais_text, encode_aton_report
from uavcore.ais_stream import AisStreamDecoder, StreamLimits

UNLIMITED = StreamLimits(rate_lines_s=1e9, burst_lines=1e9)
BUOY = AtonReport(
    mmsi=992191001,
    name="HARBOUR APPROACH NO 1 LIGHT BUOY",  # 32 characters: 20 in the name, 12 in the extension
    aid_type=AID_TYPE_OF_KIND["port"],
    lat=55.712345,
    lon=12.601234,
    position_accuracy=True,
    off_position=True,
    virtual=False,
    second=42,
    dimensions_m=(1, 1, 1, 1),
    epfd=1,
)


def decoder(limits: StreamLimits = UNLIMITED) -> AisStreamDecoder:
    return AisStreamDecoder(limits)


def test_a_real_virtual_aton_decodes_with_its_flags():
    report = decoder().feed(SF_BAY_BRIDGE_VIRTUAL, 0.0)
    assert report is not None
    assert (report.mmsi, report.name, report.aid_type_name) == (
        993692028,
        "SF OAK BAY BR VAIS E",
        "beacon_special_mark",
    )
    assert report.virtual and not report.off_position
    assert report.lat == pytest.approx(37.805622) and report.lon == pytest.approx(-122.369867)
    assert report.second == 61 and not report.off_position_valid  # timestamp 61: manual input, no second


@pytest.mark.parametrize("order", [(0, 1), (1, 0)], ids=["in order", "last part first"])
def test_a_real_two_part_report_assembles_in_either_order(order):
    stream = decoder()
    first, second = (DFO2_PARTS[i] for i in order)
    assert stream.feed(first, 0.0) is None
    report = stream.feed(second, 0.1)
    assert report is not None
    assert (report.mmsi, report.name, report.aid_type_name) == (316021442, "DFO2", "reference_point")
    assert (report.lat, report.lon) == pytest.approx((48.65457, -123.429155))
    assert report.off_position and report.position_accuracy and report.second == 18 and not report.virtual
    assert stream.counts.decoded == 1 and stream.counts.parts == 2 and stream.pending_groups == 0


def test_every_field_of_a_report_survives_encoding_and_decoding_name_extension_included():
    (line,) = encode_aton_report(BUOY)
    assert line.startswith("!AIVDM,1,1,,A,E")
    decoded = decoder().feed(line.encode(), 0.0)
    assert (decoded.lat, decoded.lon) == pytest.approx((BUOY.lat, BUOY.lon), abs=1 / 600_000)  # 1/10000 minute
    assert replace(decoded, lat=BUOY.lat, lon=BUOY.lon) == BUOY


def test_a_report_without_a_position_and_a_short_name_is_the_272_bit_message():
    report = AtonReport(992191002, "B2", 25, None, None, False, False, True, 60)
    (line,) = encode_aton_report(report)
    assert len(line.split(",")[5]) == 46  # 272 bits + 4 fill bits: no 88 bits of "@" for an empty extension
    decoded = decoder().feed(line.encode(), 0.0)
    assert decoded == report and decoded.lat is None and decoded.virtual


def test_text_is_sent_as_ais_can_carry_it():
    assert ais_text("Bøje nr. 7 <b>") == "B?JE NR. 7 <B>"
    assert len(ais_text("X" * 50)) == 34


def test_interleaved_parts_of_messages_from_several_peers_and_channels_each_assemble():
    # two buoys' reports split into three parts each, with the SAME sequential id, sent by two peers, and a third
    # on channel B of the first peer: all interleaved and shuffled
    reports = [BUOY, *(AtonReport(992191000 + i, f"BUOY {i}", 24, 55.0 + i / 100, 12.0, False, False, False, i)
                       for i in (2, 3))]  # fmt: skip
    peers = [("10.0.0.1:10110", "A"), ("10.0.0.2:10110", "A"), ("10.0.0.1:10110", "B")]
    parts = [
        (origin, part)
        for report, (origin, channel) in zip(reports, peers, strict=True)
        for part in fragments(encode_aton_report(report, channel)[0], 3, seq_id=4, channel=channel)
    ]
    random.Random(7).shuffle(parts)
    stream = decoder()
    decoded = [r for origin, part in parts if (r := stream.feed(part, 0.0, origin)) is not None]
    assert sorted((r.mmsi, r.name, r.second) for r in decoded) == sorted((r.mmsi, r.name, r.second) for r in reports)
    assert stream.counts.parts == 9 and stream.counts.parts_dropped == 0


def test_a_tag_block_gives_the_shore_stations_name_and_time():
    line = (tag_block("s:2573535,c:1671533231") + SF_BAY_BRIDGE_VIRTUAL.decode()).encode()
    report = decoder().feed(line, 0.0)
    assert report is not None and (report.station, report.station_time) == ("2573535", 1671533231.0)
    in_ms = (tag_block("c:1671533231500,s:RX1") + SF_BAY_BRIDGE_VIRTUAL.decode()).encode()
    assert decoder().feed(in_ms, 0.0).station_time == pytest.approx(1671533231.5)


def test_a_tag_block_on_the_first_part_only_dates_the_whole_message():
    first = tag_block("g:1-2-0042,s:BS1,c:1700000000") + DFO2_PARTS[0].decode()
    second = tag_block("g:2-2-0042") + DFO2_PARTS[1].decode()
    stream = decoder()
    assert stream.feed(second.encode(), 0.0) is None
    report = stream.feed(first.encode(), 0.0)
    assert report is not None and (report.station, report.station_time, report.mmsi) == ("BS1", 1.7e9, 316021442)


def test_faults_are_counted_and_dropped_never_raised():
    stream = decoder()
    unknown_type = sentence("N0000000000000")  # message type 30: AIS defines 1-27
    lines = [
        bad_checksum(SF_BAY_BRIDGE_VIRTUAL),
        (tag_block("s:X,c:1")[:-3] + "00\\" + SF_BAY_BRIDGE_VIRTUAL.decode()).encode(),  # the tag block's sum
        SF_BAY_BRIDGE_VIRTUAL.rsplit(b"*", 1)[0],  # no checksum at all
        unknown_type.encode(),
        POSITION_REPORT_1,
        POSITION_REPORT_3,
        *STATIC_DATA_5_PARTS,
        b"$GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*47",  # NMEA, but no AIS
        b"hello world",
        b"!AIVDM,1,1",
        b"\xff\xfe\x00!AIVDM",
        sentence("E", parts=(1, 2)).encode(),  # part 2 of 1
        sentence("E1").encode(),  # a message 21 cut short: checksum right, fields missing
        b"!AIVDM," + b"0" * 600,
        b"",
        b"\r\n",
    ]
    for line in lines:
        assert stream.feed(line, 0.0) is None
    assert stream.counts.as_dict() == {
        "lines": 15,  # the blank ones are no lines
        "decoded": 0,
        "other_type": 3,  # 1, 3 and the two-part 5 (its two lines counted as parts)
        "unknown_type": 1,
        "bad_checksum": 3,
        "malformed": 6,  # GPGGA, three garbage lines, part 2 of 1, the cut message 21
        "too_long": 1,
        "rate_dropped": 0,
        "parts": 2,
        "parts_dropped": 0,
    }


@settings(max_examples=300, deadline=None)
@given(st.lists(st.binary(max_size=120) | st.sampled_from([SF_BAY_BRIDGE_VIRTUAL, *DFO2_PARTS, b"\\"]), max_size=20))
def test_no_input_raises(lines):
    stream = decoder(StreamLimits(max_groups=4, rate_lines_s=1e9, burst_lines=1e9))
    for n, line in enumerate(lines):
        stream.feed(line, n * 0.01, origin="peer")
        stream.feed_stream(line, n * 0.01)
    assert stream.pending_groups <= 4


def test_a_group_not_completed_in_time_is_dropped():
    stream = decoder(StreamLimits(group_timeout_s=5.0, rate_lines_s=1e9, burst_lines=1e9))
    assert stream.feed(DFO2_PARTS[0], 0.0) is None
    assert stream.feed(DFO2_PARTS[1], 5.5) is None  # its first part expired: this one starts a new group
    assert stream.counts.parts_dropped == 1 and stream.pending_groups == 1
    stream.expire(11.0)
    assert stream.counts.parts_dropped == 2 and stream.pending_groups == 0 and stream.counts.decoded == 0


def test_a_part_seen_twice_means_its_sequential_id_came_round_again():
    stream = decoder()
    stream.feed(DFO2_PARTS[0], 0.0)
    stream.feed(DFO2_PARTS[0], 0.5)  # the first group lost its second part; the id is reused
    assert stream.counts.parts_dropped == 1
    assert stream.feed(DFO2_PARTS[1], 0.6).mmsi == 316021442


def test_partial_groups_are_capped_oldest_first():
    stream = decoder(StreamLimits(max_groups=8, rate_lines_s=1e9, burst_lines=1e9))
    for n in range(1000):  # first parts of messages that never complete, from 1000 peers
        stream.feed(DFO2_PARTS[0], n * 1e-3, origin=f"10.0.{n // 256}.{n % 256}:1")
    assert stream.pending_groups == 8 and stream.counts.parts_dropped == 992
    assert stream.feed(DFO2_PARTS[1], 1.0, origin="10.0.3.231:1") is not None  # the newest still completes


def test_a_flood_is_cut_to_the_rate_and_counted():
    stream = decoder(StreamLimits(rate_lines_s=100.0, burst_lines=50.0))
    decoded = sum(stream.feed(SF_BAY_BRIDGE_VIRTUAL, 0.0) is not None for _ in range(10_000))
    assert decoded == 50 and stream.counts.rate_dropped == 9_950 and stream.throttled(0.0)
    assert stream.retry_after_s(0.0) == pytest.approx(0.01)
    assert stream.feed(SF_BAY_BRIDGE_VIRTUAL, 0.011) is not None  # the bucket refills at the rate
    later = sum(stream.feed(SF_BAY_BRIDGE_VIRTUAL, 0.011 + n / 200) is not None for n in range(1, 401))
    assert later == pytest.approx(200, abs=2)  # 2 s at 200 lines/s offered: the rate's 100 a second get through


def test_a_stream_is_split_into_lines_across_chunks_and_dropped_a_chunk_at_a_time_when_throttled():
    stream = decoder(StreamLimits(rate_lines_s=10.0, burst_lines=3.0, max_line_bytes=100))
    text = b"\r\n".join([SF_BAY_BRIDGE_VIRTUAL, *DFO2_PARTS]) + b"\r\n"
    reports = [r for i in range(0, len(text), 7) for r in stream.feed_stream(text[i : i + 7], 0.0)]
    assert [r.mmsi for r in reports] == [993692028, 316021442] and stream.throttled(0.0)
    flood = (SF_BAY_BRIDGE_VIRTUAL + b"\n") * 1000
    assert stream.feed_stream(flood, 0.0) == []
    assert stream.counts.rate_dropped == 1000 and stream.counts.lines == 1003
    # a line split over a throttled chunk and a free one is dropped, counted once; the next line is whole
    assert stream.feed_stream(SF_BAY_BRIDGE_VIRTUAL[:20], 0.0) == []
    assert [r.mmsi for r in stream.feed_stream(SF_BAY_BRIDGE_VIRTUAL[20:] + b"\n" + DFO2_PARTS[0], 1.0)] == []
    assert stream.counts.rate_dropped == 1001
    assert [r.mmsi for r in stream.feed_stream(b"\n" + DFO2_PARTS[1] + b"\n", 1.0)] == [316021442]


def test_a_line_longer_than_the_limit_is_dropped_up_to_its_end_in_a_stream():
    stream = decoder(StreamLimits(max_line_bytes=100, rate_lines_s=1e9, burst_lines=1e9))
    assert stream.feed_stream(b"!AIVDM," + b"x" * 150, 0.0) == []
    assert stream.feed_stream(b"y" * 10_000, 0.0) == []
    reports = stream.feed_stream(b"zzz\n" + SF_BAY_BRIDGE_VIRTUAL + b"\n", 0.0)
    assert [r.mmsi for r in reports] == [993692028]
    assert stream.counts.too_long == 1 and stream.counts.lines == 2
