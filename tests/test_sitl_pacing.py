"""Paced mode's clock (sitl_quad.pacing): a vehicle behind the wall clock sprints or re-anchors, and a message
that reached the socket meanwhile belongs to the simulated time its arrival names."""

from __future__ import annotations

import pytest

from sitl_quad.pacing import RESYNC_BEHIND_S, WallPacing


def test_ticks_are_due_at_the_wall_time_their_simulated_time_maps_to():
    pacing = WallPacing(speed=5.0, wall_anchor=100.0, sim_anchor=20.0)
    assert pacing.due(25.0) == pytest.approx(101.0)
    assert pacing.behind_s(101.3, 25.0) == pytest.approx(0.3)
    assert pacing.behind_s(100.5, 25.0) == pytest.approx(-0.5)


def test_a_message_read_on_time_belongs_to_the_current_tick():
    pacing = WallPacing(speed=1.0, wall_anchor=0.0, sim_anchor=0.0)
    # the vehicle at 10.00 s waits for its next tick (due at wall 10.00); a message arrived at 9.99
    assert pacing.arrival_time(arrived_at=9.99, now=9.995, sim_t=10.0) == 10.0


def test_a_message_read_late_belongs_to_when_it_arrived():
    """0.45 s behind, the vehicle will sprint through the time it missed: a setpoint that arrived 0.3 s into the
    stall is 0.3 s younger than the tick that reads it."""
    pacing = WallPacing(speed=1.0, wall_anchor=0.0, sim_anchor=0.0)
    assert not pacing.must_resync(now=10.45, sim_t=10.0)
    assert pacing.arrival_time(arrived_at=10.3, now=10.45, sim_t=10.0) == pytest.approx(10.3)
    # at 4x the wall second is four simulated ones
    fast = WallPacing(speed=4.0, wall_anchor=0.0, sim_anchor=0.0)
    assert fast.arrival_time(arrived_at=2.6, now=2.7, sim_t=10.0) == pytest.approx(10.4)


def test_a_vehicle_too_far_behind_re_anchors_and_reads_messages_at_its_own_time():
    pacing = WallPacing(speed=1.0, wall_anchor=0.0, sim_anchor=0.0)
    now = 10.0 + RESYNC_BEHIND_S + 0.2
    assert pacing.must_resync(now, sim_t=10.0)
    assert pacing.arrival_time(arrived_at=10.6, now=now, sim_t=10.0) == 10.0
    pacing.resync(now, 10.0)
    assert pacing.due(10.0) == now and not pacing.must_resync(now, 10.0)
