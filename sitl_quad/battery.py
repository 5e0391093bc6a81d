"""The flight battery: electrical power from the rotors' mechanical power, a LiPo pack that delivers it.

Pure computation in simulated time; parameters are data (`BatteryConfig`, named as PX4 names them).

Power. Each rotor turns against its aerodynamic drag torque Q_i = kf * Omega_i^2, so the motors deliver
P_mech = sum_i Q_i * Omega_i = kf * sum_i Omega_i^3. We take the paper's Table 2 drag coefficient kf
(7.47e-7) as that per-rotor torque coefficient, its textbook meaning, and not the L * kf the paper's eq. (1)
applies to the body's yaw (see sitl_quad/rotors.py). kf / kl = 26 mm of torque per newton of thrust lies in
the range of 10-13 inch propellers (about 17 mm for a 10x4.7, 25 mm for a 13 inch), and hover then costs
112 W of shaft power: a figure of merit T^1.5 / sqrt(2 rho A) / P_mech of 0.58 on 10 inch propellers, 0.44
on 13 inch, where small propellers reach 0.4-0.65; L * kf would halve the power and put a 10 inch propeller
above 1, which no propeller reaches.
The pack supplies P = P_mech / eta + P_avionics: eta is the motor + ESC efficiency (0.76 = an 80 % motor
at hover load behind a 95 % ESC), P_avionics the flight controller, GNSS, radios and the inspection
camera's computer (8 W), drawn while armed. Rotor inertia (spin-up energy) is neglected: at hover it
averages out.

Pack. n cells in series, each an open-circuit voltage OCV(SOC) behind an internal resistance R: the
terminal voltage is V = n (OCV - I R), and the current that delivers P solves n R I^2 - n OCV I + P = 0 (the
smaller root; past the pack's maximum power n OCV^2 / (4 R) the voltage collapses to n OCV / 2). The
state of charge falls by the coulombs drawn: dSOC = -I dt / capacity. OCV(SOC) has the shape of the usual
LiPo rest-voltage chart (uavcore.battery_pack.OCV_CHART), stretched to span [BAT1_V_EMPTY, BAT1_V_CHARGED]: PX4
defines those two under a 5C load for its voltage-based estimate; here the model knows its charge and reports it as a
current-integrating PX4 estimate would, so the two only bound the curve. Temperature is not modelled.
The pack does not limit the motors: flying on past 0 % keeps flying at 0 %, which is what the failsafes
(COM_LOW_BAT_ACT) are there to prevent.

Defaults and what they give (`python -m bench.battery_endurance` flies the 1.3 kg Table 2 vehicle in
simulated time; bench/results/battery_endurance.json): a 4S 4000 mAh pack (59 Wh nominal, 61 Wh delivered
along the chart; ~420 g, a fair share of 1.3 kg). Hover draws 158 W (10.4 A, 2.6C, 122 W/kg): 23.2 min to
empty, 21.7 min to BAT_CRIT_THR. Cruising at 10 m/s (back and forth on a 1 km line) draws 165 W: 22.2 min and
12.2 km to empty. The Table 2 drag tilts the thrust, so cruise costs 4 % more than hover here; the rotor model
has no translational lift, which on real quadrotors makes 10 m/s cheaper than hover, so the cruise figure is
conservative. Quadrotors of this mass: a 1.5 kg F450-class frame on 4S 5000 mAh (74 Wh) hovers 15-20 min;
a 1.38 kg DJI Phantom 4 flies about 28 min on its 89 Wh pack, some 190 W or 138 W/kg. At 122 W/kg this model
is an efficient but plausible vehicle of the kind (its 0.5 m arms leave room for large propellers).

Warnings follow PX4's battery_status: LOW below BAT_LOW_THR, CRITICAL below BAT_CRIT_THR, EMERGENCY below
BAT_EMERGEN_THR (fractions of charge; sitl_quad.failsafe says what each does under COM_LOW_BAT_ACT).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from enum import IntEnum

from uavcore.battery_pack import PackSpec

SECONDS_PER_HOUR = 3600.0


class BatteryWarning(IntEnum):
    """PX4's battery_status warning levels (MAV_BATTERY_CHARGE_STATE is these + 1)."""

    NONE = 0
    LOW = 1
    CRITICAL = 2
    EMERGENCY = 3


@dataclass(frozen=True)
class BatteryConfig(PackSpec):
    """The pack and its thresholds (uavcore.battery_pack.PackSpec, PX4's BAT1_* and BAT_*_THR: what a ground
    station can read) and the power chain behind it, which only the simulation knows."""

    efficiency: float = 0.76  # SIM_MOT_EFF: motor + ESC, shaft power / electrical power
    avionics_w: float = 8.0  # SIM_AVIONICS_W: drawn while armed

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.avionics_w < 0:
            raise ValueError(f"the avionics load must be >= 0, got {self.avionics_w}")
        if not 0 < self.efficiency <= 1:
            raise ValueError(f"efficiency must be in (0, 1], got {self.efficiency}")

    @property
    def capacity_coulombs(self) -> float:
        return self.capacity_mah * 3.6

    def warning(self, state_of_charge: float) -> BatteryWarning:
        """The most severe threshold the charge is below, as PX4's Battery::determineWarning."""
        if state_of_charge < self.emergency_threshold:
            return BatteryWarning.EMERGENCY
        if state_of_charge < self.critical_threshold:
            return BatteryWarning.CRITICAL
        if state_of_charge < self.low_threshold:
            return BatteryWarning.LOW
        return BatteryWarning.NONE


