"""Paced mode's tie between simulated time and the wall clock (`--speed N`: N simulated seconds per wall second).

A tick is due when the wall clock reaches the time its simulated time maps to. A vehicle process that the
machine did not schedule for a while (a loaded machine; a suspended process) is then behind: up to
RESYNC_BEHIND_S it sprints through the ticks it owes, so simulated time keeps up with the wall clock; further
behind it re-anchors and carries on from where it was, rather than flying seconds of simulated time at once.

Messages that reached the socket while the vehicle was behind were sent at wall times its simulated clock had
not reached yet. They belong to the simulated time their arrival names (`arrival_time`; the link reads the
kernel's receive timestamp), not to the late tick that happens to read them: stamped at the late tick, a
setpoint stream that never paused looks up to RESYNC_BEHIND_S older than it is once the sprint has passed, and
the offboard-loss failsafe (OFFB_LOSS_T, then 0.5 s) ended healthy offboard flights because of the simulator's own lag
(MAVSDK's offboard_velocity_ned example in a test run beside two CPU burners). A real autopilot is never behind
its own clock.
"""

from __future__ import annotations

from dataclasses import dataclass

RESYNC_BEHIND_S = 0.5  # wall seconds behind: re-anchor instead of sprinting


@dataclass
class WallPacing:
    """Simulated time `sim_anchor` was due at wall time `wall_anchor`; `speed` simulated seconds per wall second."""

    speed: float
    wall_anchor: float
    sim_anchor: float

    def due(self, sim_t: float) -> float:
        """The wall time at which simulated time `sim_t` is due."""
        return self.wall_anchor + (sim_t - self.sim_anchor) / self.speed

    def behind_s(self, now: float, sim_t: float) -> float:
        """Wall seconds a vehicle at simulated time `sim_t` is late at wall time `now` (negative: early)."""
        return now - self.due(sim_t)

    def must_resync(self, now: float, sim_t: float) -> bool:
        return self.behind_s(now, sim_t) > RESYNC_BEHIND_S

    def resync(self, now: float, sim_t: float) -> None:
        """Carry on from `sim_t` as if it were due now (the lag is not sprinted through)."""
        self.wall_anchor, self.sim_anchor = now, sim_t

    def arrival_time(self, arrived_at: float, now: float, sim_t: float) -> float:
        """The simulated time of a message that reached the socket at wall time `arrived_at`, read at `now` by a
        vehicle at simulated time `sim_t`: the time its arrival names, never before `sim_t`.

        A vehicle further than RESYNC_BEHIND_S behind re-anchors at `sim_t` rather than sprinting through the
        time it missed, so a message it reads then belongs to `sim_t`.
        """
        if self.must_resync(now, sim_t):
            return sim_t
        return max(sim_t, self.sim_anchor + (arrived_at - self.wall_anchor) * self.speed)
