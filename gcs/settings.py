"""The service's settings, each default written once: from the command line, else the environment, else here.

`Settings` is a pydantic-settings `BaseSettings`: every field can be set by an environment variable named
`BUOY_GCS_` + the field's name in capitals (BUOY_GCS_VEHICLE_URL, BUOY_GCS_DB_PATH, BUOY_GCS_DB, BUOY_GCS_TOKEN,
BUOY_GCS_SIGNING_KEY, BUOY_GCS_LIVE_RATE_HZ, BUOY_GCS_AIS_SOURCES (comma-separated), ...; a limit as
BUOY_GCS_LIMITS__MAX_BUOYS). `python -m gcs serve` and `up` pass only the options given on their command line, so
an option beats the environment, which beats the default below. An empty variable counts as unset.

Airframe limits (altitude, speed) and the battery range are data here, not code, so a different airframe or
battery is a settings change. Values are for the paper's quadrotor (Table 2) flying the reference scenario.
"""

from __future__ import annotations

import os
import socket
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator
from pydantic_settings import BaseSettings, NoDecode, SettingsConfigDict

from gcs.domain.ais import parse_ais_source
from gcs.vehicle.connection import parse_vehicle
from uavcore.geodesy import DEFAULT_HOME
from uavcore.mavlink import VEHICLE_UDP_PORT

ENV_PREFIX = "BUOY_GCS_"
DB_FILENAME = "gcs.sqlite"  # the database's name inside the data directory


