"""The paper's demo through the ground station's REST API, as any client would fly it.

The reference scenario in the paper's weather (planner.scenario.paper_weather: a crosswind across the route's
longest leg, a 1-cosine gust halfway along it, Dryden turbulence, seeded by the vehicle's --seed), placed on the
route the service will fly (planned here first with the same request: the planner is deterministic for a seed),
and its buoys as a world the vehicle's camera sees (`demo_world`: each buoy's kind and light as World.default
gives them, charted in the request, two of them faulty in the water).
The report says which loops flew, the weather, the route against the exact optimum, the tracking, the gust's
effect from the recorded telemetry (gcs.domain.tracking_metrics.gust_effect), the lockstep speed and the inspection's
findings table; `comparison` puts two flights side by side, with a figure of the tracking error around the gust.
The inspection stops short of each buoy to film it: the paper's gust is placed on the timeline with those stops.
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any
from urllib.error import URLError

import numpy as np

from gcs.domain.planning import BURST_HOLD_MARGIN_S, BuoyMark, FlightParams, MissionLayout, Plan, make_plan
from gcs.domain.status import TERMINAL
from gcs.domain.tracking_metrics import GUST_WINDOW_S, RECOVERED_M, GustEffect, climb_start_s, gust_effect
from gcs.reports.report import draw_series, report_series
from gcs.storage import redacted
from planner.scenario import (
    ALTITUDE_M,
    CRUISE_SPEED_M_S,
    TURBULENCE_SIGMA_M_S,
    MissionTimeline,
    PaperWeather,
    Weather,
    paper_weather,
    reference_scenario,
)
from stack.options import CASCADE_NAMES, LOOPS, UpOptions
from stack.service_api import get_json, post_json
from stack.supervisor import Supervisor, SupervisorError
from uavcore.buoy_world import World

DEMO_DWELL_S = 1.0
DEMO_ACCEPTANCE_M = 2.0
COMPARISON_FIGURE = "demo-gust-comparison.png"
DEMO_WORLD = "demo-world.geojson"
# An AtoN's MMSI is 99 MID xxxx (ITU-R M.585); the reference scenario lies off Dalian, and 412 is a Chinese MID
DEMO_MMSI = 994_120_001
# The demo's two faults, by visiting position: the third buoy's light is out, the eighth is moored three swing radii
# beyond its charted position along the way the vehicle comes in (in the camera's view, off station)
LIGHT_OUT_AT, OFF_STATION_AT, OFF_STATION_RADII = 2, 7, 3.0


@dataclass(frozen=True)
class DemoPlan:
    request: dict  # POST /missions body
    plan: Plan  # what the service will plan for it
    placed: PaperWeather  # the paper's weather on that route
    world: World  # what the vehicle's camera sees: the buoys as charted, two of them faulty


def charted_world(options: UpOptions) -> World:
    """The reference scenario's buoys as charted: kinds and lights as World.default gives them, no faults, and
    each with an AIS transmitter (DEMO_MMSI + its index), so the page shows where AIS says they float."""
    scenario = reference_scenario(options.demo_seed)
    world = World.default(scenario.buoys_lat_lon, [f"B{i + 1}" for i in range(len(scenario.buoys_lat_lon))])
    return replace(world, buoys=tuple(replace(b, mmsi=DEMO_MMSI + i) for i, b in enumerate(world.buoys)))


def reference_request(options: UpOptions) -> dict:
    scenario = reference_scenario(options.demo_seed)
    lat, lon, _ = scenario.home
    charted = {f["properties"]["id"]: f["properties"] for f in charted_world(options).to_geojson()["features"]}
    return {
        "depot": {"lat": lat, "lon": lon},
        "buoys": [
            {"id": f"B{i + 1}", "lat": float(a), "lon": float(b)}
            | {key: charted[f"B{i + 1}"][key] for key in ("kind", "light", "swing_radius_m")}
            for i, (a, b) in enumerate(scenario.buoys_lat_lon)
        ],
        "altitude_m": ALTITUDE_M,
        "speed_m_s": CRUISE_SPEED_M_S,
        "dwell_s": DEMO_DWELL_S,
        "acceptance_radius_m": DEMO_ACCEPTANCE_M,
        "planner": {"method": "chnn-ga", "seed": options.demo_seed, "time_limit_s": 2.0},
    }


def plan_demo(options: UpOptions) -> DemoPlan:
    """Plan the demo's request here as the service will (same planner, method and seed) and place the paper's
    weather on that route: the depot, then the buoys in visiting order (the return home does not count)."""
    request = reference_request(options)
    planner = request["planner"]
    plan = make_plan(
        (request["depot"]["lat"], request["depot"]["lon"]),
        [(b["lat"], b["lon"]) for b in request["buoys"]],
        [b["id"] for b in request["buoys"]],
        planner["method"],
        planner["seed"],
        planner["time_limit_s"],
    )
    plan = replace(plan, marks=[BuoyMark(b["kind"], b["light"], b["swing_radius_m"]) for b in request["buoys"]])
    holds = []
    for index in plan.order:
        duration_s, rate_hz = plan.mark(index).burst()
        holds.append(math.ceil(duration_s * rate_hz) / rate_hz + BURST_HOLD_MARGIN_S)
    timeline = MissionTimeline(
        altitude_m=request["altitude_m"], cruise_m_s=request["speed_m_s"], dwell_s=request["dwell_s"],
        standoff_m=FlightParams(0, 0, 0, 0).inspection_range_m, holds_s=tuple(holds),
    )  # fmt: skip
    return DemoPlan(request, plan, paper_weather(plan.route_local()[:-1], timeline), demo_world(options, plan))


def demo_world(options: UpOptions, plan: Plan) -> World:
    """The charted world with the demo's two faults (LIGHT_OUT_AT, OFF_STATION_AT): what the camera sees."""
    world = charted_world(options)
    buoys = list(world.buoys)
    route = plan.route_local()  # [east, north]: the depot, the buoys in visiting order, the depot
    dark = plan.order[LIGHT_OUT_AT]
    buoys[dark] = replace(buoys[dark], actual_light=None)
    moved = plan.order[OFF_STATION_AT]
    east, north = route[OFF_STATION_AT + 1] - route[OFF_STATION_AT]  # the way in to it
    away = OFF_STATION_RADII * buoys[moved].swing_radius_m / math.hypot(east, north)
    buoys[moved] = replace(buoys[moved], offset_m=(float(north * away), float(east * away)))
    return replace(world, buoys=tuple(buoys))


