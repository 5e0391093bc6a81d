"""The parameter table: PX4 bytewise INT32 encoding, validation, files."""

from __future__ import annotations

import json
import math
import subprocess
import sys

import pytest

from sitl_quad.config import VehicleConfig
from sitl_quad.params import INT32, REAL32, ParameterError, ParameterTable, decode_value, encode_value
from sitl_quad.vehicle_params import VEHICLE_PARAMETERS
from sitl_quad.wind import gust_speed


@pytest.fixture
def table() -> ParameterTable:
    return ParameterTable(VEHICLE_PARAMETERS, VehicleConfig())


def test_int32_travels_bytewise_not_cast():
    raw = encode_value(1, INT32)
    assert raw != 1.0  # a cast would read back as 1065353216 in MAVSDK
    assert decode_value(raw, INT32) == 1
    assert decode_value(encode_value(-7, INT32), INT32) == -7
    assert encode_value(2.5, REAL32) == 2.5


def test_defaults_come_from_the_config(table):
    assert table.get("SIM_MASS") == pytest.approx(1.3)
    assert table.get("SIM_IZZ") == pytest.approx(0.151)
    assert table.get("OFFB_LOSS_T") == pytest.approx(1.0)  # PX4's COM_OF_LOSS_T default
    assert all(len(spec.name) <= 16 for spec in table.specs)


def test_set_updates_the_config_and_refusals_change_nothing(table):
    assert table.set("SIM_WIND_SPD", 5.0) == 5.0
    assert table.config.wind.speed_m_s == 5.0
    for name, bad in [
        ("SIM_WIND_SPD", -1.0),
        ("SIM_WIND_SPD", float("nan")),
        ("OFFB_LOSS_ACT", 1.5),
        ("OFFB_LOSS_ACT", 7),
        ("NOPE", 1.0),
    ]:
        with pytest.raises(ParameterError):
            table.set(name, bad)
    assert table.config.wind.speed_m_s == 5.0
    assert table.get("OFFB_LOSS_ACT") == 0


def test_file_round_trip_and_all_or_nothing_load(table, tmp_path):
    table.set("MPC_XY_CRUISE", 7.5)
    table.set("OFFB_LOSS_ACT", 2)
    path = tmp_path / "vehicle.params"
    table.save(path)
    fresh = ParameterTable(VEHICLE_PARAMETERS, VehicleConfig())
    assert fresh.load(path) == len(VEHICLE_PARAMETERS)
    assert fresh.get("MPC_XY_CRUISE") == 7.5 and fresh.get("OFFB_LOSS_ACT") == 2
    bad = tmp_path / "bad.params"
    bad.write_text("MPC_XY_CRUISE 3.0\nSIM_MASS -4\n")
    with pytest.raises(ParameterError, match="SIM_MASS"):
        fresh.load(bad)
    assert fresh.get("MPC_XY_CRUISE") == 7.5  # the good first line was not applied either


def test_the_gust_hold_reaches_the_wind_model_and_its_default_inf_survives_the_file(table, tmp_path):
    assert table.get("SIM_GUST_HOLD") == math.inf  # the default: a gust that stays (MIL-F-8785C)
    path = tmp_path / "vehicle.params"
    table.save(path)
    fresh = ParameterTable(VEHICLE_PARAMETERS, VehicleConfig())
    fresh.load(path)  # the saved "inf" loads back
    for name, value in [("SIM_GUST_AMP", 4.0), ("SIM_GUST_RISE", 1.0), ("SIM_GUST_T0", 0.0), ("SIM_GUST_HOLD", 10.0)]:
        fresh.set(name, value)
    assert fresh.config.wind.gust_hold_s == 10.0
    air = fresh.config.wind.as_array()  # the wind model: full strength through the hold, then back to none
    assert gust_speed(air, 10.9) == 4.0 and gust_speed(air, 12.5) == 0.0
    for bad in (-1.0, math.nan):
        with pytest.raises(ParameterError):
            fresh.set("SIM_GUST_HOLD", bad)
    with pytest.raises(ParameterError, match="finite"):
        fresh.set("SIM_WIND_SPD", math.inf)  # inf only where it is the parameter's maximum


@pytest.mark.integration  # each runs `python -m sitl_quad --list-params`
@pytest.mark.parametrize(
    "argv, message",
    [
        (["--params", "{tmp}/garbage.params"], "garbage.params:1"),
        (["--param", "SIM_MASS=-1"], "SIM_MASS"),
        (["--param", "NOT_A_PARAM=1"], "unknown parameter"),
        (["--home", "95,10"], "outside"),
        (["--speed", "0"], "--speed"),
        (["--world", "{tmp}/garbage.params"], "--world"),
        (["--world", "{tmp}/missing.geojson"], "missing.geojson"),
        (["--world", "{tmp}/no_kind.geojson"], "kind"),
    ],
)
def test_cli_rejects_bad_input_with_a_message(tmp_path, argv, message):
    (tmp_path / "garbage.params").write_text("this is not a parameter file\n")
    point = {"type": "Point", "coordinates": [121.66, 38.92]}
    feature = {"type": "Feature", "geometry": point, "properties": {"id": "B1"}}  # no kind: WorldFileError
    (tmp_path / "no_kind.geojson").write_text(json.dumps({"type": "FeatureCollection", "features": [feature]}))
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    result = subprocess.run(
        [sys.executable, "-m", "sitl_quad", *argv, "--list-params"], capture_output=True, text=True, timeout=60
    )
    assert result.returncode == 2
    assert message in result.stderr
    assert "Traceback" not in result.stderr


@pytest.mark.integration
def test_cli_lists_parameters():
    result = subprocess.run(
        [sys.executable, "-m", "sitl_quad", "--param", "SIM_WIND_SPD=4", "--list-params"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 0
    line = next(line for line in result.stdout.splitlines() if line.startswith("SIM_WIND_SPD"))
    assert line.split()[1] == "4"
