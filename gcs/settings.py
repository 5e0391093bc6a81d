"""The service's settings: plain data, filled from the command line and the environment.

Airframe limits (altitude, speed) and the battery range are data here, not code, so a different airframe or
battery is a settings change. Values are for the paper's quadrotor (Table 2) flying the reference scenario.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

from uavcore.geodesy import DEFAULT_HOME

TOKEN_ENV = "BUOY_GCS_TOKEN"


@dataclass(frozen=True)
class Limits:
    """What a mission request may ask for; anything outside is refused with HTTP 422."""

    max_buoys: int = 500
    min_buoy_spacing_m: float = 2.0  # two buoys (or a buoy and the depot) closer than this are one buoy
    altitude_m: tuple[float, float] = (2.0, 120.0)  # above home
    speed_m_s: tuple[float, float] = (1.0, 15.0)
    dwell_s: tuple[float, float] = (0.0, 60.0)
    acceptance_radius_m: tuple[float, float] = (0.5, 50.0)
    max_distance_from_depot_m: float = 10_000.0  # radio range: every buoy within this of the depot
    max_route_length_m: float = 30_000.0  # battery: the planned tour must not be longer
    max_time_limit_s: float = 30.0  # planner budget a request may ask for


@dataclass(frozen=True)
class Settings:
    """Everything `create_app` needs. Defaults serve on loopback and talk to the vehicle's default port."""

    vehicle_url: str = "udpout:127.0.0.1:14540"
    host: str = "127.0.0.1"
    port: int = 8000
    db_path: Path = Path("data/gcs.sqlite")
    token: str | None = None  # when set, every mutating endpoint needs `Authorization: Bearer <token>`
    home: tuple[float, float, float] = DEFAULT_HOME  # depot used while the vehicle has not reported its home
    limits: Limits = field(default_factory=Limits)
    heartbeat_timeout_s: float = 3.0  # wall clock, as MAVSDK: no vehicle heartbeat for this long = link lost
    vehicle_wait_s: float = 5.0  # how long a mission waits for a vehicle before failing with "no vehicle"
    telemetry_period_s: float = 0.1  # recorded sample spacing in the vehicle's simulated time (10 Hz)
    live_rate_hz: float = 20.0  # WebSocket push rate to each client
    mission_timeout_margin_s: float = 120.0  # simulated seconds allowed beyond the planned flight time
    web_dir: Path = Path(__file__).resolve().parent / "web"  # package data: ships in the wheel
    signing_key: str | None = None  # MAVLink 2 signing: 64 hex digits or a passphrase (sitl_quad's format)

    @property
    def reports_dir(self) -> Path:
        """Where GET /missions/{id}/report caches its drawings: beside the database."""
        return self.db_path.parent / "reports"

    @staticmethod
    def token_from_env(token: str | None) -> str | None:
        """The token given on the command line, else the environment's, else none."""
        return token or os.environ.get(TOKEN_ENV) or None