def prepare(options: UpOptions) -> tuple[UpOptions, DemoPlan | None]:
    """The options with the weather the vehicle is to fly (the paper's on the demo's route unless one was
    given; still air without a demo), and the demo's plan (None without a demo)."""
    demo = plan_demo(options) if options.demo and options.simulate else None
    if options.weather is None:
        options = replace(options, weather=demo.placed.weather if demo is not None else Weather())
    if demo is not None and options.world is None:
        path = options.settings.data_dir / DEMO_WORLD
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(demo.world.to_geojson(), indent=1))
        options = replace(options, world=path)
    return options, demo


@dataclass
class DemoFlight:
    controller: str
    weather: Weather
    mission: dict  # GET /missions/{id} once it ended
    samples: list[dict[str, Any]]  # GET /missions/{id}/telemetry
    wall_s: float  # from POST /missions until the mission ended (landed)
    gust_onset_t_s: float | None = None  # the gust's onset in the vehicle's time (None: no gust, or no climb)
    gust: GustEffect | None = None
    gust_leg: int | None = None  # the leg being flown at the onset (1 = depot to the first buoy)
    inspections: list[dict[str, Any]] = field(default_factory=list)  # GET /missions/{id}/inspections
    atons: list[dict[str, Any]] = field(default_factory=list)  # GET /ais/atons' rows once it ended

    @property
    def simulated_s(self) -> float:
        """The recorded mission's span in the vehicle's time (from its first sample, at the upload, to the last)."""
        return float(self.samples[-1]["t_s"] - self.samples[0]["t_s"]) if len(self.samples) > 1 else math.nan


