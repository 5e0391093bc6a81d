"""A LiPo flight pack as the vehicle's parameters describe it (PX4's BAT1_* names), and the energy it holds.

Shared by the simulator's battery (sitl_quad.battery, which discharges it) and the ground station's planning
(gcs.missions.energy_planning, which turns a charge reserve into the watt-hours a sortie may use). Pure computation.

The open-circuit voltage of a cell against its state of charge has the shape of the widely published LiPo
rest-voltage chart (`OCV_CHART`), stretched to span [BAT1_V_EMPTY, BAT1_V_CHARGED]. The energy between two
states of charge is the integral of the terminal voltage over the charge drawn,
    E = capacity * integral_{soc_low}^{soc_high} n (OCV(soc) - I R) d soc,   I = P / (n OCV)
at a steady load P (the I R drop is the energy the pack's own resistance keeps; ~1 % at hover for the default
pack). The warning thresholds (BAT_LOW_THR etc.) are fractions of charge, as PX4's battery_status reports them.
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass
from typing import Any

# Rest (open-circuit) voltage of one LiPo cell at 0 %, 5 %, ..., 100 % charge: the widely published LiPo
# voltage chart. Only its shape is used (normalised, then stretched between BAT1_V_EMPTY and BAT1_V_CHARGED).
OCV_CHART = (
    3.27, 3.61, 3.69, 3.71, 3.73, 3.75, 3.77, 3.79, 3.80, 3.82, 3.84,
    3.85, 3.87, 3.91, 3.95, 3.98, 4.02, 4.08, 4.11, 4.15, 4.20,
)  # fmt: skip
_SOC_POINTS = tuple(i / (len(OCV_CHART) - 1) for i in range(len(OCV_CHART)))
_SHAPE = tuple((v - OCV_CHART[0]) / (OCV_CHART[-1] - OCV_CHART[0]) for v in OCV_CHART)
ENERGY_STEPS = 200  # midpoint rule over the charge interval: exact to ~1e-5 for the piecewise-linear chart

# The pack parameters by their PX4 names, and the PackSpec field each one sets.
PACK_PARAMETERS = {
    "BAT1_N_CELLS": "cells",
    "BAT1_CAPACITY": "capacity_mah",
    "BAT1_V_CHARGED": "v_charged",
    "BAT1_V_EMPTY": "v_empty",
    "BAT1_R_INTERNAL": "r_internal",
    "BAT_LOW_THR": "low_threshold",
    "BAT_CRIT_THR": "critical_threshold",
    "BAT_EMERGEN_THR": "emergency_threshold",
}


def cell_ocv(state_of_charge: float, v_empty: float, v_charged: float) -> float:
    """Open-circuit voltage of one cell (V) at a state of charge in [0, 1] (clipped), from OCV_CHART."""
    soc = min(max(state_of_charge, 0.0), 1.0)
    i = min(bisect.bisect_right(_SOC_POINTS, soc), len(_SOC_POINTS) - 1)
    s0, s1, y0, y1 = _SOC_POINTS[i - 1], _SOC_POINTS[i], _SHAPE[i - 1], _SHAPE[i]
    shape = y0 + (y1 - y0) * (soc - s0) / (s1 - s0)
    return v_empty + (v_charged - v_empty) * shape


@dataclass(frozen=True)
class PackSpec:
    """The pack and its warning thresholds (PX4 parameter names in the comments; defaults are the simulator's)."""

    cells: int = 4  # BAT1_N_CELLS, in series
    capacity_mah: float = 4000.0  # BAT1_CAPACITY
    v_charged: float = 4.20  # BAT1_V_CHARGED, V per cell: open-circuit voltage full
    v_empty: float = 3.30  # BAT1_V_EMPTY, V per cell: open-circuit voltage empty
    r_internal: float = 0.005  # BAT1_R_INTERNAL, ohm per cell
    low_threshold: float = 0.15  # BAT_LOW_THR, fraction of charge
    critical_threshold: float = 0.07  # BAT_CRIT_THR
    emergency_threshold: float = 0.05  # BAT_EMERGEN_THR

    def __post_init__(self) -> None:
        if self.cells < 1 or not self.capacity_mah > 0 or self.r_internal < 0:
            raise ValueError("the pack needs at least one cell, a positive capacity and R >= 0")
        if not 0 < self.v_empty < self.v_charged:
            raise ValueError(f"BAT1_V_EMPTY ({self.v_empty}) must be below BAT1_V_CHARGED ({self.v_charged})")

    @classmethod
    def from_parameters(cls, values: dict[str, float]) -> PackSpec:
        """From the vehicle's parameters by PX4 name (PACK_PARAMETERS); the ones missing keep their default."""
        # keyword arguments of the dataclass, each of its field's type (cells an int below, the others floats)
        fields: dict[str, Any] = {
            PACK_PARAMETERS[name]: value for name, value in values.items() if name in PACK_PARAMETERS
        }
        if "cells" in fields:
            fields["cells"] = int(fields["cells"])
        return cls(**fields)

    def cell_ocv(self, state_of_charge: float) -> float:
        return cell_ocv(state_of_charge, self.v_empty, self.v_charged)

    def energy_wh(self, soc_high: float = 1.0, soc_low: float = 0.0, load_w: float = 0.0) -> float:
        """Watt-hours the pack delivers at its terminals while its charge falls from soc_high to soc_low under a
        steady load of load_w watts (the integral in the module's docstring)."""
        if not 0.0 <= soc_low <= soc_high <= 1.0:
            raise ValueError(f"need 0 <= soc_low <= soc_high <= 1, got {soc_low}, {soc_high}")
        step = (soc_high - soc_low) / ENERGY_STEPS
        volt_fraction = 0.0
        for k in range(ENERGY_STEPS):
            ocv = self.cells * self.cell_ocv(soc_low + (k + 0.5) * step)
            current = load_w / ocv
            volt_fraction += (ocv - current * self.cells * self.r_internal) * step
        return self.capacity_mah / 1000.0 * volt_fraction

    def charge_after(self, energy_wh: float, soc_high: float = 1.0, load_w: float = 0.0) -> float:
        """The state of charge left after delivering energy_wh from soc_high (0 when the pack cannot)."""
        if energy_wh >= self.energy_wh(soc_high, 0.0, load_w):
            return 0.0
        low, high = 0.0, soc_high
        for _ in range(40):  # bisection: energy_wh(soc_high, s) falls as s rises
            mid = 0.5 * (low + high)
            if self.energy_wh(soc_high, mid, load_w) > energy_wh:
                low = mid
            else:
                high = mid
        return 0.5 * (low + high)

    @property
    def nominal_wh(self) -> float:
        """The pack's full energy at rest (no load)."""
        return self.energy_wh()
