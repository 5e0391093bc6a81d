"""The simulated world's AIS: its buoys that carry a transmitter (a world file's `mmsi`) report themselves as AtoN
stations do, in message 21 every 3 minutes of simulated time (IALA A-126), from where they really float (drifting in
their swing circle, or dragged off station), with the off-position flag set while that is outside the charted swing
circle; and virtual AtoNs (`--ais-virtual`: a mark that exists only in AIS, e.g. over a fresh wreck) at their
charted position with the virtual flag. Pure: the vehicle process sends the sentences (sitl_quad.ais_out).

Each transmitter reports at its own offset within the interval (spread evenly: real stations take their own slots),
the first within the first interval after start.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from uavcore.ais import AID_TYPE_OF_KIND, REPORT_INTERVAL_S, AtonReport, ais_text
from uavcore.buoy_world import KINDS, MMSI_RANGE, World, WorldBuoy

EPFD_GPS, EPFD_SURVEYED = 1, 7  # a buoy's own GPS; a virtual AtoN's position is the charted (surveyed) one


class VirtualAtonError(ValueError):
    """A --ais-virtual that is not MMSI,LAT,LON[,NAME[,KIND]] (the message says what is wrong)."""


@dataclass(frozen=True)
class VirtualAton:
    """A mark that exists only in AIS: nothing is in the water there."""

    mmsi: int
    lat: float
    lon: float
    name: str = "VIRTUAL ATON"
    kind: str = "isolated_danger"  # one of uavcore.buoy_world.KINDS: its AIS type (a wreck is marked as a danger)

    @classmethod
    def parse(cls, text: str) -> VirtualAton:
        """`MMSI,LAT,LON[,NAME[,KIND]]`, e.g. `992199001,38.921,121.664,NEW WRECK`."""
        parts = [p.strip() for p in text.split(",")]
        if not 3 <= len(parts) <= 5:
            raise VirtualAtonError(f"expected MMSI,LAT,LON[,NAME[,KIND]], got {text!r}")
        try:
            mmsi, lat, lon = int(parts[0]), float(parts[1]), float(parts[2])
        except ValueError:
            raise VirtualAtonError(f"MMSI must be an integer and LAT,LON numbers, got {text!r}") from None
        if mmsi not in MMSI_RANGE or not (abs(lat) <= 90 and abs(lon) <= 180):
            raise VirtualAtonError(f"a 9-digit MMSI and a position in degrees, got {text!r}")
        kind = parts[4] if len(parts) == 5 else cls.kind
        if kind not in KINDS:
            raise VirtualAtonError(f"kind {kind!r} is not one of {', '.join(KINDS)}")
        return cls(mmsi, lat, lon, parts[3] if len(parts) >= 4 and parts[3] else cls.name, kind)


def _half_size_m(buoy: WorldBuoy) -> int:
    """Metres from the buoy's centre (its antenna, the reference point) to each side, at least 1."""
    return max(1, round(buoy.appearance.diameter_m / 2))


class AisStation:
    """The world's AIS transmitters and when each reports next (simulated seconds)."""

    def __init__(
        self, world: World, virtual: tuple[VirtualAton, ...] = (), interval_s: float = REPORT_INTERVAL_S
    ) -> None:
        self.world = world
        self.virtual = virtual
        self.interval_s = interval_s
        self._buoys = [i for i, buoy in enumerate(world.buoys) if buoy.mmsi is not None]
        count = len(self._buoys) + len(virtual)
        self._next = [k * interval_s / count for k in range(count)]  # buoys first, then the virtual ones
        self.reports_made = 0

    @property
    def transmitters(self) -> int:
        return len(self._next)

    def due(self, t_s: float, unix_s: float, *environment: float) -> list[AtonReport]:
        """The reports due at simulated time t_s (unix_s: the simulated clock's UTC, for the timestamp's second),
        each transmitter's at most once; `environment` as World.positions takes it (wind from, wind speed, current
        to, current speed)."""
        if not self._next or min(self._next) > t_s:
            return []  # the common case, every tick: nothing to compute
        second = int(unix_s) % 60
        reports = []
        north_east, lat_lon = None, None
        for k, at in enumerate(self._next):
            if at > t_s:
                continue
            # a stall (the process suspended) skips the reports it missed, as a station's slots go by
            self._next[k] = at + self.interval_s * max(1, math.ceil((t_s - at) / self.interval_s + 1e-9))
            if k < len(self._buoys):
                if north_east is None:  # where every buoy floats now: only when some report is due
                    north_east = self.world.positions(t_s, *environment)
                    lat_lon = self.world.positions_lat_lon(t_s, *environment)
                index = self._buoys[k]
                reports.append(self._buoy_report(self.world.buoys[index], north_east[index], lat_lon[index], second))
            else:
                reports.append(self._virtual_report(self.virtual[k - len(self._buoys)], second))
        self.reports_made += len(reports)
        return reports

    @staticmethod
    def _buoy_report(buoy: WorldBuoy, north_east: np.ndarray, lat_lon: np.ndarray, second: int) -> AtonReport:
        half = _half_size_m(buoy)
        assert buoy.mmsi is not None
        return AtonReport(
            mmsi=buoy.mmsi,
            name=ais_text(buoy.id),
            aid_type=AID_TYPE_OF_KIND[buoy.kind],
            lat=float(lat_lon[0]),
            lon=float(lat_lon[1]),
            position_accuracy=False,  # a buoy's own GPS: better than 10 m is not claimed
            off_position=math.hypot(*north_east) > buoy.swing_radius_m,  # outside the charted swing circle
            virtual=False,
            second=second,
            dimensions_m=(half, half, half, half),
            epfd=EPFD_GPS,
        )

    @staticmethod
    def _virtual_report(aton: VirtualAton, second: int) -> AtonReport:
        return AtonReport(
            mmsi=aton.mmsi,
            name=ais_text(aton.name),
            aid_type=AID_TYPE_OF_KIND[aton.kind],
            lat=aton.lat,
            lon=aton.lon,
            position_accuracy=True,  # the charted position itself
            off_position=False,
            virtual=True,
            second=second,
            epfd=EPFD_SURVEYED,
        )