def fly_demo(base: str, options: UpOptions, demo: DemoPlan, supervisor: Supervisor, say) -> DemoFlight:
    deadline = time.monotonic() + 60
    while not get_json(f"{base}/vehicle").get("connected"):
        _wait(supervisor, deadline, "the service never heard the vehicle's heartbeat", 0.5)
    # With the ADRC controller, fly once it answers the vehicle's ticks (its ESO estimates reach the service): in
    # lockstep the vehicle runs freely until then, and the whole demo should be the controller's flight.
    while options.controller == "adrc" and not get_json(f"{base}/vehicle").get("estimates"):
        _wait(supervisor, deadline, "the offboard controller never answered the vehicle", 0.2)
    token = options.settings.token
    headers = {"Authorization": f"Bearer {token}"} if token else {}
    posted = time.monotonic()
    mission = post_json(f"{base}/missions", demo.request, headers)
    say(f"demo: mission {mission['id']} planned, {len(mission['order'])} buoys, {mission['length_m']:.0f} m; flying")
    if mission["order"] != demo.plan.order:
        say("demo: WARNING the service planned another order than this one did: the gust was placed for this one's")
    last_visited = -1
    while mission["status"] not in TERMINAL:
        _wait(supervisor, math.inf, "", 0.5)
        try:
            mission = get_json(f"{base}/missions/{mission['id']}")
        except (TimeoutError, URLError) as error:  # a machine loaded by others: the supervisor watches the service
            say(f"demo: the service did not answer ({error}); asking again")
        visited = mission["progress"]["visited"]
        if visited != last_visited:
            say(f"demo: {mission['status']}, {visited}/{mission['progress']['buoys']} buoys")
            last_visited = visited
    wall = time.monotonic() - posted
    samples = get_json(f"{base}/missions/{mission['id']}/telemetry")
    flight = measure_flight(options.controller, options.weather or Weather(), mission, samples, wall)
    flight.inspections = get_json(f"{base}/missions/{mission['id']}/inspections")
    flight.atons = get_json(f"{base}/ais/atons")["atons"]
    return flight


def measure_flight(controller: str, weather: Weather, mission: dict, samples: list[dict], wall_s: float) -> DemoFlight:
    """The demo's figures from a mission's recorded telemetry (pure). The gust's onset is stated in seconds
    after the mission's start command (the vehicle's disturbance clock); in the vehicle's time that is the
    climb's start (the reference leaves the ground) less the motors' spool-up, to within one sample."""
    flight = DemoFlight(controller, weather, mission, samples, wall_s)
    if weather.gust_m_s == 0.0 or not samples:
        return flight
    series = report_series(samples)
    climb = climb_start_s(series.t_s, -series.ref_altitude)
    if climb is None:
        return flight
    flight.gust_onset_t_s = climb - MissionTimeline().spool_up_s + weather.gust_start_s
    flight.gust = gust_effect(series.t_s, series.position_error_m, flight.gust_onset_t_s)
    at_onset = samples[int(np.searchsorted(series.t_s, flight.gust_onset_t_s).clip(max=len(samples) - 1))]
    layout = MissionLayout(len(mission["order"]), inspected=mission["progress"].get("camera") is not None)
    leg = layout.leg_of_seq(at_onset.get("mission_seq"))
    flight.gust_leg = None if leg is None else leg + 1
    return flight


def _wait(supervisor: Supervisor, deadline: float, why: str, pause_s: float) -> None:
    """One pause of a demo's wait: the children are watched, Ctrl-C ends the demo, the deadline raises `why`."""
    supervisor.poll()
    if supervisor.stopping:
        raise SupervisorError("stopped during the demo")
    if time.monotonic() > deadline:
        raise SupervisorError(why)
    time.sleep(pause_s)


def describe_weather(weather: Weather, placed: PaperWeather | None, seed: int) -> str:
    """The weather in words; `placed`: the paper's weather for the route, to say where it was put."""
    parts = []
    if weather.wind_m_s:
        wind = f"wind {weather.wind_m_s:g} m/s from {weather.wind_from_deg:.0f} deg"
        if placed is not None and weather == placed.weather:
            wind += f" (across the longest leg, leg {placed.longest_leg}, bearing {placed.leg_bearing_deg:.0f} deg)"
        parts.append(wind)
    if weather.gust_m_s:
        hold = "stays" if math.isinf(weather.gust_hold_s) else f"held {weather.gust_hold_s:g} s"
        parts.append(
            f"1-cosine gust {weather.gust_m_s:+g} m/s from {weather.gust_from_deg:.0f} deg at "
            f"{weather.gust_start_s:g} s after the mission start (rise {weather.gust_rise_s:g} s, {hold})"
        )
    if weather.turbulence_w20_m_s:
        sigma = f", sigma {TURBULENCE_SIGMA_M_S:g} m/s at {ALTITUDE_M:g} m" if placed is not None else ""
        parts.append(f"Dryden turbulence W20 {weather.turbulence_w20_m_s:.2f} m/s{sigma}")
    return "; ".join([*(parts or ["still air"]), f"D terms variance {weather.disturbance_variance:g}; seed {seed}"])


