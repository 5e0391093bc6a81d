"""The pack model the planning budgets with (uavcore.battery_pack) against the simulator's battery that flies."""

import pytest

from sitl_quad.battery import Battery, BatteryConfig
from uavcore.battery_pack import PACK_PARAMETERS, PackSpec


def drain_to(battery: Battery, power_w: float, state_of_charge: float, dt: float = 0.5) -> float:
    """Draw power_w from the simulator's pack until its charge is down to state_of_charge: the Wh delivered."""
    while battery.state_of_charge > state_of_charge:
        battery.draw(power_w, dt)
    return battery.consumed_wh


@pytest.mark.parametrize(("capacity_mah", "reserve", "power_w"), [(4000.0, 0.15, 160.0), (500.0, 0.07, 160.0)])
def test_energy_down_to_a_reserve_is_what_the_simulated_pack_delivers(capacity_mah, reserve, power_w):
    pack = PackSpec(capacity_mah=capacity_mah)
    delivered = drain_to(Battery(BatteryConfig(capacity_mah=capacity_mah)), power_w, reserve)
    assert pack.energy_wh(1.0, reserve, power_w) == pytest.approx(delivered, rel=0.005)


def test_the_internal_resistance_costs_energy_under_load():
    pack = PackSpec(r_internal=0.05)
    assert pack.energy_wh(1.0, 0.0, 300.0) < pack.energy_wh(1.0, 0.0, 0.0) == pytest.approx(pack.nominal_wh)


def test_charge_after_inverts_energy():
    pack = PackSpec()
    left = pack.charge_after(20.0, 1.0, 160.0)
    assert pack.energy_wh(1.0, left, 160.0) == pytest.approx(20.0, rel=1e-6)
    assert pack.charge_after(1000.0) == 0.0


def test_from_parameters_reads_px4_names_and_keeps_defaults_for_the_rest():
    pack = PackSpec.from_parameters({"BAT1_CAPACITY": 500.0, "BAT1_N_CELLS": 6.0, "BAT_LOW_THR": 0.2, "OTHER": 1.0})
    assert (pack.capacity_mah, pack.cells, pack.low_threshold) == (500.0, 6, 0.2)
    assert pack.v_charged == PackSpec().v_charged
    assert set(PACK_PARAMETERS.values()) <= set(PackSpec.__dataclass_fields__)


def test_a_pack_that_cannot_be_is_refused():
    with pytest.raises(ValueError, match="BAT1_V_EMPTY"):
        PackSpec(v_empty=4.3)
    with pytest.raises(ValueError, match="soc_low"):
        PackSpec().energy_wh(0.2, 0.5)
