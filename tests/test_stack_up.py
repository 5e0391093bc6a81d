"""`buoy-gcs up` (stack): the loops each controller starts, the weather the demo hands the vehicle, its figures.

No process is started here except one `python -m sitl_quad --list-params`, which checks that the vehicle takes
every parameter `up` gives it, one vehicle whose pace `up --real-time` sets over MAVLink, and one `up --real-time`.
"""

from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest
from conftest import connected
from sitl_process import GroundStation
from test_stack_ports import STACK_S, Up

from bench.lockstep_mission import LOCKSTEP_LINE
from bench.processes import free_tcp_port, free_udp_port_block
from gcs.settings import Settings
from planner.scenario import GUST_HOLD_S, Weather, compass_bearing_deg
from stack.children import children
from stack.cli import build_parser, main, requested_weather
from stack.demo import (
    LIGHT_OUT_AT,
    OFF_STATION_AT,
    OFF_STATION_RADII,
    ais_summary,
    demo_report,
    duration_text,
    findings_table,
    measure_flight,
    prepare,
)
from stack.options import CONTROLLERS, UpOptions
from stack.sim_speed import watch_at
from stack.supervisor import ChildSpec
from uavcore.buoy_world import load_world
from uavcore.mavlink import SIGNING_KEY_ENV


def _options(tmp_path, **kwargs) -> UpOptions:
    return UpOptions(settings=Settings(data_dir=tmp_path, vehicle_url="udpout:127.0.0.1:14600"), **kwargs)


def _vehicle_params(argv: list[str]) -> dict[str, float]:
    return {
        argv[i + 1].split("=")[0]: float(argv[i + 1].split("=")[1]) for i, arg in enumerate(argv) if arg == "--param"
    }


@pytest.mark.parametrize(
    "controller, attitude_loop, offboard",
    [("adrc", 1, ["--controller", "adrc"]), ("pid", 0, ["--controller", "pid"]), ("px4", 0, None)],
)
def test_each_controller_starts_its_loops(tmp_path, controller, attitude_loop, offboard):
    started = children(_options(tmp_path, controller=controller))
    names = [child.name for child in started]
    vehicle = started[0]
    assert _vehicle_params(vehicle.argv)["MC_ATT_CTRL"] == attitude_loop  # the vehicle's inner loop: 1 ADRC, 0 PID
    if offboard is None:
        assert names == ["sitl_quad", "gcs"]  # no offboard process: the vehicle's own position loop flies
    else:
        assert names == ["sitl_quad", "adrc_offboard", "gcs"]
        argv = started[1].argv
        assert argv[argv.index("--controller") :][:2] == offboard
        assert "udpout:127.0.0.1:14600" in argv


def test_a_fleet_is_a_vehicle_and_controller_per_system_id_and_one_service_linked_to_each(tmp_path):
    options = _options(tmp_path, vehicles=3, depots=((43.0, 6.0), (43.1, 6.1)), seed=5)
    started = children(options)
    names = [child.name for child in started]
    pairs = [f"{name}{suffix}" for suffix in ("", "-2", "-3") for name in ("sitl_quad", "adrc_offboard")]
    assert names == [*pairs, "gcs"]

    def option(argv, name):
        return argv[argv.index(name) + 1]

    vehicles = started[0:6:2]
    assert [option(v.argv, "--sysid") for v in vehicles] == ["1", "2", "3"]
    assert [option(v.argv, "--port") for v in vehicles] == ["14600", "14601", "14602"]
    assert [option(v.argv, "--seed") for v in vehicles] == ["5", "6", "7"]  # each its own air
    assert len({option(v.argv, "--params") for v in vehicles}) == 3
    homes = [tuple(float(x) for x in option(v.argv, "--home").split(",")) for v in vehicles]
    assert homes[0][:2] == pytest.approx((43.0, 6.0)) and homes[1][:2] == pytest.approx((43.1, 6.1))
    assert homes[2][0] == pytest.approx(43.0) and homes[2][1] > 6.0  # the first depot's second pad, east
    controllers = started[1:6:2]
    assert [option(c.argv, "--sysid") for c in controllers] == ["1", "2", "3"]
    assert [option(c.argv, "--connect") for c in controllers] == [
        f"udpout:127.0.0.1:{p}" for p in (14600, 14601, 14602)
    ]
    service = started[-1].argv
    links = [service[i + 1] for i, arg in enumerate(service) if arg == "--vehicle"]
    assert links == [f"{n}=udpout:127.0.0.1:{14599 + n}" for n in (1, 2, 3)]


