"""The command line (`buoy-gcs`: the ground station's `serve` and `report`, and the stack's `up`): bad options give
a message and exit 2, never a traceback."""

import subprocess
import sys

import pytest

from gcs.cli import settings_from_args
from stack.cli import build_parser, main


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["serve", "--vehicle", "pigeon:127.0.0.1:5760"], "unknown scheme 'pigeon'"),
        (["serve", "--vehicle", "udpout:127.0.0.1:notaport"], "the port must be a number"),
        (["serve", "--port", "70000"], "not a TCP port"),
        (["serve", "--vehicle", "1=udpout:127.0.0.1:14600", "--vehicle", "1=tcp://h:5760"], "two vehicles"),
        (["serve", "--vehicle", "300=udpout:127.0.0.1:14600"], "a system id is 1 to 255"),
        (["serve", "--vehicle", "udpin://:14550", "--vehicle", "2=udpin://:14550"], "names each vehicle's system id"),
        (["up", "--vehicles", "0"], "--vehicles must be 1 to 64"),
        (["up", "--vehicles", "2", "--vehicle", "udpin://:14550"], "do not go with --vehicle"),
    ],
)
def test_bad_options_exit_2_with_a_message(argv, message, capsys):
    assert main(argv) == 2
    assert message in capsys.readouterr().err


def test_unusable_database_path_is_a_message(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("not a directory")
    assert main(["serve", "--db", str(blocker / "gcs.sqlite")]) == 2
    assert "--db" in capsys.readouterr().err


def test_settings_from_the_documented_options(tmp_path, monkeypatch):
    monkeypatch.delenv("BUOY_GCS_TOKEN", raising=False)
    args = build_parser().parse_args(
        [
            "serve",
            "--vehicle",
            "udpout:127.0.0.1:14600",
            "--host",
            "127.0.0.1",
            "--port",
            "8123",
            "--db",
            str(tmp_path / "x.sqlite"),
            "--token",
            "t",
        ]
    )
    settings = settings_from_args(args)
    assert (settings.vehicle_url, settings.port, settings.token) == ("udpout:127.0.0.1:14600", 8123, "t")
    assert settings.db_path == tmp_path / "x.sqlite"
    assert settings_from_args(build_parser().parse_args(["serve"])).host == "127.0.0.1"  # loopback by default


@pytest.mark.integration  # a fresh interpreter per entry point
@pytest.mark.parametrize(("module", "usage"), [("gcs", "usage: python -m gcs"), ("stack", "usage: buoy-gcs")])
def test_module_entry_point_without_a_command_shows_usage(module, usage):
    result = subprocess.run([sys.executable, "-m", module], capture_output=True, text=True, timeout=60)
    assert result.returncode == 2 and usage in result.stderr and "Traceback" not in result.stderr


@pytest.mark.integration
def test_the_ground_station_alone_starts_no_vehicle_and_says_where_up_is():
    result = subprocess.run([sys.executable, "-m", "gcs", "up"], capture_output=True, text=True, timeout=60)
    assert result.returncode == 2 and "invalid choice: 'up'" in result.stderr
    help_text = subprocess.run([sys.executable, "-m", "gcs", "--help"], capture_output=True, text=True, timeout=60)
    assert "buoy-gcs up" in help_text.stdout


def test_serve_names_the_instance_and_the_vehicle_for_a_shared_database():
    args = build_parser().parse_args(["serve", "--instance-name", "tower-2", "--vehicle-name", "harbour-drone-1"])
    settings = settings_from_args(args)
    assert (settings.instance_name, settings.vehicle_name) == ("tower-2", "harbour-drone-1")


def test_serve_takes_a_fleet_by_repeating_vehicle():
    args = build_parser().parse_args(["serve", "--vehicle", "1=udpout:127.0.0.1:14600", "--vehicle", "2=tcp://h:5760"])
    settings = settings_from_args(args)
    assert settings.fleet == [(1, "udpout:127.0.0.1:14600"), (2, "tcp://h:5760")]
    assert settings.vehicle_url == "udpout:127.0.0.1:14600"  # the first: missions fly on it, the lease names it
    lone = settings_from_args(build_parser().parse_args(["serve", "--vehicle", "udpin://:14550"]))
    assert lone.fleet == [(None, "udpin://:14550")]  # no system id: the first autopilot heard


def test_a_depot_off_the_globe_is_refused_by_the_parser(capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["up", "--depot", "91,0"])
    assert exit_info.value.code == 2 and "outside lat" in capsys.readouterr().err
