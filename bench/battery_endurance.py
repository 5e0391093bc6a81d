"""Flight endurance of the Table 2 vehicle on its default pack (sitl_quad.battery), flown in simulated time.

    .venv/bin/python -m bench.battery_endurance     # prints a table, writes bench/results/battery_endurance.json

Two flights of the vehicle itself (its built-in PID loops, no wind; the default D terms and sensor noise, seed
1), each from a full pack until the pack is empty, with COM_LOW_BAT_ACT at its default (warn only) so nothing
lands early:
- hover: take off to 10 m and hold;
- cruise: a mission at 10 m/s (the paper's speed), back and forth along a 1 km line at 10 m altitude.
For each: the time from arming to the low, critical and empty levels, the mean electrical power and current
once airborne, the pack voltage, and for the cruise the distance flown. Deterministic: the same numbers on
any machine; about 20 s of wall clock.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

from sitl_quad.battery import BatteryWarning
from sitl_quad.config import VehicleConfig
from sitl_quad.vehicle import Vehicle
from uavcore.geodesy import DEFAULT_HOME, LocalFrame
from uavcore.mission import MavCmd, MavFrame, MissionItem

RESULTS = Path(__file__).resolve().parent / "results"
ALTITUDE_M = 10.0
CRUISE_SPEED_M_S = 10.0
LINE_M = 1000.0
MAX_FLIGHT_S = 3600.0  # a safety stop: the default pack empties in well under half of this
SETTLE_S = 30.0  # power averages start this long after arming (spool-up and climb excluded)


def cruise_mission(legs: int) -> list[MissionItem]:
    """Take off, set 10 m/s, then `legs` waypoints alternating between the far end of the line and home."""
    frame = LocalFrame(*DEFAULT_HOME)

    def item(seq: int, command: int, north: float, **params: float) -> MissionItem:
        lat, lon, _ = frame.from_ned(north, 0.0, 0.0)
        return MissionItem(
            seq=seq,
            frame=MavFrame.GLOBAL_RELATIVE_ALT_INT,
            command=command,
            current=int(seq == 0),
            x=round(float(lat) * 1e7),
            y=round(float(lon) * 1e7),
            z=ALTITUDE_M,
            **params,
        )

    items = [
        item(0, MavCmd.NAV_TAKEOFF, 0.0),
        MissionItem(seq=1, frame=MavFrame.MISSION, command=MavCmd.DO_CHANGE_SPEED, param1=1, param2=CRUISE_SPEED_M_S),
    ]
    for k in range(legs):
        items.append(item(len(items), MavCmd.NAV_WAYPOINT, LINE_M if k % 2 == 0 else 0.0, param1=0.0, param2=2.0))
    return items


def fly_until_empty(vehicle: Vehicle) -> dict:
    """Tick an armed, commanded vehicle until its pack is empty; times are seconds since arming."""
    battery = vehicle.battery
    start = vehicle.t
    first_at: dict[str, float] = {}
    energy_j = charge_c = settled_s = distance_m = 0.0
    previous = vehicle.truth.position.copy()
    voltage_at_settle = None
    while battery.state_of_charge > 0.0 and vehicle.t - start < MAX_FLIGHT_S:
        vehicle.tick()
        elapsed = vehicle.t - start
        for level in (BatteryWarning.LOW, BatteryWarning.CRITICAL):
            if battery.warning >= level:
                first_at.setdefault(level.name.lower(), elapsed)
        position = vehicle.truth.position
        distance_m += float(((position[:2] - previous[:2]) ** 2).sum() ** 0.5)
        previous = position.copy()
        if elapsed >= SETTLE_S:
            voltage_at_settle = voltage_at_settle or battery.voltage_v
            energy_j += battery.power_w * vehicle.outer_dt
            charge_c += battery.current_a * vehicle.outer_dt
            settled_s += vehicle.outer_dt
    if battery.state_of_charge > 0.0:
        raise RuntimeError(f"the pack still holds {battery.state_of_charge:.0%} after {MAX_FLIGHT_S} s")
    empty_s = vehicle.t - start
    return {
        "time_to_low_s": first_at.get("low"),
        "time_to_critical_s": first_at.get("critical"),
        "time_to_empty_s": empty_s,
        "endurance_to_empty_min": empty_s / 60.0,
        "mean_power_w": energy_j / settled_s,
        "mean_current_a": charge_c / settled_s,
        "pack_voltage_after_settle_v": voltage_at_settle,
        "pack_voltage_at_empty_v": battery.voltage_v,
        "consumed_mah": battery.consumed_mah,
        "consumed_wh": battery.consumed_wh,
        "distance_flown_km": distance_m / 1000.0,
        "altitude_at_empty_m": float(-vehicle.truth.position[2]),
    }


def hover() -> dict:
    vehicle = Vehicle(VehicleConfig(), home=DEFAULT_HOME, seed=1)
    vehicle.arm()
    vehicle.takeoff(ALTITUDE_M)
    return fly_until_empty(vehicle)


def cruise() -> dict:
    vehicle = Vehicle(VehicleConfig(), home=DEFAULT_HOME, seed=1)
    legs = int(MAX_FLIGHT_S * CRUISE_SPEED_M_S / LINE_M) + 2  # more line than the pack can fly
    vehicle.set_mission(cruise_mission(legs))
    vehicle.arm()
    vehicle.start_mission()
    return fly_until_empty(vehicle)


def main() -> None:
    config = VehicleConfig()
    pack, airframe = config.battery, config.airframe
    started = time.perf_counter()
    result = {
        "pack": {
            "cells": pack.cells,
            "capacity_mah": pack.capacity_mah,
            "nominal_energy_wh": pack.cells * 3.7 * pack.capacity_mah / 1000.0,
            "r_internal_per_cell_ohm": pack.r_internal,
            "motor_esc_efficiency": pack.efficiency,
            "avionics_w": pack.avionics_w,
        },
        "airframe": {"mass_kg": airframe.mass, "kf": airframe.kf, "kl": airframe.kl},
        "hover": hover(),
        "cruise_10_m_s": cruise(),
    }
    result["hover_power_per_kg_w"] = result["hover"]["mean_power_w"] / airframe.mass
    result["wall_s"] = time.perf_counter() - started
    rows = [
        ("endurance to empty, min", "endurance_to_empty_min", "{:.1f}"),
        ("to BAT_LOW_THR (15 %), min", "time_to_low_s", "{:.1f}"),
        ("to BAT_CRIT_THR (7 %), min", "time_to_critical_s", "{:.1f}"),
        ("mean electrical power, W", "mean_power_w", "{:.0f}"),
        ("mean current, A", "mean_current_a", "{:.1f}"),
        ("pack voltage after 30 s / at empty, V", None, ""),
        ("energy drawn, Wh", "consumed_wh", "{:.1f}"),
        ("distance flown, km", "distance_flown_km", "{:.1f}"),
    ]
    print(f"{pack.cells}S {pack.capacity_mah:.0f} mAh pack, {airframe.mass} kg Table 2 airframe")
    print(f"{'':40} {'hover':>10} {'10 m/s':>10}")
    for label, key, fmt in rows:
        cells = []
        for case in ("hover", "cruise_10_m_s"):
            figures = result[case]
            if key is None:
                cells.append(f"{figures['pack_voltage_after_settle_v']:.1f}/{figures['pack_voltage_at_empty_v']:.1f}")
            else:
                value = figures[key] / 60.0 if key.startswith("time_to") else figures[key]
                cells.append(fmt.format(value))
        print(f"{label:40} {cells[0]:>10} {cells[1]:>10}")
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / "battery_endurance.json").write_text(json.dumps(result, indent=2) + "\n")
    print(f"\nwrote {RESULTS / 'battery_endurance.json'} ({result['wall_s']:.0f} s)")


if __name__ == "__main__":
    main()
