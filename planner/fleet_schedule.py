"""Take-offs and landings of vehicles that share a depot, one at a time, so that any two vehicles in the air stay
``separation_m`` apart around the depot.

Vehicles whose homes (pads) lie within SHARED_DEPOT_M of each other share a depot. Their depot zone is the circle
about the pads' centre that reaches ``separation_m`` beyond the farthest pad: a vehicle outside it is at least
``separation_m`` (horizontally) from every pad, so from another vehicle climbing from or descending onto its own
pad. Inside it, one vehicle at a time:
- departures, in the vehicles' order: the first starts at once, each next one when the one before has left the
  zone (the service starts its mission then: gcs.missions.fleet_missions launches it on that event, so the rule
  holds whatever the timing turns out to be); the plan predicts when, from the predicted timeline
  (planner.fleet_time.share_timeline), plus LAUNCH_LATENCY_S for the service to see it and start the next;
- arrivals: each vehicle's window, from entering the zone on its way home to its disarm (widened by a margin for
  the prediction's error, ``margin_s``), must not overlap another's nor any departure; a vehicle that would arrive
  too early hovers longer at its last buoy (its waypoint's hold time, param1 of MAV_CMD_NAV_WAYPOINT), away from
  the depot at its own layer.

The plan accounts for both: ``split_offsets`` gives the fleet planner (planner.fleet's takeoff_landing_s) each
vehicle's wait before its start and the landings after its own, so the min-max split gives the vehicle that leaves
last fewer buoys; ``schedule`` then times the planned shares exactly. Pure computation.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from planner.energy import EnergyModel
from planner.fleet_time import ShareTimeline, TimedLeg, share_timeline
from uavcore.motion_profiles import cut_at_distance, rest_to_rest_spans

SHARED_DEPOT_M = 50.0  # homes closer than this share a depot: a vehicle leaving one would pass over the other
LAUNCH_LATENCY_S = 1.0  # the service's poll (0.5 s), the mission's upload, the arming: its event to the next start
MARGIN_S = 2.0  # an arrival window is widened on each side by this plus MARGIN_FRACTION of its predicted time:
MARGIN_FRACTION = 0.01  # the predictions' error grows with the time flown (bench.fleet_flown: within 1-2 %)


@dataclass(frozen=True)
class DepotZone:
    """The vehicles sharing a depot (indices, in departure order) and the circle they take off and land in."""

    centre_en: np.ndarray
    radius_m: float
    vehicles: list[int]


def depot_zones(homes_en, separation_m: float) -> list[DepotZone]:
    """Group the vehicles' homes ((K, 2) [east, north] m) into depots (SHARED_DEPOT_M), each with its zone."""
    homes = np.asarray(homes_en, dtype=float).reshape(-1, 2)
    group = list(range(len(homes)))

    def root(k: int) -> int:
        while group[k] != k:
            k = group[k]
        return k

    for a in range(len(homes)):
        for b in range(a + 1, len(homes)):
            if math.dist(homes[a], homes[b]) < SHARED_DEPOT_M:
                group[root(b)] = root(a)
    zones = []
    for r in sorted({root(k) for k in range(len(homes))}):
        members = [k for k in range(len(homes)) if root(k) == r]
        centre = homes[members].mean(axis=0)
        reach = max(math.dist(homes[k], centre) for k in members)
        zones.append(DepotZone(centre, reach + separation_m, members))
    return zones


def _cover_s(leg: TimedLeg, distance: float, model: EnergyModel, speed_m_s: float) -> float:
    """Time from the leg's start until `distance` metres of it are flown (its rest-to-rest S-curve)."""
    nav = model.navigator
    length = math.dist(leg.start_en, leg.end_en)
    spans = rest_to_rest_spans(length, speed_m_s, nav.acceleration_m_s2, nav.jerk_m_s3)
    return sum(span[0] for span in cut_at_distance(spans, distance))


def _crossings(leg: TimedLeg, zone: DepotZone) -> tuple[float, float] | None:
    """(s_in, s_out): where along the leg the line through it enters and leaves the zone's circle (None: never)."""
    length = math.dist(leg.start_en, leg.end_en)
    if length <= 0.0:
        return None
    u = (leg.end_en - leg.start_en) / length
    d = leg.start_en - zone.centre_en
    b, c = float(d @ u), float(d @ d) - zone.radius_m**2
    if b * b - c < 0.0:
        return None
    root = math.sqrt(b * b - c)
    return -b - root, -b + root


