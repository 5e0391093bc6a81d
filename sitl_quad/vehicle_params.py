"""The vehicle's parameter table: PX4-style names bound to VehicleConfig fields, with limits.

Names follow PX4 where PX4 has the parameter (MPC_XY_CRUISE, NAV_ACC_RAD, ...); the simulation's own
settings are SIM_*. Only OFFB_LOSS_T is fixed by the contract.
"""

from __future__ import annotations

import math

from sitl_quad.params import INT32, REAL32, ParamSpec

DEG = math.pi / 180.0

VEHICLE_PARAMETERS: list[ParamSpec] = [
    # airframe (paper Table 2 by default)
    ParamSpec("SIM_MASS", "airframe.mass", REAL32, 0.1, 50.0, "vehicle mass, kg"),
    ParamSpec("SIM_IXX", "airframe.ixx", REAL32, 1e-4, 10.0, "roll inertia Ix, kg m^2"),
    ParamSpec("SIM_IYY", "airframe.iyy", REAL32, 1e-4, 10.0, "pitch inertia Iy, kg m^2"),
    ParamSpec("SIM_IZZ", "airframe.izz", REAL32, 1e-4, 10.0, "yaw inertia Iz, kg m^2"),
    ParamSpec("SIM_ARM_L", "airframe.arm_length", REAL32, 0.05, 5.0, "rotor arm L, m"),
    ParamSpec("SIM_KL", "airframe.kl", REAL32, 1e-7, 1e-2, "lift coefficient kl, N s^2"),
    ParamSpec("SIM_KF", "airframe.kf", REAL32, 1e-9, 1e-3, "rotor drag coefficient kf, N s^2"),
    ParamSpec("SIM_MOT_TAU", "airframe.motor_time_constant", REAL32, 0.001, 0.5, "motor lag, s"),
    ParamSpec("SIM_MOT_MAX", "airframe.rotor_speed_max", REAL32, 10.0, 5000.0, "max rotor speed, rad/s"),
    ParamSpec("SIM_DRAG_XY", "airframe.drag_linear_xy", REAL32, 0.0, 10.0, "linear drag xy, N/(m/s)"),
    ParamSpec("SIM_DRAG_XY2", "airframe.drag_quadratic_xy", REAL32, 0.0, 10.0, "quadratic drag xy"),
    ParamSpec("SIM_DRAG_Z", "airframe.drag_linear_z", REAL32, 0.0, 10.0, "linear drag z, N/(m/s)"),
    ParamSpec("SIM_DRAG_Z2", "airframe.drag_quadratic_z", REAL32, 0.0, 10.0, "quadratic drag z"),
    # wind
    ParamSpec("SIM_WIND_SPD", "wind.speed_m_s", REAL32, 0.0, 40.0, "mean wind speed, m/s"),
    ParamSpec("SIM_WIND_DIR", "wind.direction_from_deg", REAL32, -360.0, 360.0, "wind from, deg"),
    ParamSpec("SIM_GUST_AMP", "wind.gust_amplitude_m_s", REAL32, -40.0, 40.0, "1-cosine gust, m/s"),
    ParamSpec("SIM_GUST_RISE", "wind.gust_rise_time_s", REAL32, 0.01, 60.0, "gust rise time, s"),
    ParamSpec("SIM_GUST_T0", "wind.gust_start_s", REAL32, 0.0, 1e6, "gust start, s after takeoff"),
    ParamSpec("SIM_GUST_HOLD", "wind.gust_hold_s", REAL32, 0.0, math.inf, "gust hold at full strength, s; inf = stays"),
    ParamSpec("SIM_GUST_DIR", "wind.gust_direction_from_deg", REAL32, -360.0, 360.0, "gust from, deg"),
    ParamSpec("SIM_TURB_W20", "wind.turbulence_w20_m_s", REAL32, 0.0, 40.0, "Dryden W20 intensity, m/s"),
    # the paper's Gaussian disturbance terms D_x..D_psi
    ParamSpec("SIM_DIST_VX", "disturbance.variance_x", REAL32, 0.0, 100.0, "D_x variance, (m/s^2)^2"),
    ParamSpec("SIM_DIST_VY", "disturbance.variance_y", REAL32, 0.0, 100.0, "D_y variance, (m/s^2)^2"),
    ParamSpec("SIM_DIST_VZ", "disturbance.variance_z", REAL32, 0.0, 100.0, "D_z variance, (m/s^2)^2"),
    ParamSpec("SIM_DIST_VR", "disturbance.variance_roll", REAL32, 0.0, 100.0, "D_phi variance"),
    ParamSpec("SIM_DIST_VP", "disturbance.variance_pitch", REAL32, 0.0, 100.0, "D_theta variance"),
    ParamSpec("SIM_DIST_VYAW", "disturbance.variance_yaw", REAL32, 0.0, 100.0, "D_psi variance"),
    ParamSpec("SIM_DIST_T", "disturbance.sample_time_s", REAL32, 0.001, 60.0, "D sample time, s"),
    # sensor noise
    ParamSpec("SIM_NOISE_POS", "sensor_noise.position_std_m", REAL32, 0.0, 10.0, "position noise std, m"),
    ParamSpec("SIM_NOISE_VEL", "sensor_noise.velocity_std_m_s", REAL32, 0.0, 10.0, "velocity noise std"),
    ParamSpec("SIM_NOISE_ATT", "sensor_noise.attitude_std_rad", REAL32, 0.0, 1.0, "attitude noise std, rad"),
    ParamSpec("SIM_NOISE_GYR", "sensor_noise.gyro_std_rad_s", REAL32, 0.0, 10.0, "gyro noise std, rad/s"),
    # navigator
    ParamSpec("MPC_XY_CRUISE", "navigator.cruise_speed", REAL32, 0.5, 30.0, "mission cruise speed, m/s"),
    ParamSpec("MPC_ACC_HOR", "navigator.max_acceleration", REAL32, 0.2, 15.0, "leg acceleration, m/s^2"),
    ParamSpec("MPC_JERK_AUTO", "navigator.max_jerk", REAL32, 0.5, 100.0, "leg jerk, m/s^3"),
    ParamSpec("MPC_Z_VEL_MAX_UP", "navigator.climb_speed", REAL32, 0.2, 10.0, "climb speed, m/s"),
    ParamSpec("MPC_Z_VEL_MAX_DN", "navigator.descent_speed", REAL32, 0.2, 10.0, "descent speed, m/s"),
    ParamSpec("MPC_LAND_SPEED", "navigator.land_speed", REAL32, 0.1, 5.0, "final landing speed, m/s"),
    ParamSpec("MPC_YAWRAUTO_MAX", "navigator.yaw_rate", REAL32, 5 * DEG, 6.0, "auto yaw rate, rad/s"),
    ParamSpec("NAV_ACC_RAD", "navigator.acceptance_radius", REAL32, 0.05, 200.0, "acceptance radius, m"),
    ParamSpec("NAV_MC_ALT_RAD", "navigator.altitude_acceptance", REAL32, 0.05, 50.0, "altitude accept., m"),
    ParamSpec("RTL_RETURN_ALT", "navigator.rtl_altitude", REAL32, 1.0, 500.0, "return altitude, m"),
    ParamSpec("MIS_TAKEOFF_ALT", "navigator.takeoff_altitude", REAL32, 0.5, 500.0, "takeoff altitude, m"),
    # attitude PID (PX4 names)
    *[
        ParamSpec(name.upper(), f"attitude_pid.{name}", REAL32, 0.0, 100.0, "attitude PID gain")
        for name in (
            "mc_roll_p",
            "mc_pitch_p",
            "mc_yaw_p",
            "mc_rollrate_p",
            "mc_rollrate_i",
            "mc_rollrate_d",
            "mc_pitchrate_p",
            "mc_pitchrate_i",
            "mc_pitchrate_d",
            "mc_yawrate_p",
            "mc_yawrate_i",
            "mc_yawrate_d",
            "mc_rr_int_lim",
            "mc_pr_int_lim",
            "mc_yr_int_lim",
        )
    ],
    # built-in position controller (PX4 names)
    *[
        ParamSpec(name.upper(), f"position_pid.{name}", REAL32, 0.0, 100.0, "position PID gain")
        for name in (
            "mpc_xy_p",
            "mpc_z_p",
            "mpc_xy_vel_p_acc",
            "mpc_xy_vel_i_acc",
            "mpc_xy_vel_d_acc",
            "mpc_z_vel_p_acc",
            "mpc_z_vel_i_acc",
            "mpc_z_vel_d_acc",
        )
    ],
    ParamSpec("MPC_XY_VEL_MAX", "position_pid.mpc_xy_vel_max", REAL32, 0.5, 40.0, "max horizontal speed, m/s"),
    ParamSpec("MPC_TILTMAX_AIR", "position_pid.mpc_tiltmax_air", REAL32, 5.0, 85.0, "max tilt, deg"),
    # failsafe and control
    ParamSpec(
        "OFFB_LOSS_T",
        "failsafe.offboard_loss_timeout_s",
        REAL32,
        0.05,
        60.0,
        "offboard setpoints older than this (simulated s) trigger the failsafe",
    ),
    ParamSpec(
        "OFFB_LOSS_ACT", "failsafe.offboard_loss_action", INT32, 0, 2, "offboard loss action: 0 hold, 1 land, 2 return"
    ),
    ParamSpec(
        "GF_ACTION",
        "failsafe.geofence_action",
        INT32,
        0,
        5,
        "geofence breach action: 0 none, 1 warning, 2 hold, 3 return, 5 land (4 terminate: not simulated)",
    ),
    ParamSpec(
        "GF_MAX_HOR_DIST",
        "failsafe.geofence_max_horizontal_m",
        REAL32,
        0.0,
        10000.0,
        "max horizontal distance from home, m; beyond it GF_ACTION (0: no limit)",
    ),
    ParamSpec(
        "GF_MAX_VER_DIST",
        "failsafe.geofence_max_vertical_m",
        REAL32,
        0.0,
        1000.0,
        "max height above home, m; above it GF_ACTION (0: no limit)",
    ),
    ParamSpec(
        "MC_ATT_CTRL", "control.attitude_controller", INT32, 0, 2, "attitude loop: 0 PID, 1 ADRC, 2 geometric SE(3)"
    ),
    # battery (sitl_quad.battery) and its failsafe, PX4's names and ranges
    ParamSpec("BAT1_N_CELLS", "battery.cells", INT32, 1, 14, "cells in series"),
    ParamSpec("BAT1_CAPACITY", "battery.capacity_mah", REAL32, 50.0, 100000.0, "pack capacity, mAh"),
    ParamSpec("BAT1_V_CHARGED", "battery.v_charged", REAL32, 3.0, 5.0, "cell open-circuit voltage full, V"),
    ParamSpec("BAT1_V_EMPTY", "battery.v_empty", REAL32, 2.5, 4.5, "cell open-circuit voltage empty, V"),
    ParamSpec("BAT1_R_INTERNAL", "battery.r_internal", REAL32, 0.0, 0.5, "internal resistance per cell, ohm"),
    ParamSpec("BAT_LOW_THR", "battery.low_threshold", REAL32, 0.12, 0.5, "low battery warning below, fraction"),
    ParamSpec("BAT_CRIT_THR", "battery.critical_threshold", REAL32, 0.05, 0.25, "critical level below, fraction"),
    ParamSpec("BAT_EMERGEN_THR", "battery.emergency_threshold", REAL32, 0.03, 0.1, "emergency level below"),
    ParamSpec("SIM_MOT_EFF", "battery.efficiency", REAL32, 0.2, 1.0, "motor + ESC efficiency, shaft/electric"),
    ParamSpec("SIM_AVIONICS_W", "battery.avionics_w", REAL32, 0.0, 500.0, "avionics load while armed, W"),
    ParamSpec(
        "COM_LOW_BAT_ACT",
        "failsafe.low_battery_action",
        INT32,
        0,
        3,
        "battery failsafe: 0 warning, 1 return, 2 land, 3 return at critical, land at emergency",
    ),
    ParamSpec(
        "COM_ARM_BAT_MIN", "failsafe.arm_battery_min", REAL32, -1.0, 0.9, "no arming below; negative: BAT_CRIT_THR"
    ),
    ParamSpec(
        "NAV_DLL_ACT",
        "failsafe.data_link_loss_action",
        INT32,
        0,
        3,
        "data link loss action: 0 disabled, 1 hold, 2 return, 3 land (5 terminate, 6 lockdown: not simulated)",
    ),
    ParamSpec(
        "COM_DL_LOSS_T", "failsafe.data_link_loss_timeout_s", REAL32, 5.0, 300.0, "no ground station this long (s)"
    ),
    ParamSpec("SYS_FAILURE_EN", "failsafe.failure_injection_enabled", INT32, 0, 1, "MAV_CMD_INJECT_FAILURE allowed"),
    # the simulation's pace, changeable in flight (ArduPilot SITL's name): an operator watches a mission at 1 after a
    # demo flown at full lockstep speed (stack.up --real-time); the same range as --speed
    ParamSpec(
        "SIM_SPEEDUP",
        "simulation.speedup",
        REAL32,
        0.0,
        1000.0,
        "at most this many times real time; 0: as fast as lockstep goes (paced: --speed)",
    ),
]
