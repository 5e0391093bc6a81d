"""The simulated world's AIS: the world file's `mmsi` (uavcore.buoy_world), the reports its buoys make
(sitl_quad.ais_station: every 3 minutes of simulated time, staggered, from where each buoy floats, off-position
outside the charted swing circle; virtual AtoNs), and `python -m sitl_quad --ais-out` sending them over UDP."""

from __future__ import annotations

import json
import math
import socket
import time

import pytest

from sitl_quad.ais_station import AisStation, VirtualAton, VirtualAtonError
from sitl_quad.cli import main as sitl_main
from tests.sitl_process import SitlProcess
from uavcore.ais import REPORT_INTERVAL_S
from uavcore.ais_stream import AisStreamDecoder
from uavcore.buoy_world import World, WorldFileError, load_world
from uavcore.geodesy import LocalFrame

LAT, LON = 38.9210, 121.6630
CURRENT = (0.0, 0.0, 0.0, 1.0)  # World.positions' environment: no wind, a 1 m/s current flowing north


def feature(lat: float = LAT, lon: float = LON, **props) -> dict:
    return {"type": "Feature", "geometry": {"type": "Point", "coordinates": [lon, lat]}, "properties": props}


def world_file(*features: dict) -> dict:
    return {"type": "FeatureCollection", "features": list(features)}


WORLD = world_file(
    feature(id="P1", kind="port", mmsi=992191001),
    feature(LAT + 0.001, id="S2", kind="starboard", mmsi=992191002, offset_m=[30.0, 0.0]),  # dragged 30 m north
    feature(LAT + 0.002, id="N3", kind="north"),  # no AIS
    feature(LAT + 0.003, id="W4", kind="west", mmsi=992191004, offset_m=[4.0, 0.0]),  # mooring inside its circle
)


# ----- the world file's mmsi
def test_the_world_file_takes_an_mmsi_and_round_trips_it():
    world = load_world(WORLD)
    assert [b.mmsi for b in world.buoys] == [992191001, 992191002, None, 992191004]
    assert World.from_geojson(world.to_geojson()) == world
    assert "mmsi" not in world.to_geojson()["features"][2]["properties"]  # written only where present


@pytest.mark.parametrize(
    ("mmsi", "why"),
    [("992191001", "9-digit integer"), (True, "9-digit integer"), (12345, "9-digit integer"), (1.5e8, "9-digit")],
)
def test_a_bad_mmsi_is_refused_naming_the_feature(mmsi, why):
    with pytest.raises(WorldFileError, match=rf"feature 0 \(P1\): mmsi .*{why}"):
        load_world(world_file(feature(id="P1", kind="port", mmsi=mmsi)))


def test_two_buoys_with_one_mmsi_are_refused():
    with pytest.raises(WorldFileError, match="feature 1 \\(P2\\): mmsi 992191001 is already feature 0's"):
        load_world(
            world_file(feature(id="P1", kind="port", mmsi=992191001), feature(id="P2", kind="port", mmsi=992191001))
        )


# ----- the reports (pure)
def test_each_transmitter_reports_every_interval_at_its_own_offset():
    station = AisStation(load_world(WORLD), (VirtualAton(992199001, LAT, LON + 0.01, "NEW WRECK"),))
    assert station.transmitters == 4  # three buoys with an mmsi and the virtual AtoN
    heard: dict[int, list[float]] = {}
    for step in range(int(3 * REPORT_INTERVAL_S / 0.02) + 1):  # three intervals of 50 Hz ticks
        t = step * 0.02
        for report in station.due(t, 1.7e9 + t, *CURRENT):
            heard.setdefault(report.mmsi, []).append(round(t, 2))
    offsets = [0.0, 45.0, 90.0, 135.0]  # 180 s / 4 transmitters
    expected = {mmsi: [o + k * REPORT_INTERVAL_S for k in range(4)] for mmsi, o in
                zip((992191001, 992191002, 992191004, 992199001), offsets, strict=True)}  # fmt: skip
    assert heard == {mmsi: [t for t in times if t <= 3 * REPORT_INTERVAL_S] for mmsi, times in expected.items()}


def test_a_stalled_clock_skips_the_reports_it_missed():
    station = AisStation(load_world(world_file(feature(id="P1", kind="port", mmsi=992191001))))
    assert len(station.due(0.0, 0.0)) == 1
    assert len(station.due(1000.0, 1000.0)) == 1  # five intervals late: one report, not five
    assert station.due(1079.0, 0.0) == [] and len(station.due(1080.0, 0.0)) == 1  # back on its 180 s grid