def rotor_mechanical_power(rotor_speeds: Iterable[float], drag_torque_coefficient: float) -> float:
    """Shaft power (W) of rotors turning at rotor_speeds (rad/s, >= 0) against Q = k Omega^2: k sum Omega^3."""
    return drag_torque_coefficient * sum([w * w * w for w in rotor_speeds])


def electrical_power(mechanical_w: float, config: BatteryConfig, armed: bool) -> float:
    """What the pack must deliver (W): the motors' shaft power through the motor + ESC efficiency, plus the
    avionics while armed."""
    return mechanical_w / config.efficiency + (config.avionics_w if armed else 0.0)


def pack_current(power_w: float, open_circuit_v: float, resistance_ohm: float) -> float:
    """Current (A) that delivers power_w at the terminals of a source open_circuit_v behind resistance_ohm:
    the smaller root of R I^2 - OCV I + P = 0; past the source's maximum power, the current at that maximum."""
    if power_w <= 0.0:
        return 0.0
    if resistance_ohm == 0.0:
        return power_w / open_circuit_v
    discriminant = open_circuit_v * open_circuit_v - 4.0 * resistance_ohm * power_w
    return (open_circuit_v - math.sqrt(max(discriminant, 0.0))) / (2.0 * resistance_ohm)


class Battery:
    """The pack's state: charge, the last current and terminal voltage, what has been consumed."""

    def __init__(self, config: BatteryConfig, state_of_charge: float = 1.0) -> None:
        self.config = config
        self.state_of_charge = 1.0
        self.current_a = 0.0
        self.voltage_v = 0.0
        self.power_w = 0.0
        self.consumed_mah = 0.0
        self.consumed_wh = 0.0
        # an injected battery failure (PX4's BatterySimulator `_force_empty_battery`): the pack reports empty, at
        # its empty voltage, while its true charge is kept (and is reported again once the failure is cleared)
        self.reads_empty = False
        self.reset(state_of_charge)

    def reset(self, state_of_charge: float = 1.0) -> None:
        """A fresh pack at state_of_charge in [0, 1] (a swap at the depot): nothing consumed, no load."""
        if not (math.isfinite(state_of_charge) and 0.0 <= state_of_charge <= 1.0):
            raise ValueError(f"state of charge must be in [0, 1], got {state_of_charge}")
        self.state_of_charge = float(state_of_charge)
        self.consumed_mah = self.consumed_wh = 0.0
        self.discharge(0.0, 0.0)

    @property
    def open_circuit_v(self) -> float:
        return self.config.cells * self.config.cell_ocv(self.state_of_charge)

    @property
    def resistance_ohm(self) -> float:
        return self.config.cells * self.config.r_internal

    @property
    def remaining_mah(self) -> float:
        return self.state_of_charge * self.config.capacity_mah

    @property
    def reported_charge(self) -> float:
        """The state of charge the vehicle's battery monitor reports (0..1): the true one unless reads_empty."""
        return 0.0 if self.reads_empty else self.state_of_charge

    @property
    def reported_voltage_v(self) -> float:
        """The terminal voltage the monitor reports: every cell at BAT1_V_EMPTY while reads_empty."""
        return self.config.cells * self.config.v_empty if self.reads_empty else self.voltage_v

    @property
    def warning(self) -> BatteryWarning:
        return self.config.warning(self.reported_charge)

    def draw(self, power_w: float, dt: float) -> None:
        """Deliver power_w (W) for dt seconds of simulated time."""
        open_circuit_v, resistance_ohm = self.open_circuit_v, self.resistance_ohm
        self._discharge(pack_current(power_w, open_circuit_v, resistance_ohm), dt, open_circuit_v, resistance_ohm)

    def discharge(self, current_a: float, dt: float) -> None:
        """Deliver current_a (A) for dt seconds: the charge falls by the coulombs drawn (clipped at empty)."""
        self._discharge(current_a, dt, self.open_circuit_v, self.resistance_ohm)

    def _discharge(self, current_a: float, dt: float, open_circuit_v: float, resistance_ohm: float) -> None:
        self.current_a = current_a
        self.voltage_v = open_circuit_v - current_a * resistance_ohm
        self.power_w = self.voltage_v * current_a
        coulombs = current_a * dt
        self.state_of_charge = max(0.0, self.state_of_charge - coulombs / self.config.capacity_coulombs)
        self.consumed_mah += coulombs / 3.6
        self.consumed_wh += self.power_w * dt / SECONDS_PER_HOUR

    def time_remaining_s(self) -> float | None:
        """Seconds to empty at the present current (None while drawing almost nothing)."""
        if self.current_a < 0.1:
            return None
        return self.remaining_mah * 3.6 / self.current_a
