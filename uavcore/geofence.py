"""Geofences as MAVLink's fence items describe them: inclusion and exclusion polygons and circles.

A fence is uploaded as a MISSION_TYPE_FENCE list (the mission protocol): consecutive
MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION/EXCLUSION items are the vertices of one polygon (param1 = its vertex
count, repeated on every vertex), MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION/EXCLUSION is a circle (param1 = radius,
m), MAV_CMD_NAV_FENCE_RETURN_POINT an optional return point. `Geofence.from_items` builds the zones from those
items and refuses an inconsistent list.

Where the vehicle may be, as PX4's geofence module decides it: inside at least one inclusion zone (when there is
any) and outside every exclusion zone. Altitude plays no part here.

The geometry works on a local tangent plane (north, east metres; uavcore.geodesy), where polygon edges are
straight: `Geofence.in_plane(frame)` gives the zones in a frame once, so that a vehicle checks its NED position
each tick without any geodesy. The latitude/longitude methods project on a frame at the fence's first point;
over the few kilometres a fence spans the straight edges of the two views agree to centimetres.

Besides "is this point allowed", `segment_violation` answers what a ground station asks of a planned leg: does
the straight line between two points enter an exclusion zone or leave the inclusion zones. It computes, for
each zone, the parts of the segment that lie inside it (exactly: edge crossings for polygons, the chord for
circles), so a leg that cuts a corner of an exclusion polygon is caught although both its ends are outside.

Pure computation: no I/O.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from functools import cached_property

from uavcore.geodesy import LocalFrame
from uavcore.mission import MavCmd, MavFrame, MissionItem, MissionType

LatLon = tuple[float, float]  # degrees
NorthEast = tuple[float, float]  # metres on a local tangent plane
Interval = tuple[float, float]  # a part of a segment, as fractions 0..1 of its length

# Keyed by MavCmd members, looked up by a MissionItem's plain int command (an IntEnum hashes as its value).
POLYGON_COMMANDS: dict[int, bool] = {
    MavCmd.NAV_FENCE_POLYGON_VERTEX_INCLUSION: True,  # command -> is an inclusion zone
    MavCmd.NAV_FENCE_POLYGON_VERTEX_EXCLUSION: False,
}
CIRCLE_COMMANDS: dict[int, bool] = {MavCmd.NAV_FENCE_CIRCLE_INCLUSION: True, MavCmd.NAV_FENCE_CIRCLE_EXCLUSION: False}
MIN_POLYGON_VERTICES = 3
_EPS = 1e-12  # fractions of a segment closer than this are the same point


class FenceError(ValueError):
    """A fence list that does not describe zones (the message names the item and why)."""

    def __init__(self, message: str, seq: int) -> None:
        super().__init__(message)
        self.seq = seq


@dataclass(frozen=True)
class PolygonZone:
    vertices: tuple[LatLon, ...]
    inclusion: bool

    @property
    def kind(self) -> str:
        return f"{'inclusion' if self.inclusion else 'exclusion'} polygon"


@dataclass(frozen=True)
class CircleZone:
    center: LatLon
    radius_m: float
    inclusion: bool

    @property
    def kind(self) -> str:
        return f"{'inclusion' if self.inclusion else 'exclusion'} circle"


Zone = PolygonZone | CircleZone


# ----- the plane: where the geometry is done
def _cross(a: NorthEast, b: NorthEast) -> float:
    return a[0] * b[1] - a[1] * b[0]


def _minus(a: NorthEast, b: NorthEast) -> NorthEast:
    return a[0] - b[0], a[1] - b[1]


@dataclass(frozen=True)
class PlanarPolygon:
    vertices: tuple[NorthEast, ...]
    zone: PolygonZone

    def contains(self, point: NorthEast) -> bool:
        """Even-odd rule: a ray from the point crosses the boundary an odd number of times."""
        north, east = point
        inside = False
        previous = self.vertices[-1]
        for vertex in self.vertices:
            (n1, e1), (n2, e2) = previous, vertex
            if (n1 > north) != (n2 > north):
                crossing_east = e1 + (north - n1) * (e2 - e1) / (n2 - n1)
                if east < crossing_east:
                    inside = not inside
            previous = vertex
        return inside

    def inside_intervals(self, start: NorthEast, end: NorthEast) -> list[Interval]:
        """The parts of the segment start-end inside the polygon: it can only enter or leave where it crosses
        an edge, so each piece between consecutive crossings is wholly in or out (its midpoint says which)."""
        direction = _minus(end, start)
        cuts = {0.0, 1.0}
        previous = self.vertices[-1]
        for vertex in self.vertices:
            edge = _minus(vertex, previous)
            denominator = _cross(direction, edge)
            if abs(denominator) > _EPS:  # parallel edges cannot be crossed, only touched
                offset = _minus(previous, start)
                t = _cross(offset, edge) / denominator
                u = _cross(offset, direction) / denominator
                if 0.0 <= t <= 1.0 and -_EPS <= u <= 1.0 + _EPS:
                    cuts.add(t)
            previous = vertex
        ordered = sorted(cuts)
        pieces = []
        for t0, t1 in itertools.pairwise(ordered):
            middle = (t0 + t1) / 2
            if self.contains((start[0] + direction[0] * middle, start[1] + direction[1] * middle)):
                pieces.append((t0, t1))
        return _merged(pieces)


@dataclass(frozen=True)
class PlanarCircle:
    center: NorthEast
    radius_m: float
    zone: CircleZone

    def contains(self, point: NorthEast) -> bool:
        # strictly inside, as PX4's Geofence::insideCircle: a circle of radius 0 holds no point at all
        return math.dist(point, self.center) < self.radius_m

    def inside_intervals(self, start: NorthEast, end: NorthEast) -> list[Interval]:
        """The chord: where |start + t (end - start) - center| <= radius, a quadratic in t."""
        direction = _minus(end, start)
        offset = _minus(start, self.center)
        a = direction[0] ** 2 + direction[1] ** 2
        b = 2.0 * (direction[0] * offset[0] + direction[1] * offset[1])
        c = offset[0] ** 2 + offset[1] ** 2 - self.radius_m**2
        if a <= _EPS:  # a point
            return [(0.0, 1.0)] if c <= 0.0 else []
        discriminant = b * b - 4.0 * a * c
        if discriminant <= 0.0:  # misses or only touches
            return []
        root = math.sqrt(discriminant)
        t0, t1 = max(0.0, (-b - root) / (2.0 * a)), min(1.0, (-b + root) / (2.0 * a))
        return [(t0, t1)] if t1 - t0 > _EPS else []


PlanarZone = PlanarPolygon | PlanarCircle


def _merged(intervals: Iterable[Interval]) -> list[Interval]:
    """Sorted, overlapping or touching intervals joined."""
    merged: list[Interval] = []
    for t0, t1 in sorted(intervals):
        if merged and t0 <= merged[-1][1] + _EPS:
            merged[-1] = (merged[-1][0], max(merged[-1][1], t1))
        else:
            merged.append((t0, t1))
    return merged


def _covers_segment(intervals: list[Interval]) -> bool:
    merged = _merged(intervals)
    return len(merged) == 1 and merged[0][0] <= _EPS and merged[0][1] >= 1.0 - _EPS


@dataclass(frozen=True)
class PlanarFence:
    """The zones of a fence on one local tangent plane (north, east metres)."""

    zones: tuple[PlanarZone, ...]

    @property
    def inclusions(self) -> list[PlanarZone]:
        return [z for z in self.zones if z.zone.inclusion]

    @property
    def exclusions(self) -> list[PlanarZone]:
        return [z for z in self.zones if not z.zone.inclusion]

    def split_barring(self, point: NorthEast) -> tuple[PlanarFence, list[PlanarZone]]:
        """(the zones that let the vehicle be at point, the zones that do not): PX4's per-zone test
        (Geofence::checkPointAgainstPolygonCircle: inside an inclusion zone, outside an exclusion zone), with
        which its geofence discards, as it loads a fence, every zone that would bar home."""
        kept: list[PlanarZone] = []
        barring: list[PlanarZone] = []
        for zone in self.zones:
            (kept if zone.contains(point) == zone.zone.inclusion else barring).append(zone)
        return PlanarFence(tuple(kept)), barring

    def violation(self, point: NorthEast) -> Zone | None:
        """The zone a point breaks (an exclusion zone it is in, or the first inclusion zone when it is in none),
        or None where the vehicle may be."""
        for zone in self.exclusions:
            if zone.contains(point):
                return zone.zone
        inclusions = self.inclusions
        if inclusions and not any(zone.contains(point) for zone in inclusions):
            return inclusions[0].zone
        return None

    def segment_violation(self, start: NorthEast, end: NorthEast) -> Zone | None:
        """The zone the straight segment start-end breaks: an exclusion zone it enters, or an inclusion zone
        when the segment leaves them all somewhere (it may pass from one inclusion zone into another)."""
        for zone in self.exclusions:
            if zone.inside_intervals(start, end):
                return zone.zone
        inclusions = self.inclusions
        if inclusions:
            inside = [piece for zone in inclusions for piece in zone.inside_intervals(start, end)]
            if not _covers_segment(inside):
                return inclusions[0].zone
        return None


# ----- the fence in latitude/longitude
@dataclass(frozen=True)
class Geofence:
    """Inclusion and exclusion zones, and the return point if the fence names one."""

    zones: tuple[Zone, ...] = ()
    return_point: LatLon | None = None

    @classmethod
    def from_items(cls, items: Sequence[MissionItem]) -> Geofence:
        """The fence a MISSION_TYPE_FENCE list describes; FenceError if a polygon's vertices do not add up or a
        circle's radius is negative or not a number. Items are taken in order (their seq is the mission
        protocol's business).

        A circle of radius 0 is a zone that holds no point: PX4 stores it as sent (MavlinkMissionManager copies
        param1 into circle_radius unchecked) and MAVSDK's geofence example sends one at (0, 0) to mean "no
        circle"; the vehicle then discards it as it discards any zone that bars home (PlanarFence.split_barring)."""
        zones: list[Zone] = []
        return_point = None
        index = 0
        while index < len(items):
            item = items[index]
            if item.command in POLYGON_COMMANDS:
                polygon = _polygon_at(items, index)
                zones.append(polygon)
                index += len(polygon.vertices)
                continue
            if item.command in CIRCLE_COMMANDS:
                if not (math.isfinite(item.param1) and item.param1 >= 0):
                    radius = item.param1
                    raise FenceError(f"fence item {item.seq}: circle radius must be >= 0 m, got {radius}", item.seq)
                zones.append(CircleZone((item.lat, item.lon), float(item.param1), CIRCLE_COMMANDS[item.command]))
            elif item.command == MavCmd.NAV_FENCE_RETURN_POINT:
                return_point = (item.lat, item.lon)
            else:
                raise FenceError(f"fence item {item.seq}: command {item.command} is not a fence item", item.seq)
            index += 1
        return cls(tuple(zones), return_point)

    def to_items(self) -> list[MissionItem]:
        """The MISSION_TYPE_FENCE list that describes this fence (what `from_items` reads back): each polygon's
        vertices in order with param1 its vertex count, each circle with param1 its radius, then the return point
        if any; positions in MAV_FRAME_GLOBAL_INT as PX4's and QGC's fence plans carry them."""
        items: list[MissionItem] = []

        def add(command: int, point: LatLon, param1: float) -> None:
            items.append(
                MissionItem(
                    seq=len(items),
                    frame=MavFrame.GLOBAL_INT,
                    command=command,
                    param1=param1,
                    x=round(point[0] * 1e7),
                    y=round(point[1] * 1e7),
                    mission_type=MissionType.FENCE,
                )
            )

        for zone in self.zones:
            if isinstance(zone, PolygonZone):
                command = next(c for c, inclusion in POLYGON_COMMANDS.items() if inclusion == zone.inclusion)
                for vertex in zone.vertices:
                    add(command, vertex, float(len(zone.vertices)))
            else:
                command = next(c for c, inclusion in CIRCLE_COMMANDS.items() if inclusion == zone.inclusion)
                add(command, zone.center, zone.radius_m)
        if self.return_point is not None:
            add(MavCmd.NAV_FENCE_RETURN_POINT, self.return_point, 0.0)
        return items

    @property
    def empty(self) -> bool:
        return not self.zones

    def in_plane(self, frame: LocalFrame) -> PlanarFence:
        """The zones on `frame`'s tangent plane (north, east metres)."""

        def north_east(point: LatLon) -> NorthEast:
            north, east, _ = frame.to_ned(point[0], point[1], frame.alt0)
            return float(north), float(east)

        planar: list[PlanarZone] = []
        for zone in self.zones:
            if isinstance(zone, PolygonZone):
                planar.append(PlanarPolygon(tuple(north_east(v) for v in zone.vertices), zone))
            else:
                planar.append(PlanarCircle(north_east(zone.center), zone.radius_m, zone))
        return PlanarFence(tuple(planar))

    @cached_property
    def _frame(self) -> LocalFrame | None:
        if not self.zones:
            return None
        first = self.zones[0]
        lat, lon = first.vertices[0] if isinstance(first, PolygonZone) else first.center
        return LocalFrame(lat, lon, 0.0)

    @cached_property
    def _plane(self) -> PlanarFence:
        return self.in_plane(self._frame) if self._frame is not None else PlanarFence(())

    def _north_east(self, point: LatLon) -> NorthEast:
        assert self._frame is not None, "callers return early on an empty fence, the only one without a frame"
        north, east, _ = self._frame.to_ned(point[0], point[1], 0.0)
        return float(north), float(east)

    def violation(self, lat: float, lon: float) -> Zone | None:
        """The zone the point breaks, or None where the vehicle may be (see PlanarFence.violation)."""
        if self.empty:
            return None
        return self._plane.violation(self._north_east((lat, lon)))

    def contains(self, lat: float, lon: float) -> bool:
        """Whether the vehicle may be at this point."""
        return self.violation(lat, lon) is None

    def segment_violation(self, start: LatLon, end: LatLon) -> Zone | None:
        """The zone the straight leg start-end (latitude, longitude pairs) breaks, or None if it stays clear."""
        if self.empty:
            return None
        return self._plane.segment_violation(self._north_east(start), self._north_east(end))


def _polygon_at(items: Sequence[MissionItem], first: int) -> PolygonZone:
    """The polygon whose first vertex is items[first]: param1 vertices of the same command follow."""
    head = items[first]
    count = head.param1
    if not (math.isfinite(count) and count == int(count) and count >= MIN_POLYGON_VERTICES):
        raise FenceError(f"fence item {head.seq}: polygon param1 must be its vertex count >= 3, got {count}", head.seq)
    count = int(count)
    vertices = items[first : first + count]
    for vertex in vertices:
        if vertex.command != head.command or vertex.param1 != head.param1:
            raise FenceError(
                f"fence item {vertex.seq}: polygon starting at item {head.seq} has {count} vertices, "
                f"this item is not one of them",
                vertex.seq,
            )
    if len(vertices) < count:
        raise FenceError(f"fence item {head.seq}: polygon of {count} vertices has only {len(vertices)}", head.seq)
    return PolygonZone(tuple((v.lat, v.lon) for v in vertices), POLYGON_COMMANDS[head.command])