def test_reports_come_from_where_the_buoys_float_and_flag_those_outside_their_charted_circle():
    world = load_world(WORLD)
    station = AisStation(world)
    t = 3600.0
    station._next = [t] * station.transmitters  # all due now
    reports = {r.mmsi: r for r in station.due(t, 1_699_999_980.0 + 42.4, *CURRENT)}
    truth = world.positions_lat_lon(t, *CURRENT)
    for index, mmsi in ((0, 992191001), (1, 992191002), (3, 992191004)):
        assert (reports[mmsi].lat, reports[mmsi].lon) == pytest.approx(tuple(truth[index]), abs=1e-9)
    p1, s2, w4 = reports[992191001], reports[992191002], reports[992191004]
    assert not p1.off_position  # swinging in its circle
    assert s2.off_position  # dragged 30 m off station
    assert w4.off_position  # its mooring is inside the circle, but the current carries it out of it
    north_of_charted = world.positions(t, *CURRENT)[3][0]
    assert north_of_charted > world.buoys[3].swing_radius_m
    assert (p1.name, p1.aid_type_name, p1.second, p1.virtual) == ("P1", "port_hand_mark", 42, False)
    assert s2.aid_type_name == "starboard_hand_mark" and w4.aid_type_name == "cardinal_mark_w"


def test_a_virtual_aton_is_reported_where_it_is_charted_with_its_flag():
    aton = VirtualAton.parse("992199001,38.93,121.67,New wreck,isolated_danger")
    (report,) = AisStation(World(()), (aton,)).due(0.0, 0.0)
    assert (report.mmsi, report.name, report.lat, report.lon) == (992199001, "NEW WRECK", 38.93, 121.67)
    assert report.virtual and not report.off_position and report.aid_type_name == "isolated_danger"
    for bad in ("992199001,38.93", "x,38.93,121.67", "992199001,91,0", "992199001,1,2,N,cone", "12,1,2"):
        with pytest.raises(VirtualAtonError):
            VirtualAton.parse(bad)


def test_the_cli_refuses_ais_options_with_nothing_to_report(tmp_path, capsys):
    world = tmp_path / "world.geojson"
    world.write_text(json.dumps(world_file(feature(id="N3", kind="north"))))
    assert sitl_main(["--world", str(world), "--ais-out", "127.0.0.1:10110"]) == 2
    assert "nothing to report" in capsys.readouterr().err
    assert sitl_main(["--ais-virtual", "992199001,38.93,121.67"]) == 2
    assert "needs --ais-out" in capsys.readouterr().err
    assert sitl_main(["--ais-out", "127.0.0.1:10110", "--ais-virtual", "1,2,3"]) == 2
    assert "9-digit" in capsys.readouterr().err


# ----- the vehicle process sending them
@pytest.mark.integration  # starts the vehicle; loopback UDP
def test_the_vehicle_sends_its_worlds_aton_reports_over_udp(tmp_path):
    world_path = tmp_path / "world.geojson"
    world_path.write_text(json.dumps(WORLD))
    world = load_world(WORLD)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as receiver:
        receiver.bind(("127.0.0.1", 0))
        receiver.settimeout(1.0)
        ais = ("--ais-out", f"127.0.0.1:{receiver.getsockname()[1]}", "--ais-virtual", "992199001,38.93,121.67,WRECK")
        args = ("--world", str(world_path), "--no-camera", "--current", "0,1.0", *ais)
        vehicle = SitlProcess(speed=100.0, extra_args=args).start(timeout=180.0)
        try:
            decoder, reports = AisStreamDecoder(), {}
            deadline = time.monotonic() + 120.0  # 180 simulated seconds at whatever pace the machine allows
            while len(reports) < 4 and time.monotonic() < deadline:
                try:
                    datagram, _ = receiver.recvfrom(65535)
                except TimeoutError:
                    continue
                for report in decoder.feed_datagram(datagram, time.monotonic()):
                    reports.setdefault(report.mmsi, report)
            assert vehicle.alive(), vehicle.stderr()
        finally:
            vehicle.stop()
    assert sorted(reports) == [992191001, 992191002, 992191004, 992199001], vehicle.stderr()
    assert decoder.counts.bad_checksum == decoder.counts.malformed == 0
    for index in (0, 1, 3):
        buoy, report = world.buoys[index], reports[world.buoys[index].mmsi]
        # the reported position is the buoy's true one: within its swing circle around its real mooring
        north, east, _ = LocalFrame(*buoy.charted).to_ned(report.lat, report.lon)
        assert math.hypot(north - buoy.offset_m[0], east - buoy.offset_m[1]) <= buoy.swing_radius_m + 0.5
        assert report.name == buoy.id and not report.virtual
    assert not reports[992191001].off_position and reports[992191002].off_position
    assert reports[992199001].virtual and reports[992199001].name == "WRECK"
    assert vehicle.returncode == 0 and "Traceback" not in vehicle.stderr()