def demo_report(flight: DemoFlight, options: UpOptions, demo: DemoPlan | None = None) -> str:
    """The paper's Section VI in figures from our own run."""
    from planner import plan_tour
    from uavcore.geodesy import LocalFrame

    mission = flight.mission
    depot = mission["depot"]
    frame = LocalFrame(depot["lat"], depot["lon"])
    points = np.vstack([[0.0, 0.0], frame.project(np.array([[b["lat"], b["lon"]] for b in mission["buoys"]]))])
    optimum = plan_tour(points, method="exact").length
    outer, inner = LOOPS[flight.controller]
    with_eso = sum(1 for s in flight.samples if s.get("eso"))
    evidence = f"; ESO estimates in {with_eso} of {len(flight.samples)} samples" if flight.controller != "px4" else ""
    lines = [f"mission {mission['id']}: {mission['status']}" + (f" ({mission['reason']})" if mission["reason"] else "")]
    lines.append(f"  loops      {CASCADE_NAMES[flight.controller]}: outer {outer}{evidence}")
    lines.append(f"             inner {inner} in the vehicle")
    lines.append(f"  weather    {describe_weather(flight.weather, demo.placed if demo else None, options.seed)}")
    lines.append(
        f"  route      {mission['length_m']:.1f} m planned by {mission['method']}; exact optimum "
        f"{optimum:.1f} m ({100 * (mission['length_m'] / optimum - 1):+.2f} %); "
        f"{mission['improvement_pct']:.1f} % shorter than the input order"
    )
    reached = [b for b in mission["buoy_results"] if b["reached"]]
    worst = max((b["closest_m"] for b in mission["buoy_results"] if b["closest_m"] is not None), default=math.nan)
    lines.append(
        f"  buoys      {len(reached)}/{len(mission['buoy_results'])} reached; worst closest approach "
        f"{worst:.2f} m (acceptance {mission['acceptance_radius_m']:g} m)"
    )
    tracking = mission.get("tracking") or {}
    if tracking:
        lines.append(
            f"  flight     {duration_text(tracking.get('flight_time_s'))} in the air (vehicle time, take-off to "
            f"landing); flown {tracking['distance_flown_m']:.0f} m of {tracking['planned_length_m']:.0f} m planned"
        )
        lines.append(
            f"  tracking   cross-track RMS {tracking['rms_cross_track_m'] or math.nan:.3f} m, "
            f"max {tracking['max_cross_track_m'] or math.nan:.3f} m"
        )
    if flight.gust is not None:
        lines.append(
            f"  gust       peak 3-D tracking error {flight.gust.peak_m:.3f} m within {GUST_WINDOW_S:g} s of the onset "
            f"(vehicle time {flight.gust_onset_t_s:.1f} s, on leg {flight.gust_leg}); back under {RECOVERED_M:g} m "
            f"for good after {flight.gust.recovery_s:.1f} s"
        )
    # the mission's span on both clocks: its recorded samples (from the upload, the vehicle on the ground until
    # armed, to landed: longer than the time in the air) against the wall clock over the request (POST to landed)
    lines.append(
        f"  sim speed  {flight.simulated_s:.1f} s of vehicle time (upload to landed) in {flight.wall_s:.1f} s of "
        f"wall-clock time (POST to landed): {flight.simulated_s / flight.wall_s:.1f} times real time"
    )
    if flight.inspections:
        lines.append(f"  inspection {mission['progress'].get('camera') or 'no camera'}")
        lines += ["    " + line for line in findings_table(flight.inspections).splitlines()]
    if flight.atons:
        lines.append(f"  AIS        {ais_summary(flight.atons)}")
    lines.append(f"  report     python -m gcs report {mission['id']} --db {redacted(str(options.settings.database))}")
    return "\n".join(lines)


def duration_text(seconds: float | None) -> str:
    """A duration as an operator reads it: "12 min 05.3 s", "41.2 s" (None: "unknown")."""
    if seconds is None or not math.isfinite(seconds):
        return "unknown"
    minutes, rest = divmod(seconds, 60.0)
    return f"{int(minutes)} min {rest:04.1f} s" if minutes else f"{rest:.1f} s"