def test_the_command_line_offers_exactly_the_controllers_and_adrc_is_the_default():
    parser = build_parser()
    assert parser.parse_args(["up"]).controller == "adrc"
    for controller in CONTROLLERS:
        assert parser.parse_args(["up", "--controller", controller]).controller == controller
    with pytest.raises(SystemExit):
        parser.parse_args(["up", "--controller", "none"])


def test_without_a_demo_the_air_is_still_and_every_weather_parameter_is_set(tmp_path):
    options, demo = prepare(_options(tmp_path))
    assert demo is None and options.weather == Weather()
    params = _vehicle_params(children(options)[0].argv)
    assert params["SIM_WIND_SPD"] == params["SIM_GUST_AMP"] == params["SIM_TURB_W20"] == 0.0
    assert params["SIM_GUST_HOLD"] == math.inf
    assert {"SIM_WIND_DIR", "SIM_GUST_T0", "SIM_GUST_RISE", "SIM_GUST_DIR", "SIM_DIST_VX", "SIM_DIST_VYAW"} <= set(
        params
    )


def test_the_demo_flies_the_papers_weather_placed_on_the_route_the_service_will_plan(tmp_path):
    options, demo = prepare(_options(tmp_path, demo=True))
    params = _vehicle_params(children(options)[0].argv)
    route = demo.plan.route_local()[:-1]  # [east, north]: the depot, then the buoys in visiting order
    legs = np.hypot(*np.diff(route, axis=0).T)
    longest = int(np.argmax(legs))
    bearing = compass_bearing_deg(route[longest], route[longest + 1])
    assert demo.placed.longest_leg == longest + 1
    # the crosswind: 5 m/s, perpendicular to the longest leg, from its right-hand side
    assert params["SIM_WIND_SPD"] == 5.0
    assert params["SIM_WIND_DIR"] == pytest.approx((bearing + 90.0) % 360.0, abs=1e-3)
    # the gust: 4 m/s along the crosswind, 1 s rise, held 10 s, starting while the longest leg is flown
    assert params["SIM_GUST_AMP"] == 4.0 and params["SIM_GUST_RISE"] == 1.0 and params["SIM_GUST_HOLD"] == GUST_HOLD_S
    assert params["SIM_GUST_DIR"] == params["SIM_WIND_DIR"]
    onset = params["SIM_GUST_T0"]
    assert onset == pytest.approx(demo.placed.leg_start_s + demo.placed.leg_duration_s / 2, abs=0.05)
    assert demo.placed.leg_start_s + 10.0 < onset < demo.placed.leg_start_s + demo.placed.leg_duration_s - 10.0
    # Dryden turbulence with sigma 1 m/s at 5 m, and the D terms
    assert params["SIM_TURB_W20"] == pytest.approx(5.152)
    assert params["SIM_DIST_VX"] == 0.05
    # the ADRC cascade by default; --calm and --wind replace the weather, the demo still flies
    assert params["MC_ATT_CTRL"] == 1
    # the camera sees the demo's world: the charted buoys of the request, two of them faulty
    argv = children(options)[0].argv
    world = load_world(argv[argv.index("--world") + 1])
    assert [(b.kind, b.light.abbreviation()) for b in world.buoys] == [
        (b["kind"], b["light"]) for b in demo.request["buoys"]
    ]
    faulty = [i for i, b in enumerate(world.buoys) if b.actual_light != b.light or b.offset_m != (0.0, 0.0)]
    assert faulty == sorted([demo.plan.order[LIGHT_OUT_AT], demo.plan.order[OFF_STATION_AT]])
    dark, moved = world.buoys[demo.plan.order[LIGHT_OUT_AT]], world.buoys[demo.plan.order[OFF_STATION_AT]]
    assert dark.actual_light is None and dark.offset_m == (0.0, 0.0)
    assert math.hypot(*moved.offset_m) == pytest.approx(OFF_STATION_RADII * moved.swing_radius_m)
    calm, _ = prepare(_options(tmp_path, demo=True, weather=Weather()))
    assert _vehicle_params(children(calm)[0].argv)["SIM_GUST_AMP"] == 0.0


