"""The paper's reference scenario (Section VI), generated reproducibly.

13 buoys uniform at random in a 1200 m x 700 m area whose south-west corner is the area origin, depot at
(269 m, 293 m) in that area, flight altitude 5 m, cruise 10 m/s. The depot is the vehicle's home, so local
coordinates used elsewhere are relative to the depot: ``local = area - DEPOT_IN_AREA``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from uavcore.geodesy import DEFAULT_HOME, LocalFrame

AREA_SIZE_M = (1200.0, 700.0)  # east x north extent of the area
DEPOT_IN_AREA_M = (269.0, 293.0)
ALTITUDE_M = 5.0
CRUISE_SPEED_M_S = 10.0
N_BUOYS = 13


@dataclass(frozen=True)
class Scenario:
    """Depot and buoys in local ENU metres relative to the depot, and as WGS84 degrees."""

    buoys_local: np.ndarray  # (n, 2) [east, north] metres from the depot
    buoys_lat_lon: np.ndarray  # (n, 2) [lat, lon]
    home: tuple[float, float, float]

    @property
    def depot_lat_lon(self) -> tuple[float, float]:
        return self.home[0], self.home[1]


def random_area_points(n: int, rng: np.random.Generator) -> np.ndarray:
    """n points uniform in the area, as [east, north] metres relative to the depot."""
    area = rng.uniform((0.0, 0.0), AREA_SIZE_M, size=(n, 2))
    return area - np.asarray(DEPOT_IN_AREA_M)


def reference_scenario(seed: int = 1, n_buoys: int = N_BUOYS, home=DEFAULT_HOME) -> Scenario:
    """The reference scenario for a seed: the same seed always gives the same buoys."""
    rng = np.random.default_rng(seed)
    local = random_area_points(n_buoys, rng)
    frame = LocalFrame(*home)
    return Scenario(buoys_local=local, buoys_lat_lon=frame.unproject(local), home=tuple(home))