def _finding_text(finding: dict[str, Any]) -> str:
    """A finding and its figures in a few words: "off_station 15.2 m (swing 5 m)", "light_out"."""
    code = finding["code"]
    if code == "off_station":
        return f"off_station {finding['offset_m']:.1f} m (swing {finding['swing_radius_m']:g} m)"
    if code in ("wrong_character", "wrong_period", "wrong_colour"):
        return f"{code} (charted {finding.get('charted')}, seen {finding.get('seen')})"
    return code


def ais_summary(atons: list[dict[str, Any]]) -> str:
    """The AtoNs the service heard, in a line: how many, and those reporting themselves off position."""
    off = sorted(a["name"] for a in atons if a["off_position"] and a["off_position_valid"] and not a["stale"])
    flagged = f"off position: {', '.join(off)}" if off else "none reports itself off position"
    return f"{len(atons)} AtoNs heard (GET /ais/atons, the map's AIS layer); {flagged}"


def findings_table(inspections: list[dict[str, Any]]) -> str:
    """The inspections as a text table, a row per buoy, then the count of each verdict."""
    rows = [("buoy", "kind", "light", "verdict", "seen", "offset", "findings / reason")]
    for i in inspections:
        offset = "" if i["offset_m"] is None else f"{i['offset_m']:.1f} m"
        why = ", ".join(_finding_text(f) for f in i["findings"]) or (i["reason"] or "")
        rows.append((i["buoy"], i["charted"]["kind"], i["charted"]["light"] or "unlit", i["verdict"],
                     i["light_seen"] or "", offset, why))  # fmt: skip
    widths = [max(len(str(row[c])) for row in rows) for c in range(len(rows[0]) - 1)]
    lines = ["  ".join(str(v).ljust(w) for v, w in zip(row, widths, strict=False)) + "  " + row[-1] for row in rows]
    verdicts = [i["verdict"] for i in inspections]
    counts = ", ".join(f"{verdicts.count(v)} {v}" for v in ("ok", "defect", "not_inspected"))
    return "\n".join([*lines, f"{len(inspections)} buoys: {counts}"])


def comparison(flights: list[DemoFlight], figure: Path) -> str:
    """The flights side by side (same seed and weather), and a figure of their tracking error around the gust."""

    def figures(f: DemoFlight) -> list[str]:
        tracking = f.mission.get("tracking") or {}
        gust = f.gust or GustEffect(math.nan, math.nan)
        return [
            CASCADE_NAMES[f.controller],
            LOOPS[f.controller][0].split(" (")[0],
            LOOPS[f.controller][1],
            f"{f.mission['status']}",
            f"{tracking.get('rms_cross_track_m') or math.nan:.3f} m",
            f"{tracking.get('max_cross_track_m') or math.nan:.3f} m",
            f"{gust.peak_m:.3f} m",
            f"{gust.recovery_s:.1f} s",
            f"{f.simulated_s:.1f} s",
            f"{f.wall_s:.1f} s",
            f"{f.simulated_s / f.wall_s:.1f}x",
        ]

    rows = [
        "",
        "outer loop",
        "inner loop",
        "status",
        "cross-track RMS",
        "cross-track max",
        "gust peak error",
        "gust recovery",
        "simulated",
        "wall POST->landed",
        "lockstep speed",
    ]
    columns = [figures(f) for f in flights]
    widths = [max(len(c) for c in column) + 2 for column in columns]
    lines = ["comparison (same seed, same weather):"]
    for i, row in enumerate(rows):
        lines.append(f"  {row:18}" + "".join(f"{column[i]:<{w}}" for column, w in zip(columns, widths, strict=True)))
    drawn = [f for f in flights if f.gust_onset_t_s is not None]
    if drawn:
        curves = []
        for f in drawn:
            series = report_series(f.samples)
            near = (series.t_s >= f.gust_onset_t_s - 5.0) & (series.t_s <= f.gust_onset_t_s + 2 * GUST_WINDOW_S)
            curves.append(
                (series.t_s[near] - f.gust_onset_t_s, series.position_error_m[near], CASCADE_NAMES[f.controller])
            )
        weather = drawn[0].weather
        full_until = weather.gust_rise_s + min(weather.gust_hold_s, 2 * GUST_WINDOW_S)
        draw_series(
            figure,
            "3-D tracking error around the gust (shaded: gust at full strength)",
            "time since the gust's onset (s)",
            "m",
            curves,
            shade=(weather.gust_rise_s, full_until),
        )
        lines.append(f"  figure: {figure}")
    return "\n".join(lines)