@pytest.mark.integration  # the vehicle's own CLI lists them
def test_the_vehicle_takes_every_parameter_up_gives_it(tmp_path):
    options, _ = prepare(_options(tmp_path, demo=True))
    argv = children(options)[0].argv
    params = [arg for i, arg in enumerate(argv) if i > 0 and argv[i - 1] == "--param"]
    listed = subprocess.run(
        [sys.executable, "-m", "sitl_quad", *[a for p in params for a in ("--param", p)], "--list-params"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert listed.returncode == 0, listed.stderr
    values = {line.split()[0]: line.split()[1] for line in listed.stdout.splitlines()}
    assert values["MC_ATT_CTRL"] == "1" and values["SIM_GUST_HOLD"] == "10"


def test_weather_options_on_the_command_line(capsys):
    parser = build_parser()
    assert requested_weather(parser.parse_args(["up"])) is None  # the default: the paper's weather with --demo
    assert requested_weather(parser.parse_args(["up", "--calm"])) == Weather()
    assert requested_weather(parser.parse_args(["up", "--wind", "3,90"])) == Weather(wind_m_s=3.0, wind_from_deg=90.0)
    with pytest.raises(SystemExit):
        parser.parse_args(["up", "--calm", "--wind", "3"])
    assert main(["up", "--compare"]) == 2
    assert "--demo" in capsys.readouterr().err


def _sample(t: float, north: float, ref_down: float, seq: int) -> dict:
    return {
        "t_s": t,
        "north": north,
        "east": 0.0,
        "down": ref_down,
        "ref_north": 0.0,
        "ref_east": 0.0,
        "ref_down": ref_down,
        "yaw": 0.0,
        "ref_yaw": 0.0,
        "mission_seq": seq,
        "eso": None,
        "cross_track_m": None,
    }


def test_the_gust_is_found_in_the_telemetry_by_the_climb_and_measured_there():
    """Telemetry at 10 Hz from t = 100 s: the reference starts climbing after 101.0 s, so the mission started
    at 100.0 s (1 s spool-up) and a gust stated at 20 s meets the vehicle at 120.0 s."""
    weather = Weather(gust_m_s=4.0, gust_start_s=20.0, gust_hold_s=10.0)
    samples = []
    for k in range(400):
        t = 100.0 + 0.1 * k
        ref_down = 0.03 if t <= 101.0 + 1e-9 else 0.03 - 2.5 * (t - 101.0)
        error = 0.05 + (0.3 if 121.0 <= t < 123.0 else 0.0) + (0.9 if t > 131.0 else 0.0)  # the last: after 10 s
        samples.append(_sample(t, error, ref_down, 8 if t > 110.0 else 1))
    mission = {"status": "completed", "order": list(range(13)), "progress": {"camera": None}}
    flight = measure_flight("adrc", weather, mission, samples, wall_s=2.0)
    assert flight.gust_onset_t_s == pytest.approx(120.0)
    assert flight.gust.peak_m == pytest.approx(0.35)
    assert flight.gust.recovery_s == pytest.approx(3.0)  # the sample at 123.0 s is back at 0.05 m
    assert flight.gust_leg == 7  # mission item 8 is the 7th buoy leg
    assert flight.simulated_s == pytest.approx(39.9) and flight.simulated_s / flight.wall_s == pytest.approx(19.95)
    still = measure_flight("adrc", Weather(), mission, samples, wall_s=2.0)
    assert still.gust is None and still.gust_onset_t_s is None
    # an inspection mission: seven items a buoy (gcs.domain.planning.inspection_items); item 2 + 6 * 7 + 3 is the
    # seventh buoy's standoff hold, on the seventh leg
    inspected = [s | {"mission_seq": 2 + 6 * 7 + 3 if s["mission_seq"] == 8 else s["mission_seq"]} for s in samples]
    camera = mission | {"progress": {"camera": "component 100: sim"}}
    assert measure_flight("adrc", weather, camera, inspected, wall_s=2.0).gust_leg == 7


def test_a_database_url_reaches_the_service_by_the_environment_never_its_command_line(tmp_path):
    url = "postgresql://pilot:secret@db.example:5432/buoys"  # a password: the command line is logged and in ps
    settings = Settings(data_dir=tmp_path, db=url, vehicle_url="udpout:127.0.0.1:14600")
    service = children(UpOptions(settings=settings))[-1]
    assert service.env[Settings.env_name("db")] == url
    assert "--db" not in service.argv and "secret" not in " ".join(service.argv)
    sqlite_service = children(_options(tmp_path))[-1]  # a SQLite file goes on the command line, as before
    assert sqlite_service.argv[sqlite_service.argv.index("--db") + 1] == str(tmp_path / "gcs.sqlite")


def test_the_signing_key_reaches_every_child_by_the_environment_never_a_command_line(tmp_path):
    key = "harbour signing passphrase"
    settings = Settings(data_dir=tmp_path, signing_key=key, vehicle_url="udpout:127.0.0.1:14600")
    vehicle, controller, service = children(UpOptions(settings=settings))
    assert vehicle.env[SIGNING_KEY_ENV] == controller.env[SIGNING_KEY_ENV] == key
    assert service.env[Settings.env_name("signing_key")] == key
    assert all(
        "--signing-key" not in child.argv and key not in " ".join(child.argv)
        for child in (vehicle, controller, service)
    )


def test_the_findings_table_has_a_row_per_buoy_with_its_findings_or_reason_and_the_verdict_counts():
    charted = {"kind": "port", "light": "Fl R 4s", "lat": 0.0, "lon": 0.0, "swing_radius_m": 5.0}
    off = {"code": "off_station", "offset_m": 15.24, "swing_radius_m": 5.0, "bearing_deg": 90}
    inspections = [
        {"buoy": "B1", "charted": charted, "verdict": "ok", "light_seen": "flashing . R 4.0s", "offset_m": 0.4,
         "findings": [], "reason": None},
        {"buoy": "B2", "charted": charted, "verdict": "defect", "light_seen": "flashing . R 4.0s", "offset_m": 15.24,
         "findings": [off], "reason": None},
        {"buoy": "B3", "charted": charted | {"light": None}, "verdict": "not_inspected", "light_seen": None,
         "offset_m": None, "findings": [], "reason": "the vehicle has no camera"},
    ]  # fmt: skip
    lines = findings_table(inspections).splitlines()
    assert lines[0].split()[:4] == ["buoy", "kind", "light", "verdict"]
    assert lines[2].startswith("B2") and lines[2].endswith("off_station 15.2 m (swing 5 m)") and "15.2 m" in lines[2]
    assert "unlit" in lines[3] and lines[3].endswith("the vehicle has no camera")
    assert lines[-1] == "3 buoys: 1 ok, 1 defect, 1 not_inspected"


def test_the_simulated_worlds_ais_reaches_the_service_and_the_users_feeds_are_passed_on(tmp_path):
    world = tmp_path / "world.geojson"
    world.write_text('{"type": "FeatureCollection", "features": []}')
    settings = Settings(data_dir=tmp_path, vehicle_url="udpout:127.0.0.1:14600", ais_sources=["tcp://shore:5631"])

    def sources(argv: list[str]) -> list[str]:
        return [argv[i + 1] for i, arg in enumerate(argv) if arg == "--ais"]

    started = children(UpOptions(settings=settings, world=world, vehicles=2))
    first, second, service = started[0].argv, started[2].argv, started[-1].argv
    assert first[first.index("--ais-out") + 1] == "127.0.0.1:10110"
    assert "--ais-out" not in second  # one station for the world a fleet shares
    assert sources(service) == ["tcp://shore:5631", "udp://127.0.0.1:10110"]
    quiet = children(UpOptions(settings=settings, world=world, world_ais_port=0))
    assert "--ais-out" not in quiet[0].argv and sources(quiet[-1].argv) == ["tcp://shore:5631"]
    no_world = children(UpOptions(settings=settings))
    assert "--ais-out" not in no_world[0].argv and sources(no_world[-1].argv) == ["tcp://shore:5631"]
    # the demo's buoys each have an AtoN's MMSI of their own
    options, demo = prepare(_options(tmp_path, demo=True))
    mmsis = [b.mmsi for b in demo.world.buoys]
    assert len(set(mmsis)) == len(mmsis) and all(str(m).startswith("99") and len(str(m)) == 9 for m in mmsis)
    assert "--ais-out" in children(options)[0].argv


def test_up_refuses_a_world_ais_port_that_is_no_port(capsys):
    assert main(["up", "--world-ais-port", "70000"]) == 2
    assert "--world-ais-port 70000 is not a port" in capsys.readouterr().err


def test_the_demos_ais_line_counts_the_atons_and_names_those_off_position():
    aton = {"name": "B1", "off_position": False, "off_position_valid": True, "stale": False}
    off = aton | {"name": "B7", "off_position": True}
    assert ais_summary([aton, off]) == "2 AtoNs heard (GET /ais/atons, the map's AIS layer); off position: B7"
    assert ais_summary([aton, off | {"stale": True}]).endswith("none reports itself off position")


def test_durations_read_as_minutes_and_seconds():
    assert [duration_text(s) for s in (725.31, 60.0, 41.23, None, float("nan"))] == [
        "12 min 05.3 s", "1 min 00.0 s", "41.2 s", "unknown", "unknown"
    ]  # fmt: skip


# ----- --real-time / --watch-speed N: the vehicles' SIM_SPEEDUP once the demo has flown (stack.sim_speed)
def test_the_watch_options_on_the_command_line(capsys):
    parser = build_parser()
    assert parser.parse_args(["up"]).watch_speed is None  # the default: every mission at full lockstep speed
    assert parser.parse_args(["up", "--real-time"]).watch_speed == 1.0
    assert parser.parse_args(["up", "--watch-speed", "4"]).watch_speed == 4.0
    with pytest.raises(SystemExit):
        parser.parse_args(["up", "--real-time", "--watch-speed", "4"])
    refused = {
        ("--watch-speed", "0"): "--watch-speed must be in (0, 1000]",
        ("--watch-speed", "nan"): "--watch-speed must be in (0, 1000]",
        ("--real-time", "--vehicle", "udpin://0.0.0.0:14550"): "they do not go with --vehicle",
        ("--real-time", "--demo", "--exit-after-demo"): "--exit-after-demo flies none",
    }
    for args, error in refused.items():
        assert main(["up", *args]) == 2  # before anything starts
        assert error in capsys.readouterr().err


def test_every_vehicle_starts_at_full_speed_whatever_its_parameter_file_kept(tmp_path):
    """A parameter file keeps the SIM_SPEEDUP an earlier `up --real-time` set: each start sets it back to 0, so a
    demo flies at full lockstep speed."""
    for vehicle in children(_options(tmp_path, vehicles=2))[0:4:2]:
        assert _vehicle_params(vehicle.argv)["SIM_SPEEDUP"] == 0.0


@pytest.mark.integration  # one vehicle, over MAVLink
def test_watch_at_sets_the_pace_on_the_vehicle_and_in_its_restart_arguments(start_sitl):
    vehicle = start_sitl(speed=20.0)
    spec = ChildSpec("sitl_quad", ["python", "-m", "sitl_quad", "--param", "SIM_SPEEDUP=0", "--seed", "0"])
    said: list[str] = []
    watch_at([(spec, vehicle.port, 1)], 1.0, None, said.append)
    assert said == ["missions from now on fly at real time (SIM_SPEEDUP 1)"]
    assert spec.argv == ["python", "-m", "sitl_quad", "--param", "SIM_SPEEDUP=1", "--seed", "0"]  # a restart keeps it
    gcs = connected(vehicle)
    try:
        assert gcs.read_param("SIM_SPEEDUP").param_value == 1.0
    finally:
        gcs.close()


@pytest.mark.integration
@pytest.mark.slow
@pytest.mark.timeout(STACK_S + 120)
def test_up_real_time_without_a_demo_sets_every_vehicle_to_real_time_and_says_so(tmp_path):
    """`up --real-time --vehicles 2` (the vehicles' own loops: no offboard process to start): once the stack runs,
    both vehicles have SIM_SPEEDUP 1, read back over MAVLink and from the parameter file each saved."""
    first = free_udp_port_block(2)
    up = Up(
        "--real-time", "--vehicles", "2", "--controller", "px4", "--data", str(tmp_path),
        "--port", str(free_tcp_port()), "--vehicle-port", str(first),
    )  # fmt: skip
    try:
        up.wait_line(r"^missions from now on fly at real time on all 2 vehicles \(SIM_SPEEDUP 1\)$", STACK_S)
        up.wait_line(r"^running; Ctrl-C stops everything", 60)
        gcs = GroundStation(first)
        try:
            gcs.connect(timeout=60)
            assert gcs.read_param("SIM_SPEEDUP").param_value == 1.0
        finally:
            gcs.close()
        for name in ("vehicle.params", "vehicle-2.params"):
            assert _saved_params(tmp_path / name)["SIM_SPEEDUP"] == 1.0
    finally:
        code = up.stop()
    assert code == 0, up.text()


def _saved_params(path) -> dict[str, float]:
    """A vehicle's parameter file (QGC's format: sysid, compid, name, value, type) as {name: value}."""
    rows = [line.split("\t") for line in path.read_text().splitlines() if not line.startswith("#")]
    return {row[2]: float(row[3]) for row in rows if len(row) == 5}


def test_the_demo_report_says_each_duration_once_and_the_lockstep_bench_reads_its_speed(tmp_path):
    """The report's flight line (in the air) and speed line (the mission's span on both clocks) say what each
    measures, and bench.lockstep_mission parses the speed line as printed."""
    samples = [_sample(100.0 + 0.1 * k, 0.05, -5.0, 3) for k in range(400)]
    mission = {
        "id": 1, "status": "completed", "reason": None, "depot": {"lat": 38.921, "lon": 121.663},
        "buoys": [{"lat": 38.922, "lon": 121.664}], "length_m": 300.0, "method": "exact", "improvement_pct": 0.0,
        "buoy_results": [{"reached": True, "closest_m": 0.1}], "acceptance_radius_m": 2.0, "order": [0],
        "tracking": {"flight_time_s": 612.3, "distance_flown_m": 310.0, "planned_length_m": 300.0,
                     "rms_cross_track_m": 0.03, "max_cross_track_m": 0.1},
        "progress": {"camera": None},
    }  # fmt: skip
    flight = measure_flight("adrc", Weather(), mission, samples, wall_s=2.0)
    report = demo_report(flight, _options(tmp_path))
    assert "flight     10 min 12.3 s in the air (vehicle time, take-off to landing)" in report
    (speed,) = [line for line in report.splitlines() if "s of wall-clock time (POST to landed)" in line]
    assert [float(x) for x in LOCKSTEP_LINE.search(speed).groups()] == [39.9, 2.0]
    assert speed.endswith("20.0 times real time")
