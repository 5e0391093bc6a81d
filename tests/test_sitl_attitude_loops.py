"""The attitude loops injected into the vehicle: MC_ATT_CTRL selects them, and the ADRC's observers always model
the airframe's own motor lag (one constructor path), also after the airframe's parameters change."""

from __future__ import annotations

import dataclasses

import pytest

from adrc_offboard.adrc_attitude import AdrcAttitudeController
from sitl_quad.attitude_loops import attitude_loops
from sitl_quad.attitude_pid import PidAttitudeController
from sitl_quad.config import AttitudeControllerKind, ControlConfig, VehicleConfig
from sitl_quad.vehicle import Vehicle
from uavcore.airframe import ModelParameterError
from uavcore.geodesy import DEFAULT_HOME


def _vehicle(kind: AttitudeControllerKind, **loops) -> Vehicle:
    config = VehicleConfig(control=ControlConfig(attitude_controller=kind))
    return Vehicle(config, home=DEFAULT_HOME, **loops)


def test_mc_att_ctrl_1_flies_the_adrc_whose_actuator_model_is_the_airframes_motor_lag():
    vehicle = _vehicle(AttitudeControllerKind.ADRC, attitude_loops=attitude_loops())
    assert isinstance(vehicle.attitude, AdrcAttitudeController)
    assert vehicle.attitude.actuator_time_constant == vehicle.config.airframe.motor_time_constant > 0


def test_the_adrc_follows_a_changed_motor_lag():
    vehicle = _vehicle(AttitudeControllerKind.ADRC, attitude_loops=attitude_loops())
    vehicle.config.airframe = dataclasses.replace(vehicle.config.airframe, motor_time_constant=0.05)
    vehicle.apply_config("airframe")
    assert vehicle.attitude.actuator_time_constant == 0.05


def test_mc_att_ctrl_0_flies_the_builtin_pid():
    assert isinstance(_vehicle(AttitudeControllerKind.PID).attitude, PidAttitudeController)


def test_a_vehicle_not_given_the_adrc_refuses_to_select_it():
    with pytest.raises(ModelParameterError, match="MC_ATT_CTRL=1"):
        _vehicle(AttitudeControllerKind.ADRC)
