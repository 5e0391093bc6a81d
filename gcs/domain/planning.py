"""From a validated request to a plan (route) and to the mission items the vehicle flies. No I/O.

The depot is node 0 of the planner's instance and the origin of the local frame; buoys are projected onto the
depot's tangent plane (uavcore.geodesy) so the planner works in metres.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import asdict, dataclass, replace
from typing import Any

import numpy as np

from gcs.domain.records import PlanEnergy, PlanFleet
from planner import plan_tour
from planner.distances import closed_tour_length, euclidean_matrix
from uavcore.geodesy import LocalFrame
from uavcore.geofence import Geofence
from uavcore.mission import MavCmd, MavFrame, MissionItem

# Mission layout: item 0 takeoff, item 1 speed, items 2..n+1 the buoys in visiting order, then the return.
FIRST_BUOY_SEQ = 2
SPEED_TYPE_GROUND = 1.0  # MavCmd.DO_CHANGE_SPEED param1
HOME_TOLERANCE_M = 1.0  # a depot this close to the vehicle's home returns with RTL, else waypoint + land
FENCED_LEG_PENALTY_M = 1e7  # longer than any tour a battery allows: a fenced leg is taken only if unavoidable


@dataclass(frozen=True)
class FlightParams:
    altitude_m: float
    speed_m_s: float
    dwell_s: float
    acceptance_radius_m: float
    override: bool = False  # fly even when the pre-flight charge check says the pack is short (recorded)


@dataclass(frozen=True)
class Plan:
    """A planned tour. Local coordinates are [east, north] metres from the depot."""

    depot: tuple[float, float]  # lat, lon
    buoy_ids: list[str]
    buoys_lat_lon: list[list[float]]
    buoys_local: list[list[float]]
    order: list[int]  # buoy indices (0-based, input order) in visiting order
    length_m: float
    input_order_length_m: float
    method: str
    elapsed_s: float
    # Multi-sortie missions (a battery cannot cover every buoy): the buoy indices of each sortie in flying order
    # (their concatenation is `order`); None for one tour. `energy` is the battery budget and each sortie's
    # predicted energy (gcs.missions.energy_planning), None when the request asked for no energy planning.
    sorties: list[list[int]] | None = None
    energy: PlanEnergy | None = None
    # A fleet mission (gcs.missions.fleet_planning): its shares, one part mission per vehicle; None otherwise
    fleet: PlanFleet | None = None

    def sortie_orders(self) -> list[list[int]]:
        """Each sortie's buoys in flying order: one sortie (the whole tour) unless the plan splits it."""
        return [list(s) for s in self.sorties] if self.sorties else [list(self.order)]

    def sortie_plan(self, k: int) -> Plan:
        """Sortie k as a plan of its own (the same buoys and depot, its order and length): what the vehicle
        flies, and what its progress and tracking are measured against."""
        single = replace(self, order=self.sortie_orders()[k], sorties=None, energy=None)
        return replace(single, length_m=float(np.hypot(*np.diff(single.route_local(), axis=0).T).sum()))

    @property
    def improvement_pct(self) -> float:
        """How much shorter than visiting the buoys in the order given, in percent of that order's length."""
        if self.input_order_length_m <= 0.0:
            return 0.0
        return 100.0 * (self.input_order_length_m - self.length_m) / self.input_order_length_m

    @property
    def frame(self) -> LocalFrame:
        return LocalFrame(self.depot[0], self.depot[1], 0.0)

    def route_nodes(self) -> list[int | None]:
        """The route as buoy indices, None for the depot: depot, each sortie's buoys and the depot again."""
        return [None, *(node for sortie in self.sortie_orders() for node in [*sortie, None])]

    def route_local(self) -> np.ndarray:
        """[east, north] of the route_nodes: (n + sorties + 1, 2); leg k runs from point k to point k + 1."""
        local = np.asarray(self.buoys_local, dtype=float).reshape(-1, 2)
        return np.array([[0.0, 0.0] if node is None else local[node] for node in self.route_nodes()])

    def route_lat_lon(self) -> list[list[float]]:
        depot = [self.depot[0], self.depot[1]]
        return [depot if node is None else list(self.buoys_lat_lon[node]) for node in self.route_nodes()]

    def first_leg_of_sortie(self, sortie: int) -> int:
        """The route's leg on which sortie `sortie` starts (each sortie has its buoys' legs and the way home)."""
        return sum(len(order) + 1 for order in self.sortie_orders()[:sortie])

    def to_dict(self) -> dict[str, Any]:
        """As stored (JSON)."""
        sections = {
            "energy": None if self.energy is None else self.energy.model_dump(mode="json"),
            "fleet": None if self.fleet is None else self.fleet.model_dump(mode="json"),
        }
        return asdict(replace(self, energy=None, fleet=None)) | sections

    @staticmethod
    def from_dict(data: dict[str, Any]) -> Plan:
        energy, fleet = data.get("energy"), data.get("fleet")
        return Plan(
            **{**data, "depot": tuple(data["depot"])}
            | {
                "energy": None if energy is None else PlanEnergy.model_validate(energy),
                "fleet": None if fleet is None else PlanFleet.model_validate(fleet),
            }
        )


