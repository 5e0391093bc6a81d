"""Gains from the airframe (uavcore.envelope, adrc_offboard.design), and that what ships is what the tuning chose."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from adrc_offboard.adrc import AdrcParameterError
from adrc_offboard.adrc_attitude import AdrcAttitudeGains
from adrc_offboard.cli import make_controller as offboard_controller
from adrc_offboard.design import (
    ATTITUDE_RATE_HZ,
    DESIGN_PARAMETERS,
    RATE_LOOP_SHARE,
    SAMPLED_BANDWIDTH_SHARE,
    Design,
    acceleration_limits,
    adrc_attitude_gains,
    adrc_outer_gains,
    gains_files,
    geometric_gains,
    load_design,
    load_designs,
    outer_loop_for,
    pid_attitude_gains,
    pid_outer_gains,
)
from adrc_offboard.geometric import GeometricGains
from adrc_offboard.outer_loop import AccelerationLimits, AdrcOuterGains, PidOuterGains
from sitl_quad.attitude_loops import attitude_loops
from sitl_quad.config import AttitudeControllerKind, VehicleConfig
from sitl_quad.params import ParameterTable
from sitl_quad.rotors import mix
from sitl_quad.vehicle_params import VEHICLE_PARAMETERS
from stack.children import designed_pid_attitude
from uavcore.airframe import Airframe, ModelParameterError
from uavcore.envelope import MAX_TILT_POLICY_RAD, THRUST_RESERVE, envelope

REPO = Path(__file__).resolve().parents[1]
TABLE2 = Airframe.table2()


def test_the_envelope_follows_from_table2() -> None:
    env = envelope(TABLE2)
    weight = TABLE2.mass * TABLE2.g
    assert env.thrust_to_weight == pytest.approx(TABLE2.max_thrust_n / weight)
    usable = (1 - THRUST_RESERVE) * TABLE2.max_thrust_n
    assert env.max_tilt_rad == pytest.approx(min(math.acos(weight / usable), MAX_TILT_POLICY_RAD))
    assert env.max_horizontal_acc == pytest.approx(TABLE2.g * math.tan(env.max_tilt_rad))
    assert env.max_up_acc == pytest.approx(min(usable / TABLE2.mass - TABLE2.g, TABLE2.g))
    assert env.attitude_bandwidth_limit == pytest.approx(1 / (4 * TABLE2.motor_time_constant))  # 12.5 rad/s


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_the_torque_authority_is_what_the_mixer_delivers_at_hover(axis: int) -> None:
    authority = envelope(TABLE2).max_torque[axis]
    params, omega = TABLE2.as_array(), np.zeros(4)
    hover = TABLE2.mass * TABLE2.g
    for share, clipped in ((0.99, False), (1.02, True)):
        torque = [0.0, 0.0, 0.0]
        torque[axis] = share * authority
        assert mix(hover, *torque, params, omega) is clipped


def test_a_smaller_airframe_gets_its_own_gains_by_the_same_rules() -> None:
    small = TABLE2.replace(ixx=TABLE2.ixx / 2, iyy=TABLE2.iyy / 2, motor_time_constant=0.01)
    design = load_design("adrc")
    big, little = adrc_attitude_gains(TABLE2, design), adrc_attitude_gains(small, design)
    cap = SAMPLED_BANDWIDTH_SHARE * ATTITUDE_RATE_HZ  # what a 250 Hz loop can sample
    assert little.roll["omega_c"] == pytest.approx(min(2 * big.roll["omega_c"], cap))  # motors twice as fast
    assert little.roll["u_max"] == pytest.approx(big.roll["u_max"])  # same mixer
    assert little.roll["r1"] == pytest.approx(2 * big.roll["r1"])  # half the inertia: twice the acceleration
    pid = load_design("pid")
    rate = min(pid.rate_ratio * pid.bandwidths(small)["attitude"], RATE_LOOP_SHARE * ATTITUDE_RATE_HZ)
    assert pid_attitude_gains(small, pid)["mc_rollrate_p"] == pytest.approx(small.ixx * rate)  # P = I w_r
    heavy = TABLE2.replace(mass=1.5 * TABLE2.mass)  # thrust-to-weight 1.49: less room to tilt or climb
    assert envelope(heavy).max_horizontal_acc < 0.75 * envelope(TABLE2).max_horizontal_acc
    assert acceleration_limits(heavy).max_up < 0.5 * acceleration_limits(TABLE2).max_up
    loaded = envelope(TABLE2.replace(mass=1.9 * TABLE2.mass))  # 1.18: the reserve shrinks, it flies gently
    assert loaded.usable_thrust_n == pytest.approx(1.1 * 1.9 * TABLE2.mass * TABLE2.g)
    assert math.degrees(loaded.max_tilt_rad) == pytest.approx(math.degrees(math.acos(1 / 1.1)))
    with pytest.raises(ModelParameterError, match=r"thrust-to-weight of at least 1\.16"):
        envelope(TABLE2.replace(mass=2 * TABLE2.mass))  # 1.12: it hovers, but cannot be controlled with margin


def test_a_design_names_exactly_its_family_numbers() -> None:
    values = dict(load_design("adrc").values)
    with pytest.raises(AdrcParameterError, match="unknown controller family"):
        Design("lqr", values)
    with pytest.raises(AdrcParameterError, match="needs exactly"):
        Design("adrc", {k: v for k, v in values.items() if k != "separation"})
    with pytest.raises(AdrcParameterError, match="finite and positive"):
        Design("adrc", values | {"separation": -1.0})
    assert set(load_designs()) == set(DESIGN_PARAMETERS)


def test_the_paper_literal_design_has_the_outer_td_and_the_eso_rate() -> None:
    paper = adrc_outer_gains(TABLE2, load_design("adrc_paper"))
    ours = adrc_outer_gains(TABLE2, load_design("adrc"))
    assert paper.horizontal.r0 is not None and not paper.use_measured_velocity
    assert ours.horizontal.r0 is None and ours.use_measured_velocity


def test_the_gains_files_are_what_the_shipped_design_gives_on_table2() -> None:
    designs = load_designs()
    assert AdrcOuterGains.load() == adrc_outer_gains(TABLE2, designs["adrc"])
    assert PidOuterGains.load() == pid_outer_gains(TABLE2, designs["pid"])
    assert AccelerationLimits.load() == acceleration_limits(TABLE2)
    assert AdrcAttitudeGains.load() == adrc_attitude_gains(TABLE2, designs["adrc"])
    assert GeometricGains.load() == geometric_gains(TABLE2, designs["geometric"])
    for name, data in gains_files(TABLE2, designs).items():  # byte for byte what --regenerate writes
        assert json.loads((REPO / "adrc_offboard" / "gains" / name).read_text()) == json.loads(json.dumps(data))


def test_the_shipped_designs_are_the_ones_the_tuning_campaign_chose() -> None:
    tuning = json.loads((REPO / "bench" / "results" / "tune.json").read_text())
    shipped = json.loads((REPO / "adrc_offboard" / "gains" / "design.json").read_text())["families"]
    assert tuning["chosen"], "the campaign chose nothing"
    for family, chosen in tuning["chosen"].items():
        assert shipped[family]["design"] == pytest.approx(chosen, rel=1e-5), family
        assert tuning["bound_check"][family]["bracketed"], f"{family}: a best point on a bound of the space"
        assert tuning["families"][family]["best"]["params"] == chosen


def test_make_run_flies_the_shipped_designs() -> None:
    """`make run` = `stack up --demo --real-time`: the adrc_offboard process's outer loop and the vehicle's ADRC
    attitude loop; --compare's PID run passes the PID design's attitude gains as the vehicle's MC_* parameters."""
    designs = load_designs()
    outer = offboard_controller("adrc", 50.0)
    assert outer.gains == adrc_outer_gains(TABLE2, designs["adrc"])
    assert outer._out.limits == acceleration_limits(TABLE2)
    assert offboard_controller("pid", 50.0).gains == pid_outer_gains(TABLE2, designs["pid"])
    config = VehicleConfig()
    inner = attitude_loops()[AttitudeControllerKind.ADRC](config, 250.0)
    assert inner.gains == adrc_attitude_gains(TABLE2, designs["adrc"])
    params = designed_pid_attitude()
    assert params == pid_attitude_gains(TABLE2, designs["pid"])
    config = VehicleConfig()
    table = ParameterTable(VEHICLE_PARAMETERS, config)  # what the vehicle does with each --param NAME=VALUE
    for name, value in params.items():
        table.set(name.upper(), float(f"{value:.6g}"))  # as stack.children formats them
    for name, value in params.items():
        assert getattr(table.config.attitude_pid, name) == pytest.approx(value, rel=1e-5)


def test_a_saturated_demand_keeps_the_path_and_gives_up_speed_along_it() -> None:
    limits = AccelerationLimits(6.0, 4.0, 3.0)
    # flying north, a demand of 5 m/s^2 east (back to the path) and 8 north (catching up): over the limit
    ax, ay, _ = limits.apply(8.0, 5.0, 0.0, along=(1.0, 0.0))
    assert ay == pytest.approx(5.0)  # the cross-track part kept whole
    assert math.hypot(ax, ay) == pytest.approx(6.0) and ax == pytest.approx(math.sqrt(36 - 25))
    _, sy, _ = limits.apply(8.0, 5.0, 0.0)  # without a path: scaled as a whole
    assert sy == pytest.approx(5.0 * 6.0 / math.hypot(8, 5))
    cx, cy, _ = limits.apply(1.0, 9.0, 0.0, along=(1.0, 0.0))  # the cross-track part alone is over the limit
    assert (cx, cy) == pytest.approx((0.0, 6.0))


def test_outer_loops_for_other_families_are_refused_cleanly() -> None:
    with pytest.raises(AdrcParameterError, match="cannot build"):
        outer_loop_for("adrc", TABLE2, load_design("pid"))
