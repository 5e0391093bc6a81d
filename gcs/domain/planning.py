"""From a validated request to a plan (route) and to the mission items the vehicle flies. No I/O.

The depot is node 0 of the planner's instance and the origin of the local frame; buoys are projected onto the
depot's tangent plane (uavcore.geodesy) so the planner works in metres.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, replace
from typing import Any

import numpy as np

from gcs.domain.records import PlanEnergy, PlanFleet
from gcs.domain.schemas import FenceZoneIn
from planner import plan_tour
from planner.distances import closed_tour_length, euclidean_matrix
from uavcore.buoy_world import DEFAULT_SWING_RADIUS_M
from uavcore.geodesy import LocalFrame
from uavcore.geofence import Geofence
from uavcore.light_character import burst_for, parse
from uavcore.mission import MavCmd, MavFrame, MissionItem

# Mission layout: item 0 takeoff, item 1 speed, then each buoy's items in visiting order (one waypoint, or the
# inspection's group of INSPECTION_GROUP items ending with it: `MissionLayout`), then the return.
FIRST_BUOY_SEQ = 2
INSPECTION_GROUP = 7  # ROI, standoff, capture start, standoff hold, capture stop, ROI none, the buoy's waypoint
ROI_HEIGHT_M = 1.0  # the camera aims this far above the sea at the buoy's charted position: its body, not its foot
BURST_HOLD_MARGIN_S = 0.5  # the standoff is held this much longer than the burst lasts
STOP_AND_GO_S = 5.0  # a stop at the standoff and the climb back to cruise speed, for the time budget
MIN_STANDOFF_M = 5.0  # a buoy closer than twice this to the previous point is looked at from half the leg
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
    # with a camera on the vehicle: stop this far short of each buoy on the way in, aim at it, capture a burst
    inspect: bool = True
    inspection_range_m: float = 20.0
    # a fleet's part: hover this much longer at the last buoy, so that the vehicle lands in its turn at a depot it
    # shares (planner.fleet_schedule)
    final_hold_s: float = 0.0


@dataclass(frozen=True)
class BuoyMark:
    """What the chart says of a buoy beyond its position: its IALA kind (None: not charted, the inspection then
    finds it by position alone), its light's character as charted (None: unlit), its mooring's swing radius, and
    which buoy of the register it is (None: none)."""

    kind: str | None = None
    light: str | None = None
    swing_radius_m: float = DEFAULT_SWING_RADIUS_M
    register_id: str | None = None  # the buoy register's id of this buoy: its inspection joins that buoy's history
    # where the chart has it when the mission looks for it elsewhere (its latest AIS position); None: where it looks
    charted_lat_lon: tuple[float, float] | None = None
    region: str = "A"  # the IALA buoyage region its lateral colours follow

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> BuoyMark:
        """A mark as stored (a plan's JSON: the position pair is a list there)."""
        charted = data.get("charted_lat_lon")
        return cls(**(data | {"charted_lat_lon": None if charted is None else (charted[0], charted[1])}))

    def burst(self) -> tuple[float, float]:
        """(duration s, rate Hz) of the camera burst that reads this light (uavcore.light_character.burst_for)."""
        return burst_for(None if self.light is None else parse(self.light))

    def burst_frames(self) -> int:
        """How many frames that burst is (IMAGE_START_CAPTURE's count)."""
        duration_s, rate_hz = self.burst()
        return math.ceil(duration_s * rate_hz)


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
    # What the chart says of each buoy (input order); None: positions only (a plan stored before charts were asked)
    marks: list[BuoyMark] | None = None
    # The request's geofence and rally points, uploaded to the vehicle before each sortie (MAV_MISSION_TYPE_FENCE,
    # MAV_MISSION_TYPE_RALLY) so that it enforces them itself; None: the vehicle keeps what it holds
    fence: list[FenceZoneIn] | None = None
    rally_points: list[list[float]] | None = None  # [lat, lon, altitude above home m]

    def mark(self, index: int) -> BuoyMark:
        """Buoy `index`'s charted kind, light and swing radius (all unknown when none were given)."""
        return self.marks[index] if self.marks else BuoyMark()

    def charted_lat_lon(self, index: int) -> tuple[float, float]:
        """Where the chart has buoy `index`: its mark's charted position when the mission looks for it elsewhere (its
        latest AIS position), else where the mission looks (buoys_lat_lon)."""
        lat, lon = self.mark(index).charted_lat_lon or self.buoys_lat_lon[index]
        return lat, lon

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
            "fence": None if self.fence is None else [zone.model_dump(mode="json") for zone in self.fence],
        }
        return asdict(replace(self, energy=None, fleet=None, fence=None)) | sections

    @staticmethod
    def from_dict(data: dict[str, Any]) -> Plan:
        energy, fleet, marks, fence = data.get("energy"), data.get("fleet"), data.get("marks"), data.get("fence")
        return Plan(
            **{**data, "depot": tuple(data["depot"])}
            | {
                "energy": None if energy is None else PlanEnergy.model_validate(energy),
                "fleet": None if fleet is None else PlanFleet.model_validate(fleet),
                "marks": None if marks is None else [BuoyMark.from_dict(mark) for mark in marks],
                "fence": None if fence is None else [FenceZoneIn.model_validate(zone) for zone in fence],
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


def _waypoint(lat: float, lon: float, alt: float, hold_s: float, acceptance_m: float) -> MissionItem:
    return MissionItem(
        seq=0,
        frame=MavFrame.GLOBAL_RELATIVE_ALT_INT,
        command=MavCmd.NAV_WAYPOINT,
        param1=float(hold_s),
        param2=float(acceptance_m),
        param3=0.0,
        x=_deg_e7(lat),
        y=_deg_e7(lon),
        z=alt,
    )


def _command(command: MavCmd, *params: float) -> MissionItem:
    """A DO_ or IMAGE_ item without a position; params not given are NaN (unused), as MissionItem's."""
    p1, p2, p3, p4 = [*map(float, params), math.nan, math.nan, math.nan, math.nan][:4]
    return MissionItem(0, MavFrame.MISSION, command, param1=p1, param2=p2, param3=p3, param4=p4)


def standoff_point(plan: Plan, position: int, range_m: float) -> tuple[float, float]:
    """[lat, lon] the camera looks at the `position`-th buoy of the plan's order from: on the straight way in
    (from the point before it on the route), `range_m` short of the buoy or half the leg when the leg is shorter
    than twice that; due south of it when the leg has no length. On the leg: the track stays the planned one."""
    route = plan.route_local()
    nodes = plan.route_nodes()
    # the position-th buoy's place in the route: every sortie adds its way home before the next one's buoys
    k = [i for i, node in enumerate(nodes) if node is not None][position]
    here, before = route[k], route[k - 1]
    leg = before - here
    length = float(np.hypot(*leg))
    away = leg / length if length > 1e-6 else np.array([0.0, -1.0])
    distance = max(min(range_m, 0.5 * length), min(MIN_STANDOFF_M, range_m)) if length > 1e-6 else range_m
    point = here + distance * away
    lat, lon = plan.frame.unproject(point[None, :])[0]
    return float(lat), float(lon)


def inspection_items(plan: Plan, flight: FlightParams, position: int) -> list[MissionItem]:
    """The `position`-th buoy visited as an inspection (MissionLayout's group): aim the gimbal at its charted
    position (DO_SET_ROI_LOCATION), stop at the standoff on the way in, capture the burst its charted light needs
    (IMAGE_START_CAPTURE: interval and count) while holding there, stop capturing, release the ROI, and go on to
    the buoy itself (the visit the route is measured by)."""
    index = plan.order[position]
    lat, lon = plan.buoys_lat_lon[index]
    _, rate_hz = plan.mark(index).burst()
    count = plan.mark(index).burst_frames()
    s_lat, s_lon = standoff_point(plan, position, flight.inspection_range_m)
    alt, acceptance = float(flight.altitude_m), float(flight.acceptance_radius_m)
    roi = replace(_command(MavCmd.DO_SET_ROI_LOCATION), frame=MavFrame.GLOBAL_RELATIVE_ALT_INT,
                  x=_deg_e7(lat), y=_deg_e7(lon), z=ROI_HEIGHT_M)  # fmt: skip
    return [
        roi,
        _waypoint(s_lat, s_lon, alt, 0.0, acceptance),
        _command(MavCmd.IMAGE_START_CAPTURE, 0.0, 1.0 / rate_hz, count, 0.0),
        _waypoint(s_lat, s_lon, alt, count / rate_hz + BURST_HOLD_MARGIN_S, acceptance),
        _command(MavCmd.IMAGE_STOP_CAPTURE, 0.0),
        _command(MavCmd.DO_SET_ROI_NONE, 0.0),
        _waypoint(lat, lon, alt, flight.dwell_s, acceptance),
    ]


def inspection_time_s(plan: Plan) -> float:
    """The hover the plan's inspections add (each buoy's standoff hold, and a stop and go there): for the flight's
    time budget, not a prediction."""
    holds = 0.0
    for index in plan.order:
        duration_s, rate_hz = plan.mark(index).burst()
        holds += math.ceil(duration_s * rate_hz) / rate_hz + BURST_HOLD_MARGIN_S + STOP_AND_GO_S
    return holds


def mission_items(
    plan: Plan, flight: FlightParams, home: tuple[float, float] | None = None, camera: bool = False
) -> list[MissionItem]:
    """The mission: takeoff at the depot, cruise speed, one waypoint per buoy, then home and land.

    Waypoints carry param1 = dwell (hold time) and param2 = acceptance radius, as MAV_CMD_NAV_WAYPOINT defines.
    With `camera` (the vehicle has one and the flight asks to inspect) each buoy is an inspection group instead
    (`inspection_items`). The return is MavCmd.NAV_RETURN_TO_LAUNCH when the depot is the vehicle's home (`home`
    None: taken to be the depot) and the plan has no rally points; otherwise a waypoint at the depot and
    MavCmd.NAV_LAND there, so the vehicle comes back to the depot and not to wherever it booted, nor to a rally
    point: PX4 flies a NAV_RETURN_TO_LAUNCH item as its RTL, which with RTL_TYPE 0 lands at the closest of home and
    the rally (safe) points (RTL::findRtlDestination), and a sortie's next take-off is from the depot.
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
        _command(MavCmd.DO_CHANGE_SPEED, SPEED_TYPE_GROUND, flight.speed_m_s, -1.0),
    ]
    for position, index in enumerate(plan.order):
        if camera and flight.inspect:
            items += inspection_items(plan, flight, position)
        else:
            lat, lon = plan.buoys_lat_lon[index]
            items.append(_waypoint(lat, lon, alt, flight.dwell_s, flight.acceptance_radius_m))
    if flight.final_hold_s > 0 and plan.order:  # the last buoy's waypoint (an inspection group's last item)
        items[-1] = replace(items[-1], param1=items[-1].param1 + flight.final_hold_s)
    depot_is_home = home is None or _distance_m(plan.frame, home) <= HOME_TOLERANCE_M
    if depot_is_home and not plan.rally_points:
        items.append(MissionItem(seq=0, frame=MavFrame.GLOBAL_RELATIVE_ALT_INT, command=MavCmd.NAV_RETURN_TO_LAUNCH))
    else:
        items.append(_waypoint(depot_lat, depot_lon, alt, 0.0, flight.acceptance_radius_m))
        items.append(
            MissionItem(
                seq=0,
                frame=MavFrame.GLOBAL_RELATIVE_ALT_INT,
                command=MavCmd.NAV_LAND,
                x=_deg_e7(depot_lat),
                y=_deg_e7(depot_lon),
                z=0.0,
            )
        )
    return [replace(item, seq=seq) for seq, item in enumerate(items)]


@dataclass(frozen=True)
class MissionLayout:
    """Where each of a mission's `buoys` buoys has its items: after the take-off and the speed, one waypoint each,
    or with `inspected` an inspection group each (`inspection_items`) whose last item is the buoy's waypoint."""

    buoys: int
    inspected: bool = False

    @property
    def group_size(self) -> int:
        return INSPECTION_GROUP if self.inspected else 1

    def group_start(self, position: int) -> int:
        """The first item of the position-th buoy's items."""
        return FIRST_BUOY_SEQ + position * self.group_size

    def visit_seq(self, position: int) -> int:
        """The waypoint at the position-th buoy visited."""
        return self.group_start(position) + self.group_size - 1

    def position_of(self, seq: int | None) -> int | None:
        """Which buoy's items (its position in the visiting order) item `seq` is one of; None for the others."""
        if seq is None or seq < FIRST_BUOY_SEQ:
            return None
        position = (seq - FIRST_BUOY_SEQ) // self.group_size
        return position if position < self.buoys else None

    def leg_of_seq(self, seq: int | None) -> int | None:
        """The planned leg flown while item `seq` is current: leg k ends at the k-th buoy visited (its inspection
        is on the way in), leg n is the way home. None during takeoff and when unknown."""
        if seq is None or seq < FIRST_BUOY_SEQ:
            return None
        return min((seq - FIRST_BUOY_SEQ) // self.group_size, self.buoys)


def _distance_m(frame: LocalFrame, lat_lon: tuple[float, float]) -> float:
    east_north = frame.project(np.array([lat_lon], dtype=float))[0]
    return float(np.hypot(*east_north))


def buoy_of_seq(seq: int, plan: Plan, layout: MissionLayout | None = None) -> int | None:
    """The buoy index whose visit (its waypoint) mission item `seq` is, or None for the other items."""
    layout = layout or MissionLayout(len(plan.order))
    position = layout.position_of(seq)
    return plan.order[position] if position is not None and seq == layout.visit_seq(position) else None


def leg_of_seq(seq: int | None, n_buoys: int, inspected: bool = False) -> int | None:
    """MissionLayout(n_buoys, inspected).leg_of_seq(seq)."""
    return MissionLayout(n_buoys, inspected).leg_of_seq(seq)