def fenced_legs(depot: tuple[float, float], lat_lon: np.ndarray, fence: Geofence) -> dict[tuple[int, int], str]:
    """Every straight leg between two nodes (0 the depot, k the buoy k - 1) that breaks the fence, with the kind of
    zone it breaks (i < j)."""
    nodes = [tuple(depot), *map(tuple, lat_lon.tolist())]
    broken = {}
    for i, j in itertools.combinations(range(len(nodes)), 2):
        zone = fence.segment_violation(nodes[i], nodes[j])
        if zone is not None:
            broken[(i, j)] = zone.kind
    return broken


def local_nodes(
    depot: tuple[float, float], buoys: Sequence[Sequence[float]]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The buoys' [lat, lon] (n, 2), their local [east, north] (n, 2), and the distances between the n + 1 nodes
    (node 0 the depot)."""
    frame = LocalFrame(depot[0], depot[1], 0.0)
    lat_lon = np.asarray(buoys, dtype=float).reshape(-1, 2)
    local = frame.project(lat_lon)
    return lat_lon, local, euclidean_matrix(np.vstack([[0.0, 0.0], local]))


def make_plan(
    depot: tuple[float, float],
    buoys: list[tuple[float, float]],
    buoy_ids: list[str],
    method: str = "auto",
    seed: int = 0,
    time_limit_s: float = 2.0,
    fenced: dict[tuple[int, int], str] | None = None,
) -> Plan:
    """Plan the closed tour depot -> every buoy once -> depot. Raises planner.errors.InputError/TooLargeError.

    fenced: legs the fence forbids (`fenced_legs`); the planner sees them as very long, so it takes one only when
    no tour avoids them (the caller then refuses the plan), and the plan's length is the true one."""
    _, local, distance = local_nodes(depot, buoys)
    penalised = None
    if fenced:
        penalised = distance.copy()
        for i, j in fenced:
            penalised[i, j] = penalised[j, i] = distance[i, j] + FENCED_LEG_PENALTY_M
    points = np.vstack([[0.0, 0.0], local])
    result = plan_tour(points, method=method, seed=seed, time_limit_s=time_limit_s, distance=penalised)
    order = [int(node) - 1 for node in result.order[1:]]
    return sorties_plan(depot, buoys, buoy_ids, [order], str(result.method), float(result.elapsed_s))


def sorties_plan(
    depot: tuple[float, float],
    buoys: Sequence[Sequence[float]],  # [lat, lon] each: a request's tuples or a stored plan's lists
    buoy_ids: list[str],
    sorties: list[list[int]],
    method: str,
    elapsed_s: float,
    energy: PlanEnergy | None = None,
) -> Plan:
    """The Plan of given sorties (buoy indices, 0-based, in flying order; one sortie: a single tour)."""
    lat_lon, local, distance = local_nodes(depot, buoys)
    length = sum(closed_tour_length(np.array([0, *(b + 1 for b in sortie)]), distance) for sortie in sorties)
    return Plan(
        depot=(float(depot[0]), float(depot[1])),
        buoy_ids=list(buoy_ids),
        buoys_lat_lon=lat_lon.tolist(),
        buoys_local=local.tolist(),
        order=[b for sortie in sorties for b in sortie],
        length_m=float(length),
        input_order_length_m=float(closed_tour_length(np.arange(len(distance)), distance)),
        method=method,
        elapsed_s=elapsed_s,
        sorties=[list(sortie) for sortie in sorties] if len(sorties) > 1 else None,
        energy=energy,
    )


def _deg_e7(value: float) -> int:
    return round(value * 1e7)


def mission_items(plan: Plan, flight: FlightParams, home: tuple[float, float] | None = None) -> list[MissionItem]:
    """The mission: takeoff at the depot, cruise speed, one waypoint per buoy, then home and land.

    Waypoints carry param1 = dwell (hold time) and param2 = acceptance radius, as MAV_CMD_NAV_WAYPOINT defines.
    The return is MavCmd.NAV_RETURN_TO_LAUNCH when the depot is the vehicle's home; otherwise a waypoint at the depot
    and MavCmd.NAV_LAND there, so the vehicle comes back to the depot and not to wherever it booted.
    """
    depot_lat, depot_lon = plan.depot
    alt = float(flight.altitude_m)
    items = [
        MissionItem(
            seq=0,
            frame=MavFrame.GLOBAL_RELATIVE_ALT_INT,
            command=MavCmd.NAV_TAKEOFF,
            current=1,
            x=_deg_e7(depot_lat),
            y=_deg_e7(depot_lon),
            z=alt,
        ),
        MissionItem(
            seq=1,
            frame=MavFrame.MISSION,
            command=MavCmd.DO_CHANGE_SPEED,
            param1=SPEED_TYPE_GROUND,
            param2=float(flight.speed_m_s),
            param3=-1.0,
        ),
    ]
    for index in plan.order:
        lat, lon = plan.buoys_lat_lon[index]
        items.append(
            MissionItem(
                seq=len(items),
                frame=MavFrame.GLOBAL_RELATIVE_ALT_INT,
                command=MavCmd.NAV_WAYPOINT,
                param1=float(flight.dwell_s),
                param2=float(flight.acceptance_radius_m),
                param3=0.0,
                x=_deg_e7(lat),
                y=_deg_e7(lon),
                z=alt,
            )
        )
    depot_is_home = home is None or _distance_m(plan.frame, home) <= HOME_TOLERANCE_M
    if depot_is_home:
        items.append(
            MissionItem(seq=len(items), frame=MavFrame.GLOBAL_RELATIVE_ALT_INT, command=MavCmd.NAV_RETURN_TO_LAUNCH)
        )
    else:
        items.append(
            MissionItem(
                seq=len(items),
                frame=MavFrame.GLOBAL_RELATIVE_ALT_INT,
                command=MavCmd.NAV_WAYPOINT,
                param1=0.0,
                param2=float(flight.acceptance_radius_m),
                param3=0.0,
                x=_deg_e7(depot_lat),
                y=_deg_e7(depot_lon),
                z=alt,
            )
        )
        items.append(
            MissionItem(
                seq=len(items),
                frame=MavFrame.GLOBAL_RELATIVE_ALT_INT,
                command=MavCmd.NAV_LAND,
                x=_deg_e7(depot_lat),
                y=_deg_e7(depot_lon),
                z=0.0,
            )
        )
    return items


def _distance_m(frame: LocalFrame, lat_lon: tuple[float, float]) -> float:
    east_north = frame.project(np.array([lat_lon], dtype=float))[0]
    return float(np.hypot(*east_north))


def buoy_of_seq(seq: int, plan: Plan) -> int | None:
    """The buoy index a mission item sequence number inspects, or None for the other items."""
    position = seq - FIRST_BUOY_SEQ
    return plan.order[position] if 0 <= position < len(plan.order) else None


def leg_of_seq(seq: int | None, n_buoys: int) -> int | None:
    """The planned leg flown while mission item `seq` is current: leg k ends at the k-th buoy visited, leg n
    is the way home. None during takeoff (items before the first buoy) and when unknown."""
    if seq is None or seq < FIRST_BUOY_SEQ:
        return None
    return min(seq - FIRST_BUOY_SEQ, n_buoys)
