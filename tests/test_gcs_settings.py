"""Settings: every default in gcs.settings, overridden by BUOY_GCS_* variables, overridden by command-line options."""

import os

import pytest

from gcs.cli import build_parser, main, settings_from_args
from gcs.settings import DB_FILENAME, Settings
from stack.children import children
from stack.options import UpOptions


@pytest.fixture(autouse=True)
def clean_environment(monkeypatch):
    for name in [n for n in os.environ if n.startswith("BUOY_GCS_")]:
        monkeypatch.delenv(name)


def test_every_field_is_read_from_its_environment_variable(monkeypatch, tmp_path):
    monkeypatch.setenv("BUOY_GCS_VEHICLE_URL", "tcp://127.0.0.1:5760")
    monkeypatch.setenv("BUOY_GCS_PORT", "8123")
    monkeypatch.setenv("BUOY_GCS_DB_PATH", str(tmp_path / "x.sqlite"))
    monkeypatch.setenv("BUOY_GCS_SIGNING_KEY", "secret words")
    monkeypatch.setenv("BUOY_GCS_LIVE_RATE_HZ", "5")
    monkeypatch.setenv("BUOY_GCS_VEHICLE_WAIT_S", "0.5")
    monkeypatch.setenv("BUOY_GCS_LIMITS__MAX_BUOYS", "12")
    settings = Settings()
    assert settings.vehicle_url == "tcp://127.0.0.1:5760"
    assert settings.port == 8123
    assert settings.db_path == tmp_path / "x.sqlite"
    assert settings.reports_dir == tmp_path / "reports"
    assert settings.signing_key == "secret words"
    assert (settings.live_rate_hz, settings.vehicle_wait_s) == (5.0, 0.5)
    assert settings.limits.max_buoys == 12
    assert settings.limits.max_route_length_m == Settings().limits.max_route_length_m  # the others stay


def test_the_database_lives_in_the_data_directory_unless_named(monkeypatch, tmp_path):
    assert Settings().db_path == Settings().data_dir / DB_FILENAME
    monkeypatch.setenv("BUOY_GCS_DATA_DIR", str(tmp_path))
    assert Settings().db_path == tmp_path / DB_FILENAME
    assert Settings(db_path=tmp_path / "other.sqlite").db_path == tmp_path / "other.sqlite"


def test_an_option_beats_the_environment_which_beats_the_default(monkeypatch):
    parser = build_parser()
    assert settings_from_args(parser.parse_args(["serve"])).port == Settings.default("port")
    monkeypatch.setenv("BUOY_GCS_PORT", "9001")
    assert settings_from_args(parser.parse_args(["serve"])).port == 9001
    assert settings_from_args(parser.parse_args(["serve", "--port", "9002"])).port == 9002


def test_a_bad_environment_value_is_a_message_naming_the_variable(monkeypatch, capsys):
    monkeypatch.setenv("BUOY_GCS_PORT", "eighty")
    assert main(["serve"]) == 2
    assert "BUOY_GCS_PORT" in capsys.readouterr().err


def test_up_hands_its_settings_to_the_children(tmp_path):
    settings = Settings(data_dir=tmp_path, port=8123, token="t", vehicle_url="udpout:127.0.0.1:14600")
    vehicle, controller, service = children(UpOptions(settings=settings))
    assert vehicle.argv[vehicle.argv.index("--port") + 1] == "14600"
    assert "udpout:127.0.0.1:14600" in controller.argv
    argv = service.argv
    assert argv[argv.index("--db") + 1] == str(tmp_path / DB_FILENAME)
    assert argv[argv.index("--port") + 1] == "8123"
    # the token by the environment: a command line shows in ps and in the supervisor's log
    assert "--token" not in argv and "t" not in argv and service.env == {"BUOY_GCS_TOKEN": "t"}
