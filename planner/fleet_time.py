"""The fleet's time model: the calibrated motion profiles the sortie planner prices (planner.energy), in the form the
fleet planner (planner.fleet) adds up, and a share's exact predicted timeline.

One model, two forms, as for the sortie planner (planner.energy.calibrated_sortie_cost):
- the planner's sums (``fleet_time_terms``): each leg a rest-to-rest S-curve at the cruise speed
  (planner.energy.leg_durations_s: the acceleration from and the stop at every buoy), each buoy its dwell, a turn
  of the fitted mean angle before its leg and its item's hand-over, each vehicle its fixed part at its own layer
  (spool-up, the climb to its layer, the take-off's hand-over, the climb to the return altitude if its layer is
  lower, a mean turn before the leg home, the descent and the touchdown: planner.energy.SortieTimes);
- a planned share's exact timeline (``share_timeline``): planner.energy.route_timeline, the phases the navigator
  flies (sitl_quad.navigator: PX4's mission sequencing) with the real turn angles of its order.

Still air: the commanded speeds are ground speeds, so the wind changes the energy and not the durations.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planner.distances import check_points, euclidean_matrix
from planner.energy import EnergyModel, Phase, RouteFlight, leg_durations_s, route_timeline, sortie_times


@dataclass(frozen=True)
class FleetTimeTerms:
    """plan_fleet's inputs for the calibrated model: pass leg_time_s, dwell_s (per node) and fixed_s (per vehicle,
    as takeoff_landing_s)."""

    leg_time_s: np.ndarray  # (n, n) symmetric
    dwell_s: np.ndarray  # (n,) the dwell, the mean turn and the hand-over of each buoy; 0 at the depots
    fixed_s: np.ndarray  # (K,) each vehicle's fixed part at its altitude


def fleet_time_terms(
    points, depot_of_vehicle, altitudes_m, speed_m_s: float, dwell_s: float, model: EnergyModel
) -> FleetTimeTerms:
    """The model's terms for planar points ((n, 2) metres), the vehicles' depots (node indices) and altitudes."""
    pts = check_points(points)
    times = [sortie_times(RouteFlight(float(altitude), speed_m_s, dwell_s), model) for altitude in altitudes_m]
    per_buoy = np.full(len(pts), times[0].per_buoy_s + times[0].dwell_s)  # a buoy's terms do not depend on altitude
    per_buoy[np.asarray(depot_of_vehicle, dtype=np.int64)] = 0.0
    return FleetTimeTerms(
        leg_time_s=leg_durations_s(euclidean_matrix(pts), speed_m_s, model.navigator),
        dwell_s=per_buoy,
        fixed_s=np.array([t.fixed_s + t.return_s for t in times]),
    )


@dataclass(frozen=True)
class TimedLeg:
    """One straight leg of a share's timeline: from, to ([east, north] m), when it starts, how long it takes."""

    start_en: np.ndarray
    end_en: np.ndarray
    start_s: float
    duration_s: float


@dataclass(frozen=True)
class ShareTimeline:
    """A share's predicted flight, its mission start to its disarm: the total and its straight legs."""

    time_s: float
    legs: list[TimedLeg]


def share_timeline(route_en, altitude_m: float, speed_m_s: float, dwell_s: float, model: EnergyModel) -> ShareTimeline:
    """route_en: the vehicle's home, then its buoys in flying order ([east, north] m); the return is RTL's."""
    route = np.asarray(route_en, dtype=float).reshape(-1, 2)
    phases: list[Phase] = route_timeline(route, RouteFlight(altitude_m, speed_m_s, dwell_s), model)
    legs, t = [], 0.0
    ends = [*route[1:], route[0]]  # item k flies to buoy k; the return (item -1) home
    starts = list(route)
    for phase in phases:
        if phase.name == "leg":
            index = phase.item - 1 if phase.item > 0 else len(route) - 1
            legs.append(TimedLeg(starts[index], ends[index], t, phase.time_s))
        t += phase.time_s
    return ShareTimeline(t, legs)
