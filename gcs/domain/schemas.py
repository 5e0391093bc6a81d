"""The REST contract as pydantic models (field names fixed by docs/architecture.md, section REST).

Only structural checks live here (types, finite numbers, lat/lon ranges, 1..500 buoys); the checks that depend
on settings (airframe limits, spacing, range) are in `gcs.missions.validation`, which answers in the same 422 shape.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import AwareDatetime, BaseModel, ConfigDict, Field, field_validator, model_validator

from gcs.domain.buoy_files import BuoyFileError, buoys_from_geojson
from gcs.domain.status import MissionKind, MissionStatus
from uavcore.buoy_world import DEFAULT_SWING_RADIUS_M
from uavcore.light_character import LightCharacterError, parse

MAX_BUOYS = 500
MAX_FENCE_ZONES = 50
MAX_FENCE_VERTICES = 200
# PX4 keeps at most 8 rally ("safe") points (dataman's DM_KEY_SAFE_POINTS_MAX)
MAX_RALLY_POINTS = 8
PlannerMethod = Literal["auto", "chnn-ga", "chnn", "exact"]
# An operator's command in force on a flying mission (gcs.missions.lifecycle): held where it is, returning to the
# depot (resumable until it lands), or landing where it is. A resume ends the first two; nothing ends a landing.
OperatorCommand = Literal["hold", "return", "land"]


class Strict(BaseModel):
    """Base: unknown fields are errors and NaN/Infinity (which Python's JSON parser accepts) are refused."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


class LatLon(Strict):
    lat: float = Field(ge=-90.0, le=90.0, description="WGS84 latitude, degrees")
    lon: float = Field(ge=-180.0, le=180.0, description="WGS84 longitude, degrees")


BuoyKind = Literal[
    "port", "starboard", "north", "east", "south", "west", "isolated_danger", "safe_water", "special"
]  # uavcore.buoy_world.KINDS (a test keeps the two the same)


class BuoyIn(LatLon):
    id: str | None = Field(default=None, max_length=64, description="the buoy's name; defaults to B<index>")
    kind: BuoyKind | None = Field(
        default=None, description="the charted IALA kind (its colours, shape and topmark are checked); none: unknown"
    )
    light: str | None = Field(
        default=None,
        max_length=40,
        description="the charted light in chart abbreviation, e.g. 'Fl(2) G 6s', 'Q(6)+LFl W 15s'; none: unlit",
    )
    swing_radius_m: float | None = Field(
        default=None, ge=0.0, le=200.0, description=f"the mooring's swing radius; default {DEFAULT_SWING_RADIUS_M:g} m"
    )
    register_id: str | None = Field(
        default=None,
        min_length=1,
        max_length=64,
        description="the buoy register's id of this buoy (GET /buoys): its inspection joins that buoy's history",
    )
    region: Literal["A", "B"] | None = Field(
        default=None,
        description="the IALA buoyage region its lateral colours follow (A: port red, starboard green; B: port "
        "green, starboard red); default: the service's iala_region",
    )
    charted: LatLon | None = Field(
        default=None,
        description="the charted position when lat/lon is another (e.g. the buoy's latest AIS report): the mission "
        "looks for the buoy at lat/lon and the inspection judges its station against this; default: lat/lon",
    )

    @field_validator("light")
    @classmethod
    def _charted_light(cls, value: str | None) -> str | None:
        if value is not None:
            try:
                parse(value)
            except LightCharacterError as error:
                raise ValueError(f"not a light character: {error}") from None
        return value


class FenceZoneIn(Strict):
    """One geofence zone, as MAVLink's fence items describe them: a polygon (3 or more vertices) or a circle."""

    kind: Literal["polygon", "circle"]
    inclusion: bool = Field(description="true: the vehicle must stay inside; false: it must stay out")
    vertices: list[LatLon] | None = Field(default=None, min_length=3, max_length=MAX_FENCE_VERTICES)
    center: LatLon | None = None
    radius_m: float | None = Field(default=None, gt=0.0, le=100_000.0)

    @model_validator(mode="after")
    def _shape(self) -> FenceZoneIn:
        if self.kind == "polygon" and (self.vertices is None or self.center is not None or self.radius_m is not None):
            raise ValueError("a polygon zone has vertices (3 or more) and no center or radius_m")
        if self.kind == "circle" and (self.center is None or self.radius_m is None or self.vertices is not None):
            raise ValueError("a circle zone has a center and a radius_m and no vertices")
        return self


class RallyPointIn(LatLon):
    """A rally point: where the vehicle may return instead of home (PX4's RTL flies to the nearest rally point or
    home, RTL_TYPE 0), uploaded to it as a MAV_MISSION_TYPE_RALLY list."""

    alt_m: float = Field(default=10.0, description="altitude above home, m")


class PlannerOptions(Strict):
    method: PlannerMethod = "auto"
    seed: int = Field(default=0, ge=0, le=2**31 - 1)
    time_limit_s: float = Field(default=2.0, gt=0.0, description="the planner's wall-clock budget")


class WindIn(Strict):
    """The forecast wind the energy prediction flies against."""

    speed_m_s: float = Field(ge=0.0, le=30.0, description="mean wind speed")
    from_deg: float = Field(ge=0.0, le=360.0, description="compass direction the wind blows from")
    turbulence_w20_m_s: float | None = Field(
        default=None, ge=0.0, le=30.0, description="Dryden intensity (wind at 20 ft); default: the mean wind speed"
    )


class BatteryIn(Strict):
    """Energy planning: split the buoys into sorties that each fit one battery, and predict each one's energy."""

    reserve_pct: Annotated[float, Field(ge=0.0, le=90.0)] | Literal["vehicle"] = Field(
        default="vehicle",
        description="charge left at landing, % of the pack; 'vehicle': the vehicle's BAT_LOW_THR (read from it), "
        "so a sortie flown as predicted lands before the low-battery warning",
    )
    capacity_mah: float | None = Field(
        default=None, gt=0.0, le=100_000.0, description="the pack's capacity; default: the vehicle's BAT1_CAPACITY"
    )
    margin_pct: float = Field(
        default=5.0, ge=0.0, le=50.0, description="energy kept free in every sortie for prediction errors, %"
    )
    split: bool = Field(default=True, description="false: one sortie whatever the prediction (flown at your risk)")
    objective: Literal["time", "distance"] = Field(default="time", description="what the sorties minimise in total")


class RegisterSelectionIn(Strict):
    """Buoys of the register (GET /buoys), with GET /buoys' filters: each given narrows the selection."""

    ids: list[Annotated[str, Field(min_length=1, max_length=64)]] | None = Field(
        default=None, min_length=1, max_length=MAX_BUOYS, description="only these register ids"
    )
    bbox: tuple[float, float, float, float] | None = Field(
        default=None, description="only buoys charted in [west, south, east, north] (degrees)"
    )
    kind: BuoyKind | None = Field(default=None, description="only buoys of this IALA kind")
    overdue_days: float | None = Field(
        default=None, gt=0.0, le=36_500.0, description="only buoys not inspected for this many days, or never"
    )
    open_defects: bool | None = Field(
        default=None, description="true: only buoys with open or confirmed defects; false: only those without"
    )

    @field_validator("bbox")
    @classmethod
    def _box(cls, value: tuple[float, float, float, float] | None) -> tuple[float, float, float, float] | None:
        if value is not None:
            west, south, east, north = value
            if not (-180.0 <= west < east <= 180.0 and -90.0 <= south < north <= 90.0):
                raise ValueError("west < east within -180..180 and south < north within -90..90, in degrees")
        return value


class PlanRequest(Strict):
    depot: LatLon | None = Field(default=None, description="default: the vehicle's home")
    buoys: list[BuoyIn] = Field(
        default_factory=list,
        max_length=MAX_BUOYS,
        description="a list of {id?, lat, lon} or a GeoJSON FeatureCollection of Points (at least one, unless "
        "`from_register` selects some); a feature with the property role 'depot' is the depot when `depot` is not "
        "given (a fleet's is not used: its vehicles fly from their homes)",
    )
    from_register: RegisterSelectionIn | None = Field(
        default=None,
        description="buoys taken from the register, after `buoys`: each is looked for at its latest AIS position "
        "while that report is current, else at its charted position, and judged against the chart; virtual AtoNs "
        "are never taken",
    )
    altitude_m: float = Field(default=5.0, description="flight altitude above home")
    speed_m_s: float = Field(default=10.0, description="cruise speed")
    dwell_s: float = Field(default=1.0, description="time hovering over each buoy")
    inspect: bool = Field(
        default=True,
        description="when the vehicle has a camera: stop short of each buoy, aim the camera at it and capture a "
        "burst long enough to read its light; the verdicts are at GET /missions/{id}/inspections",
    )
    inspection_range_m: float = Field(
        default=20.0, ge=5.0, le=100.0, description="how far short of each buoy the camera looks at it from"
    )
    acceptance_radius_m: float = Field(default=2.0, description="how close counts as reaching a buoy")
    planner: PlannerOptions = Field(default_factory=PlannerOptions)
    geofence: list[FenceZoneIn] | None = Field(
        default=None,
        max_length=MAX_FENCE_ZONES,
        description="zones the route must respect, uploaded to the vehicle (each vehicle of a fleet) as its fence "
        "before it flies; default: the fence the vehicle holds, if any",
    )
    rally_points: list[RallyPointIn] | None = Field(
        default=None,
        max_length=MAX_RALLY_POINTS,
        description="rally points uploaded to the vehicle (each vehicle of a fleet) with the mission, inside the "
        "geofence; default: none uploaded (the vehicle keeps its own)",
    )
    battery: BatteryIn | Literal["vehicle"] | None = Field(
        default=None,
        description="plan sorties within one battery each ('vehicle': every option from the vehicle); default: "
        "one tour, no energy planning",
    )
    wind: WindIn | None = Field(default=None, description="the forecast wind, for the energy prediction; default: calm")
    vehicle: int | None = Field(
        default=None, ge=1, le=255, description="the fleet's vehicle to fly (its system id); default: the first"
    )
    vehicles: list[Annotated[int, Field(ge=1, le=255)]] | Literal["fleet"] | None = Field(
        default=None,
        max_length=64,
        description="a fleet mission: the buoys shared among these vehicles (system ids; 'fleet': every vehicle of "
        "the service), each flying its share from its own home; default: one vehicle (`vehicle`)",
    )
    layer_gap_m: float = Field(
        default=3.0,
        ge=1.0,
        le=50.0,
        description="a fleet mission's altitude layers: the k-th vehicle flies at altitude_m + k x layer_gap_m",
    )
    separation_m: float = Field(
        default=5.0,
        ge=1.0,
        le=100.0,
        description="a fleet mission's least distance between two vehicles in the air around a shared depot: they "
        "take off in turn (each once the one before is this far beyond every pad) and land in turn",
    )

    @field_validator("battery", mode="after")
    @classmethod
    def _battery_shorthand(cls, value: Any) -> Any:
        return BatteryIn() if value == "vehicle" else value

    @model_validator(mode="before")
    @classmethod
    def _accept_geojson(cls, data: Any) -> Any:
        # A FeatureCollection becomes the same list of {id, lat, lon, ...} a client could have sent; its depot
        # feature (role "depot") is the request's depot when the request names none and is not a fleet's (whose
        # vehicles fly from their homes).
        if not isinstance(data, dict) or not isinstance(data.get("buoys"), dict):
            return data
        try:
            file = buoys_from_geojson(data["buoys"])
        except BuoyFileError:
            return data  # _geojson_refused names the field
        data = data | {"buoys": [b.as_dict() for b in file.buoys]}
        if file.depot is not None and data.get("depot") is None and data.get("vehicles") is None:
            data["depot"] = file.depot_as_dict()
        return data

    @field_validator("buoys", mode="before")
    @classmethod
    def _geojson_refused(cls, value: Any) -> Any:
        if isinstance(value, dict):  # a FeatureCollection _accept_geojson could not read: say why, at `buoys`
            try:
                buoys_from_geojson(value)
            except BuoyFileError as error:
                raise ValueError(str(error)) from None
        return value


class MissionRequest(PlanRequest):
    start: bool = Field(default=True, description="upload, arm and fly now")
    override: bool = Field(
        default=False,
        description="fly even when the pre-flight check finds the vehicle's charge short of what the tour needs "
        "(the override is recorded with the mission)",
    )


class Buoy(BaseModel):
    index: int
    id: str
    lat: float = Field(description="where the mission looks for it")
    lon: float
    east_m: float
    north_m: float
    register_id: str | None = Field(default=None, description="its id in the buoy register (null: none)")
    charted: LatLon | None = Field(
        default=None, description="its charted position when lat/lon is another (its latest AIS report)"
    )


class SortieOut(BaseModel):
    """One sortie: take-off at the depot, its buoys, back and land; predicted, and once flown, measured."""

    index: int
    order: list[int] = Field(description="its buoys' input indices in visiting order")
    route: list[list[float]] = Field(description="[lat, lon] from the depot through its buoys back to it")
    length_m: float
    predicted_energy_wh: float | None = Field(description="the energy model's prediction (null: no energy planning)")
    predicted_time_s: float | None
    margin_wh: float | None = Field(description="budget left after the predicted energy (negative: over budget)")
    margin_pct: float | None = Field(description="margin_wh in % of the budget")
    predicted_landing_charge_pct: float | None = Field(description="charge predicted at landing, on a full pack")
    used_energy_wh: float | None = Field(description="measured: the vehicle's BATTERY_STATUS energy consumed")
    landing_charge_pct: float | None = Field(description="measured: the vehicle's remaining charge after landing")
    battery_warning: str | None = Field(description="the worst battery state the vehicle reported in the sortie")


class EnergyOut(BaseModel):
    """The battery a multi-sortie plan was made for."""

    capacity_wh: float = Field(description="a full pack's energy at the terminals")
    usable_wh: float = Field(description="down to the reserve")
    budget_wh: float = Field(description="what a sortie may be planned to use: usable less the margin")
    reserve_pct: float
    reserve_source: str
    margin_pct: float
    pack: dict[str, float]
    pack_source: str = Field(description="'vehicle' (its parameters) or 'energy model' (the pack it was fitted on)")
    wind: dict[str, float | None]
    objective: str
    split: bool


class PlanOut(BaseModel):
    order: list[int] = Field(description="the buoys' input indices in visiting order")
    length_m: float
    input_order_length_m: float = Field(description="the tour visiting the buoys in the order given")
    improvement_pct: float = Field(description="how much shorter the plan is than the input order")
    method: str
    elapsed_s: float
    depot: LatLon
    buoys: list[Buoy]
    route: list[list[float]] = Field(
        description="[lat, lon] from the depot through the buoys back to it (a fleet mission: none, its shares' "
        "routes are in fleet.shares)"
    )
    sorties: list[SortieOut] = Field(description="one for a single tour; none for a fleet mission (fleet.shares)")
    energy: EnergyOut | None = Field(description="the battery and budget (null: no energy planning)")
    fleet: FleetPlanOut | None = Field(
        default=None, description="a fleet plan (`vehicles` given): the vehicles' shares (null: one vehicle)"
    )


class BuoyResult(BaseModel):
    index: int
    id: str
    closest_m: float | None
    reached: bool
    arrival_s: float | None = Field(description="vehicle time (time_boot_ms / 1000) when it was reached")
    arrival_at: AwareDatetime | None = Field(
        default=None, description="when the service heard it reached, UTC (null: not reached, or not heard live)"
    )


class LegFigures(BaseModel):
    leg: int
    samples: int
    rms_cross_track_m: float | None
    max_cross_track_m: float | None


class TrackingFigures(BaseModel):
    legs: list[LegFigures]
    rms_cross_track_m: float | None
    max_cross_track_m: float | None
    distance_flown_m: float
    planned_length_m: float
    flight_time_s: float | None


# MAV_SEVERITY's levels in its order (0 emergency ... 7 debug), as words
SEVERITIES = ("emergency", "alert", "critical", "error", "warning", "notice", "info", "debug")
Severity = Literal["emergency", "alert", "critical", "error", "warning", "notice", "info", "debug"]


class VehicleEvent(BaseModel):
    """A STATUSTEXT of the vehicle, or a mode change ("mode OFFBOARD -> AUTO.RTL"), at the vehicle's time."""

    t_s: float | None
    text: str
    at: AwareDatetime | None = Field(default=None, description="when the service received it, UTC")
    severity: Severity | None = Field(default=None, description="a STATUSTEXT's (MAV_SEVERITY); null: a mode change")


class PreflightCheck(BaseModel):
    """A sortie's pre-flight check: the charge it needs (its predicted energy, landing with the reserve) against
    the charge the vehicle reported before arming."""

    sortie: int = Field(description="0-based")
    needed_pct: float = Field(description="charge needed at take-off (over 100: no full pack of this kind suffices)")
    energy_wh: float = Field(description="the sortie's predicted energy")
    reserve_pct: float = Field(description="charge to land with")
    remaining_pct: float | None = Field(description="charge the vehicle reported (null: none reported)")
    override: bool = Field(description="flown short of charge because the request said override")
    swapped: bool = Field(default=False, description="flown after the operator confirmed a battery swap")


class BatterySwapIn(BaseModel):
    charge_pct: float = Field(default=100.0, ge=1.0, le=100.0, description="the charge of the pack put in")


class BatterySwapOut(BaseModel):
    vehicle: str = Field(description="what the vehicle answered to MAV_CMD_BATTERY_RESET")
    battery_remaining_pct: float | None = Field(description="the charge the vehicle reports now")
    waiting_mission: int | None = Field(description="the mission that was waiting for this swap, if any")


class Progress(BaseModel):
    current_seq: int | None = None
    total: int | None = None
    mission_state: int | None = None
    reached_seqs: list[int] = []
    visited: int = 0
    buoys: int = 0
    vehicle_events: list[VehicleEvent] = []
    sortie: int | None = Field(default=None, description="the sortie being flown (0-based)")
    sorties: int = 1
    visited_buoys: list[int] = Field(default=[], description="input indices of the buoys visited, every sortie")
    preflight: list[PreflightCheck] = Field(default=[], description="each sortie's pre-flight charge check")
    camera: str | None = Field(
        default=None,
        description="the camera the buoys are inspected with (null: visited only; the inspections say why)",
    )
    command: OperatorCommand | None = Field(
        default=None,
        description="the operator's command in force (POST /missions/{id}/hold, /return, /land; null: none, the "
        "mission flies as planned): which buttons apply, resume after hold or return",
    )


class PlannedShareOut(BaseModel):
    """One vehicle's share of a fleet mission as planned."""

    sysid: int
    buoys: list[int] = Field(description="input indices of its buoys in flying order")
    altitude_m: float
    predicted_time_s: float = Field(description="its flight, start command to disarm, its final hold included")
    length_m: float
    route: list[list[float]] = Field(description="[lat, lon] from its home through its buoys back home")
    start_s: float = Field(description="predicted mission start, seconds after the fleet's (take-offs in turn)")
    depart_after: int | None = Field(
        description="the vehicle (system id) whose leaving the depot zone starts this one (null: it starts at once)"
    )
    final_hold_s: float = Field(description="hover added at its last buoy, so that it lands in its turn")


class FleetPlanOut(BaseModel):
    """A fleet plan: the buoys shared among the vehicles (POST /plans with `vehicles`: nothing stored or flown)."""

    makespan_s: float = Field(description="predicted: when the last vehicle is home, the staggered starts counted")
    total_time_s: float
    layer_gap_m: float
    separation_m: float | None = Field(description="kept between vehicles taking off and landing (null: not kept)")
    shares: list[PlannedShareOut] = Field(description="the vehicles given buoys, in layer order")


class FleetShareOut(PlannedShareOut):
    """One vehicle's share of a fleet mission: its buoys, as planned, and its part mission as flown."""

    mission_id: int = Field(description="the part mission it flies (GET /missions/{id} for its telemetry, report)")
    status: MissionStatus
    visited_buoys: list[int] = Field(description="input indices of its buoys inspected so far")
    lost: str | None = Field(default=None, description="why this vehicle dropped out of the fleet mission, if it did")
    started_t_s: float | None = Field(
        default=None, description="its vehicle's time (time_boot_ms / 1000) when it was started in its turn"
    )
    ahead_t_s: float | None = Field(
        default=None, description="the time then of the vehicle it waited for (`depart_after`), on that vehicle's clock"
    )
    handed_over: dict[str, list[int]] = Field(
        default={}, description="a lost vehicle's buoys re-shared in flight: system id -> the buoys it took"
    )


class SeparationOut(BaseModel):
    """The closest two vehicles came while both were in the air (null: never two in the air at once)."""

    min_horizontal_m: float | None
    min_vertical_m: float | None
    min_distance_m: float | None


class FleetOut(FleetPlanOut):
    shares: list[FleetShareOut]  # type: ignore[assignment]  # the planned shares, each with its part mission
    inspected_by: dict[str, int] = Field(description="buoy id -> the system id of the vehicle that inspected it")
    separation: SeparationOut


class HomeOut(BaseModel):
    lat: float
    lon: float
    alt: float = Field(description="AMSL, metres")


class VehicleMotion(BaseModel):
    """Where the vehicle is, how it moves and where its controller wants it: the fields a telemetry sample and a
    vehicle's live state share, named as the link's VehicleStatus names them. Positions NED metres from home,
    angles radians; null where the vehicle has not reported it."""

    lat: float | None
    lon: float | None
    alt_m: float | None = Field(description="above home")
    north: float | None
    east: float | None
    down: float | None
    vn: float | None
    ve: float | None
    vd: float | None
    roll: float | None
    pitch: float | None
    yaw: float | None
    ref_north: float | None = Field(description="the offboard controller's reference")
    ref_east: float | None
    ref_down: float | None
    ref_yaw: float | None
    mission_seq: int | None
    landed_state: int | None = Field(description="MAV_LANDED_STATE")
    armed: bool


class VehicleOut(VehicleMotion):
    """A vehicle as its link last heard it (GET /vehicle, each of GET /vehicles, /ws): the vehicle status's fields
    by name (gcs.vehicle.link.VehicleStatus; a test keeps the two in step), and who owns the link."""

    connected: bool
    sysid: int | None
    compid: int | None
    autopilot: str | None
    vehicle_type: str | None
    reboots: int = Field(description="new boots of the same vehicle seen")
    incarnation: int = Field(description="rises with every new boot or new vehicle")
    base_mode: int
    custom_mode: int
    mode: str | None = Field(description="the flight mode's name (null while not connected)")
    time_boot_ms: int | None
    t_s: float | None = Field(description="vehicle time, time_boot_ms / 1000")
    boot_instant_s: float | None = Field(description="unix time of the vehicle's boot (SYSTEM_TIME)")
    heartbeat_age_s: float | None
    mission_total: int | None
    mission_state: int | None = Field(description="MISSION_STATE")
    battery_remaining_pct: float | None
    battery_voltage_v: float | None
    battery_current_a: float | None
    battery_consumed_wh: float | None
    battery_charge_state: int | None = Field(description="MAV_BATTERY_CHARGE_STATE")
    battery_critical: bool
    battery_low_pct: float | None = Field(description="the vehicle's own warning level (PX4's BAT_LOW_THR)")
    battery_critical_pct: float | None
    home: HomeOut | None
    estimates: dict[str, Any] = Field(description="a companion controller's ESO outputs, by name")
    status_texts: list[str] = Field(description="the vehicle's latest STATUSTEXTs, oldest first")
    status_severities: list[int] = Field(description="each one's MAV_SEVERITY (0 emergency .. 7 debug)")
    status_texts_heard: int = Field(description="STATUSTEXTs heard in all: a repeated text still counts anew")
    role: Literal["owner", "standby"] = Field(description="whether this instance owns the link (else a stand-by)")


class LinkOwnerOut(BaseModel):
    instance: str = Field(description="this service instance's name")
    owner: str | None = Field(description="the instance that owns the vehicle link (null: unknown)")


class ServiceVehicleOut(VehicleOut, LinkOwnerOut):
    """GET /vehicle: the (first) vehicle, with the depot a plan would use and the mission flying on it."""

    depot: LatLon
    active_mission: int | None


class LinkReceivedOut(BaseModel):
    messages: int = Field(description="MAVLink messages received from the vehicle")
    positions: int = Field(description="GLOBAL_POSITION_INT among them")


class FleetVehicleOut(VehicleOut):
    """An entry of GET /vehicles: the vehicle, its link and the mission flying on it."""

    link: str = Field(description="the connection, e.g. udpout:127.0.0.1:14540")
    active_mission: int | None
    received: LinkReceivedOut


class StatusEvent(BaseModel):
    """One entry of a mission's status history."""

    at: str
    status: MissionStatus
    reason: str | None = None


FLEET_ID = "the fleet mission this mission is a part of (null: not a part; a fleet mission's kind is `fleet`)"


class MissionOut(BaseModel):
    id: int
    status: MissionStatus
    reason: str | None
    created_at: str
    updated_at: str
    vehicle_sysid: int | None = Field(description="the fleet's vehicle it flies on (null: the service's one vehicle)")
    kind: MissionKind = Field(description="flown by one vehicle, shared by a fleet, or a vehicle's part of one")
    fleet_id: int | None = Field(description=FLEET_ID)
    fleet: FleetOut | None = Field(description="a fleet mission: its shares, who inspected what, the separation")
    order: list[int]
    length_m: float
    input_order_length_m: float
    improvement_pct: float
    method: str
    elapsed_s: float = Field(description="planner time")
    altitude_m: float
    speed_m_s: float
    dwell_s: float
    acceptance_radius_m: float
    depot: LatLon
    buoys: list[Buoy]
    route: list[list[float]] = Field(description="as in PlanOut: none for a fleet mission (fleet.shares' routes)")
    sorties: list[SortieOut] = Field(description="as in PlanOut: none for a fleet mission (fleet.shares)")
    energy: EnergyOut | None
    progress: Progress
    buoy_results: list[BuoyResult]
    tracking: TrackingFigures | None
    events: list[StatusEvent]


class MissionSummary(BaseModel):
    id: int
    status: MissionStatus
    reason: str | None
    created_at: str
    updated_at: str
    vehicle_sysid: int | None = Field(description="the fleet's vehicle it flies on (null: the service's one vehicle)")
    kind: MissionKind = Field(description="flown by one vehicle, shared by a fleet, or a vehicle's part of one")
    fleet_id: int | None = Field(description=FLEET_ID)
    buoys: int
    length_m: float
    tracking: TrackingFigures | None


class TelemetrySample(VehicleMotion):
    """One recorded sample of the vehicle's state. The one definition of a sample: the recorder fills these
    fields (TELEMETRY_FROM_STATUS from the link's vehicle status by name, the rest computed), storage keeps each
    sample as this document, and the API, the exports and the report read these names."""

    t_s: float = Field(description="vehicle time, time_boot_ms / 1000")
    eso: dict[str, Any] | None = Field(description="the offboard controller's ESO estimates, by name")
    cross_track_m: float | None = Field(default=None, description="distance to the leg being flown")
    sortie: int | None = Field(default=None, description="the sortie being flown (0-based)")


class TrackOut(BaseModel):
    """A mission's flown track cut down for the page (GET /missions/{id}/track); the exports keep every sample."""

    mission: int
    samples: int = Field(description="samples recorded (every one is in /telemetry and track.geojson)")
    tolerance_m: float = Field(description="every recorded position lies within this distance of `points`")
    points: list[list[float]] = Field(
        description="[lat, lon] of the kept samples: the first, the last, each buoy arrival, and the ones that "
        "keep the polyline closest to the recorded track"
    )
    series: list[TelemetrySample] = Field(
        description="samples over the whole flight for the charts (at most max_points, and 1000): in each stretch "
        "of the flight, the ones with the lowest and the highest cross-track error"
    )


# The sample's fields the recorder copies from the link's VehicleStatus attribute of the same name.
TELEMETRY_COMPUTED = ("t_s", "eso", "cross_track_m", "sortie")
TELEMETRY_FROM_STATUS = tuple(name for name in TelemetrySample.model_fields if name not in TELEMETRY_COMPUTED)


IalaRegion = Literal["A", "B"]


class ChartedMarkOut(BaseModel):
    """A buoy or beacon as an S-57 cell charts it (gcs.domain.charted_marks.ChartedMark.as_dict)."""

    id: str = Field(description="the object's LNAM (stable across the cell's editions), else RCID<n>")
    name: str | None = Field(description="OBJNAM, e.g. 'Annapolis Harbor Lighted Buoy 2'")
    lat: float
    lon: float
    object_class: str = Field(description="the S-57 class: BOYLAT, BOYCAR, ..., BCNLAT, BCNSPP, ...")
    beacon: bool = Field(description="a beacon stands fixed (swing radius 0); a buoy floats on its mooring")
    kind: BuoyKind | None = Field(description="from the class, CATLAM or CATCAM; null: the chart does not tell")
    preferred_channel: Literal["port", "starboard"] | None = Field(
        description="a modified lateral mark at a fork (CATLAM 3, 4): the side of the preferred channel"
    )
    light: str | None = Field(description="the main light in chart abbreviation (null: unlit or not readable)")
    other_lights: list[str] = Field(description="the other lights on the structure (chart text, or as charted)")
    swing_radius_m: float | None = Field(description="0 for a beacon; null for a buoy (the mission's default)")
    shape: str | None = Field(description="BOYSHP (cone, can, sphere, pillar, spar, ...) or BCNSHP (stake, pile...)")
    colours: list[str] = Field(description="the body's colours as charted (COLOUR), top to bottom")
    colour_pattern: str | None = Field(description="COLPAT: solid, horizontal, vertical, diagonal, squared, ...")
    region: IalaRegion | None = Field(description="the IALA region its colours are read in; null: no IALA system")


class ChartOut(BaseModel):
    """The S-57 cell an import read, and its marks in the order of `buoys`."""

    cell: str = Field(description="the cell's name, e.g. US4MD81M")
    edition: str | None
    update: str | None = Field(description="the last update applied (0: the base cell)")
    issued: str | None = Field(description="the issue date, YYYYMMDD")
    region: IalaRegion = Field(description="the cell's IALA region (its M_NSYS), else the request's or the default")
    region_source: Literal["chart", "default"]
    marks: list[ChartedMarkOut]


class ImportOut(BaseModel):
    buoys: list[BuoyIn] = Field(description="the buoys, as POST /missions takes them")
    depot: LatLon | None = Field(
        default=None, description="the file's depot: its point whose role is depot (GeoJSON property, CSV column)"
    )
    chart: ChartOut | None = Field(default=None, description="an S-57 cell's own description of them")
    warnings: list[str] = Field(default_factory=list, description="what the import could not map, each named")


# ----- inspections
class ChartedBuoyOut(BaseModel):
    lat: float
    lon: float
    kind: str = Field(description="IALA kind as charted ('unknown': not given)")
    light: str | None = Field(description="the charted light (null: unlit)")
    swing_radius_m: float
    region: str = Field(default="A", description="the IALA region its colours were checked in")


class InspectionOut(BaseModel):
    """One buoy's inspection: its verdict, the findings with their figures, what was observed, and the frames."""

    buoy: str = Field(description="the buoy's id")
    index: int = Field(description="the buoy's input index")
    verdict: Literal["ok", "defect", "not_inspected"]
    findings: list[dict[str, Any]] = Field(
        description="each defect: `code` (off_station, light_out, wrong_character, wrong_period, wrong_colour, "
        "wrong_body_colour, not_found) and its figures"
    )
    observed: LatLon | None = Field(description="where the buoy was seen (the median of its frames' waterlines)")
    offset_m: float | None = Field(description="observed position's distance from the charted one")
    light_seen: str | None = Field(description="the light as read from the burst ('dark', 'flashing .. G 6.0s')")
    charted: ChartedBuoyOut
    frames: list[str] = Field(description="URLs of the burst's frames, capture order")
    best_frame: str | None = Field(description="URL of the frame to show first")
    reason: str | None = Field(description="why the buoy was not inspected (null otherwise)")
    target: LatLon | None = Field(
        default=None,
        description="where the mission looked for the buoy when not at its charted position (its latest AIS report)",
    )
    offset_from_target_m: float | None = Field(default=None, description="observed position's distance from `target`")