def zone_exit_s(timeline: ShareTimeline, zone: DepotZone, model: EnergyModel, speed_m_s: float) -> float:
    """When the vehicle first leaves the zone after its start (its whole flight when it never does)."""
    for leg in timeline.legs:
        crossing = _crossings(leg, zone)
        if crossing is not None and 0.0 <= crossing[1] <= math.dist(leg.start_en, leg.end_en):
            return leg.start_s + _cover_s(leg, crossing[1], model, speed_m_s)
    return timeline.time_s


def zone_entry_s(timeline: ShareTimeline, zone: DepotZone, model: EnergyModel, speed_m_s: float) -> float:
    """When the vehicle last enters the zone on its way home (0 when it never leaves it)."""
    for leg in reversed(timeline.legs):
        crossing = _crossings(leg, zone)
        if crossing is not None and 0.0 <= crossing[0] <= math.dist(leg.start_en, leg.end_en):
            return leg.start_s + _cover_s(leg, crossing[0], model, speed_m_s)
    return 0.0


def margin_s(at_s: float) -> float:
    return MARGIN_S + MARGIN_FRACTION * at_s


@dataclass(frozen=True)
class Slot:
    """A vehicle's place in its depot's sequence: its predicted mission start (seconds after the fleet's start),
    the vehicle whose leaving the zone starts it (None: it starts at once), and the extra hold at its last buoy."""

    start_s: float
    after: int | None
    hold_s: float
    exit_s: float  # after its own start: when it leaves the zone (the next one starts then)
    entry_s: float  # after its own start, without the hold: when it enters the zone on its way home


def schedule(
    zones: list[DepotZone], timelines: dict[int, ShareTimeline], model: EnergyModel, speed_m_s: float
) -> dict[int, Slot]:
    """Each flying vehicle's slot (timelines: vehicle index -> its share's predicted timeline; a vehicle without
    one stays on the ground and has no slot)."""
    slots: dict[int, Slot] = {}
    for zone in zones:
        flying = [k for k in zone.vehicles if k in timelines]
        exits = {k: zone_exit_s(timelines[k], zone, model, speed_m_s) for k in flying}
        entries = {k: zone_entry_s(timelines[k], zone, model, speed_m_s) for k in flying}
        starts, t, before, departures_end = {}, 0.0, None, 0.0
        after: dict[int, int | None] = {}
        for k in flying:
            starts[k], after[k] = t, before
            departures_end = t + exits[k]
            t, before = departures_end + LAUNCH_LATENCY_S, k
        free_from = departures_end  # the zone is free for arrivals once the last one has left it
        for k in sorted(flying, key=lambda k: starts[k] + timelines[k].time_s):
            end = starts[k] + timelines[k].time_s
            # the least hold with start + hold + entry - margin_s(end + hold) >= free_from (the margin grows with it)
            hold = max(0.0, (free_from - (starts[k] + entries[k] - margin_s(end))) / (1.0 - MARGIN_FRACTION))
            free_from = end + hold + margin_s(end + hold)
            slots[k] = Slot(starts[k], after[k], hold, exits[k], entries[k])
    return slots


def split_offsets(
    zones: list[DepotZone],
    homes_en,
    altitude_of: Callable[[int], float],
    speed_m_s: float,
    dwell_s: float,
    model: EnergyModel,
) -> np.ndarray:
    """What each vehicle's flight must leave room for in the min-max split, before its buoys are known: the
    departures before its own (each vehicle's predicted time to leave the zone, plus the launch latency) and the
    arrivals after its own (in the same order: the first to leave lands first). Estimated on an out-and-back
    due south (a half turn from the north the vehicles stand facing: the longest turn) past the zone."""
    homes = np.asarray(homes_en, dtype=float).reshape(-1, 2)
    offsets = np.zeros(len(homes))
    for zone in zones:
        leave, occupy = {}, {}
        for k in zone.vehicles:
            away = homes[k] + np.array([0.0, -(2.0 * zone.radius_m + 100.0)])
            timeline = share_timeline([homes[k], away], altitude_of(k), speed_m_s, dwell_s, model)
            leave[k] = zone_exit_s(timeline, zone, model, speed_m_s) + LAUNCH_LATENCY_S
            entry = zone_entry_s(timeline, zone, model, speed_m_s)
            occupy[k] = timeline.time_s - entry + 2.0 * MARGIN_S
        for position, k in enumerate(zone.vehicles):
            offsets[k] = sum(leave[j] for j in zone.vehicles[:position])
            offsets[k] += sum(occupy[j] for j in zone.vehicles[position + 1 :])
    return offsets