class Limits(BaseModel):
    """What a mission request may ask for; anything outside is refused with HTTP 422."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    max_buoys: int = 500
    min_buoy_spacing_m: float = 2.0  # two buoys (or a buoy and the depot) closer than this are one buoy
    altitude_m: tuple[float, float] = (2.0, 120.0)  # above home
    speed_m_s: tuple[float, float] = (1.0, 15.0)
    dwell_s: tuple[float, float] = (0.0, 60.0)
    acceptance_radius_m: tuple[float, float] = (0.5, 50.0)
    max_distance_from_depot_m: float = 10_000.0  # radio range: every buoy within this of the depot
    max_route_length_m: float = 30_000.0  # battery: the planned tour must not be longer
    max_time_limit_s: float = 30.0  # planner budget a request may ask for


class Settings(BaseSettings):
    """Everything `create_app` and `up` need. Defaults serve on loopback and talk to the vehicle's default port."""

    model_config = SettingsConfigDict(
        env_prefix=ENV_PREFIX, env_nested_delimiter="__", env_ignore_empty=True, frozen=True, extra="forbid"
    )

    vehicle_url: str = Field(f"udpout:127.0.0.1:{VEHICLE_UDP_PORT}", description="MAVLink connection to the vehicle")
    vehicles: Annotated[list[str], NoDecode] = Field(
        default_factory=list,
        description="a fleet, each vehicle as SYSID=URL (the first is vehicle_url); none: vehicle_url alone",
    )
    host: str = Field("127.0.0.1", description="address the service binds (loopback only by default)")
    port: int = Field(8000, description="HTTP port of the service and map page")
    data_dir: Path = Field(Path("data"), description="`up`'s data directory (database, logs, vehicle parameters)")
    db_path: Path = Field(
        default_factory=lambda fields: fields["data_dir"] / DB_FILENAME, description="the SQLite file"
    )
    db: str | None = Field(
        None,
        description="a PostgreSQL database instead of the SQLite file: postgresql://USER[:PASSWORD]@HOST:PORT/NAME",
        pattern=r"^postgres(ql)?://",
    )
    token: str | None = Field(None, description="when set, every mutating endpoint needs `Authorization: Bearer`")
    signing_key: str | None = Field(None, description="MAVLink 2 signing: 64 hex digits or a passphrase")
    cors_origins: Annotated[list[str], NoDecode] = Field(
        default_factory=list,
        description="origins (scheme://host[:port]) whose pages may call the API and open /ws; none by default",
    )
    max_body_bytes: int = Field(1 << 20, gt=0, description="largest request body (a buoy file too): 413 beyond")
    # an S-57 cell is larger than any other body: IHO's ENC product specification allows 5 MB a cell
    max_chart_bytes: int = Field(5 << 20, gt=0, description="largest S-57 cell POST /imports takes: 413 beyond")
    iala_region: Literal["A", "B"] = Field(
        "A",
        description="the IALA buoyage region of a chart's marks where the chart names none (its MARSYS): A, or B "
        "(the Americas, Japan, Korea, the Philippines: port marks green, starboard red)",
    )
    home: tuple[float, float, float] = DEFAULT_HOME  # depot used while the vehicle has not reported its home
    limits: Limits = Field(default_factory=Limits)
    heartbeat_timeout_s: float = Field(
        3.0, gt=0, description="wall seconds without a vehicle heartbeat before the link counts as lost (MAVSDK's 3)"
    )
    vehicle_wait_s: float = Field(5.0, description="seconds a mission waits for a vehicle before failing")
    telemetry_period_s: float = 0.1  # recorded sample spacing in the vehicle's simulated time (10 Hz)
    live_rate_hz: float = 20.0  # WebSocket push rate to each client
    mission_timeout_margin_s: float = 120.0  # simulated seconds allowed beyond the planned flight time
    # several instances on one PostgreSQL database: one owns the vehicle link, the others stand by
    # (gcs.missions.ownership)
    instance_name: str = Field(
        default_factory=lambda: f"{socket.gethostname()}:{os.getpid()}",
        description="this instance's name, shown by the others while it owns the vehicle link (default host:pid)",
    )
    vehicle_name: str | None = Field(
        None, description="the vehicle lease's name: instances naming the same vehicle share it (default: vehicle_url)"
    )
    lease_poll_s: float = Field(
        0.5, gt=0, description="wall seconds between a stand-by's tries to take the vehicle lease (and owner checks)"
    )
    # the inspection's camera frames (gcs.missions.inspector)
    max_frame_bytes: int = Field(16 << 20, gt=0, description="largest camera frame downloaded (a JPEG is a few MB)")
    max_mission_frame_bytes: int = Field(
        4 << 30, gt=0, description="frames stored per mission beyond this are not stored (the buoy's reason says so)"
    )
    inspection_workers: int = Field(
        2, ge=0, le=64, description="processes analysing camera frames (0: a thread of the service)"
    )
    inspection_drain_s: float = Field(
        900.0,
        ge=0,
        description="wall seconds a landed sortie waits at most for its frames still downloading and being analysed "
        "(it stops waiting sooner when none of them gets done for a minute)",
    )
    # the AIS feed (gcs.ais): AtoN reports (message 21) from AIS receivers and shore stations
    ais_sources: Annotated[list[str], NoDecode] = Field(
        default_factory=list,
        description="NMEA AIS sources: udp://[HOST]:PORT listens for a receiver's datagrams, tcp://HOST:PORT "
        "connects to a shore station or receiver; none: no AIS",
    )
    ais_stale_s: float = Field(
        420.0, gt=0, description="an AtoN report older than this is stale (AtoNs report every 180 s: two missed + 60)"
    )
    ais_max_lines_s: float = Field(
        500.0,
        gt=0,
        description="lines a second parsed per AIS source (bursts of twice that); beyond, dropped and counted",
    )
    web_dir: Path = Path(__file__).resolve().parent / "web"  # package data: ships in the wheel

    @field_validator("cors_origins", "vehicles", "ais_sources", mode="before")
    @classmethod
    def _comma_separated(cls, value: Any) -> Any:
        # BUOY_GCS_CORS_ORIGINS="https://a.example,https://b.example"
        return [part.strip() for part in value.split(",") if part.strip()] if isinstance(value, str) else value

    @field_validator("vehicles")
    @classmethod
    def _vehicle_specs(cls, value: list[str]) -> list[str]:
        specs = [parse_vehicle(text) for text in value]  # raises naming a bad one
        if len(specs) > 1 and any(sysid is None for sysid, _ in specs):
            raise ValueError(f"a fleet names each vehicle's system id, SYSID=URL: {value}")
        sysids = [sysid for sysid, _ in specs if sysid is not None]
        if len(set(sysids)) < len(sysids):
            raise ValueError(f"a system id is given to two vehicles: {value}")
        return value

    @field_validator("ais_sources")
    @classmethod
    def _ais_sources(cls, value: list[str]) -> list[str]:
        return [str(parse_ais_source(text)) for text in value]  # raises naming a bad one; written one way

    @model_validator(mode="after")
    def _first_vehicle_is_vehicle_url(self) -> Settings:
        if self.vehicles:  # frozen: set as pydantic sets fields
            object.__setattr__(self, "vehicle_url", parse_vehicle(self.vehicles[0])[1])
        return self

    @property
    def fleet(self) -> list[tuple[int | None, str]]:
        """Each vehicle's (system id or None, connection string); vehicle_url alone without a fleet."""
        return [parse_vehicle(text) for text in self.vehicles] or [(None, self.vehicle_url)]

    @property
    def database(self) -> str | Path:
        """What gcs.storage.open_storage opens: the PostgreSQL URL when one is set, else the SQLite file."""
        return self.db if self.db is not None else self.db_path

    @property
    def reports_dir(self) -> Path:
        """Where GET /missions/{id}/report caches its drawings: beside the database."""
        return self.db_path.parent / "reports"

    @classmethod
    def default(cls, name: str) -> Any:
        """A field's default as written above (not the environment's value), for command-line help."""
        return cls.model_fields[name].default

    @staticmethod
    def env_name(name: str) -> str:
        """The environment variable that sets a field."""
        return f"{ENV_PREFIX}{name.upper()}"
