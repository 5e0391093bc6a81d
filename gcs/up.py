"""`buoy-gcs up`: the whole stack (vehicle, offboard controller, service) as supervised children.

With `--demo` it then flies the paper's reference scenario through the service's own REST API, as any
client would, and prints the report: route length against the exact optimum, flight time, tracking.
"""

from __future__ import annotations

import json
import math
import time
import urllib.error
import urllib.request
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from gcs.connection import parse_connection
from gcs.settings import Settings
from gcs.status import TERMINAL, MissionStatus
from gcs.supervisor import ChildSpec, Supervisor, SupervisorError, python_module

REPO = Path(__file__).resolve().parent.parent


@dataclass
class UpOptions:
    # the service's settings: its host, port and token; the vehicle's UDP port (vehicle_url's); the data
    # directory (database, logs, the vehicle's parameters); the MAVLink signing key shared by all three children
    settings: Settings = field(default_factory=Settings)
    lockstep: bool = True
    speed: float = 1.0
    seed: int = 0
    wind_m_s: float = 0.0
    wind_from_deg: float = 0.0
    controller: str = "adrc"  # adrc | pid | none (the vehicle's built-in PX4-style loop only)
    simulate: bool = True  # False: settings.vehicle_url is a real vehicle; only the service is started
    demo: bool = False
    demo_seed: int = 1  # which reference scenario to fly
    exit_after_demo: bool = False

    @property
    def base_url(self) -> str:
        return f"http://{self.settings.host}:{self.settings.port}"


def stack(options: UpOptions) -> list[ChildSpec]:
    """The children in start order (vehicle, offboard controller, service; the service alone for a real
    vehicle), with how to tell each is ready."""
    settings = options.settings
    if not options.simulate:
        return [_service(options, settings.vehicle_url, [])]
    vehicle_port = parse_connection(settings.vehicle_url).port
    vehicle_url = f"udpout:127.0.0.1:{vehicle_port}"  # the children all run on this machine
    vehicle_args = [
        "--port",
        str(vehicle_port),
        "--seed",
        str(options.seed),
        "--params",
        str(settings.data_dir / "vehicle.params"),
        "--param",
        f"SIM_WIND_SPD={options.wind_m_s:g}",
        "--param",
        f"SIM_WIND_DIR={options.wind_from_deg:g}",
    ]
    vehicle_args += ["--lockstep"] if options.lockstep else ["--speed", f"{options.speed:g}"]
    signing = ["--signing-key", settings.signing_key] if settings.signing_key else []
    vehicle_args += signing
    vehicle_log = settings.data_dir / "logs" / "sitl_quad.log"
    children = [
        ChildSpec(
            "sitl_quad", python_module("sitl_quad", *vehicle_args), ready=lambda: _log_says(vehicle_log, "listening")
        )
    ]
    if options.controller != "none":
        children.append(
            ChildSpec(
                "adrc_offboard",
                python_module("adrc_offboard", "--connect", vehicle_url, "--controller", options.controller, *signing),
            )
        )
    children.append(_service(options, vehicle_url, signing))
    return children


def _service(options: UpOptions, vehicle_url: str, signing: list[str]) -> ChildSpec:
    settings = options.settings
    gcs_args = [
        "serve",
        "--vehicle",
        vehicle_url,
        "--host",
        settings.host,
        "--port",
        str(settings.port),
        "--db",
        str(settings.db_path),
    ]
    if settings.token:
        gcs_args += ["--token", settings.token]
    gcs_args += signing or (["--signing-key", settings.signing_key] if settings.signing_key else [])
    base = options.base_url
    return ChildSpec("gcs", python_module("gcs", *gcs_args), ready=lambda: _http_ok(f"{base}/vehicle"))


def run_up(options: UpOptions, say=print) -> int:
    settings = options.settings
    settings.data_dir.mkdir(parents=True, exist_ok=True)
    supervisor = Supervisor(stack(options), settings.data_dir / "logs", REPO, say=say)
    supervisor.install_signal_handlers()
    base = options.base_url
    pacing = "lockstep" if options.lockstep else f"speed {options.speed:g}x"
    if options.simulate:
        say(f"starting vehicle ({pacing}, seed {options.seed}), {options.controller} controller and service ...")
    else:
        say(f"starting the service for the vehicle at {settings.vehicle_url} ...")
    try:
        supervisor.start_all()
        say(f"map page:   {base}/")
        say(f"API docs:   {base}/docs")
        say(f"data:       {settings.data_dir.resolve()} (vehicle.params, logs/); database {settings.db_path}")
        if options.demo:
            mission = fly_demo(base, options, supervisor, say)
            say(demo_report(mission, options))
            if options.exit_after_demo:
                return 0 if mission["status"] == MissionStatus.COMPLETED else 1
        say("running; Ctrl-C stops everything")
        supervisor.run_until_stopped()
        return 0
    except SupervisorError as error:
        say(f"buoy-gcs up: {error}")
        return 1
    finally:
        for name, code in supervisor.stop_all():
            if code not in (0, -15, None):
                say(f"{name} exited with code {code}")
        say("stopped")


# ----- the demo: the reference scenario through the REST API
def reference_request(options: UpOptions) -> dict:
    from planner.scenario import ALTITUDE_M, CRUISE_SPEED_M_S, reference_scenario

    scenario = reference_scenario(options.demo_seed)
    lat, lon, _ = scenario.home
    return {
        "depot": {"lat": lat, "lon": lon},
        "buoys": [
            {"id": f"B{i + 1}", "lat": float(a), "lon": float(b)} for i, (a, b) in enumerate(scenario.buoys_lat_lon)
        ],
        "altitude_m": ALTITUDE_M,
        "speed_m_s": CRUISE_SPEED_M_S,
        "dwell_s": 1.0,
        "acceptance_radius_m": 2.0,
        "planner": {"method": "chnn-ga", "seed": options.demo_seed, "time_limit_s": 2.0},
    }


def fly_demo(base: str, options: UpOptions, supervisor: Supervisor, say) -> dict:
    deadline = time.monotonic() + 60
    while not _get_json(f"{base}/vehicle").get("connected"):
        if time.monotonic() > deadline:
            raise SupervisorError("the service never heard the vehicle's heartbeat")
        supervisor.poll()
        time.sleep(0.5)
    # With a controller, fly once it answers the vehicle's ticks (its ESO estimates reach the service): in
    # lockstep the vehicle runs freely until then, and the whole demo should be the controller's flight.
    while options.controller == "adrc" and not _get_json(f"{base}/vehicle").get("estimates"):
        if time.monotonic() > deadline:
            raise SupervisorError("the offboard controller never answered the vehicle")
        supervisor.poll()
        time.sleep(0.2)
    token = options.settings.token
    headers = {"Authorization": f"Bearer {token}"} if token else {}
    mission = _post_json(f"{base}/missions", reference_request(options), headers)
    say(f"demo: mission {mission['id']} planned, {len(mission['order'])} buoys, {mission['length_m']:.0f} m; flying")
    last_visited = -1
    while mission["status"] not in TERMINAL:
        supervisor.poll()
        time.sleep(0.5)
        mission = _get_json(f"{base}/missions/{mission['id']}")
        visited = mission["progress"]["visited"]
        if visited != last_visited:
            say(f"demo: {mission['status']}, {visited}/{mission['progress']['buoys']} buoys")
            last_visited = visited
    return mission


def demo_report(mission: dict, options: UpOptions) -> str:
    """The paper's Section VI in figures from our own run."""
    from planner import plan_tour
    from uavcore.geodesy import LocalFrame

    depot = mission["depot"]
    frame = LocalFrame(depot["lat"], depot["lon"])
    points = np.vstack([[0.0, 0.0], frame.project(np.array([[b["lat"], b["lon"]] for b in mission["buoys"]]))])
    optimum = plan_tour(points, method="exact").length
    lines = [f"mission {mission['id']}: {mission['status']}" + (f" ({mission['reason']})" if mission["reason"] else "")]
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
            f"  flight     {tracking.get('flight_time_s') or math.nan:.1f} s simulated; flown "
            f"{tracking['distance_flown_m']:.0f} m of {tracking['planned_length_m']:.0f} m planned"
        )
        lines.append(
            f"  tracking   cross-track RMS {tracking['rms_cross_track_m'] or math.nan:.3f} m, "
            f"max {tracking['max_cross_track_m'] or math.nan:.3f} m ({options.controller} controller)"
        )
    lines.append(f"  report     python -m gcs report {mission['id']} --db {options.settings.db_path}")
    return "\n".join(lines)


# ----- small HTTP helpers (stdlib: the stack needs no HTTP client library)
def _http_ok(url: str) -> bool:
    try:
        with urllib.request.urlopen(url, timeout=2) as response:
            return response.status == 200
    except (urllib.error.URLError, OSError):
        return False


def _get_json(url: str) -> dict:
    with urllib.request.urlopen(url, timeout=10) as response:
        return json.loads(response.read())


def _post_json(url: str, body: dict, headers: dict) -> dict:
    request = urllib.request.Request(
        url, data=json.dumps(body).encode(), method="POST", headers={"Content-Type": "application/json", **headers}
    )
    try:
        with urllib.request.urlopen(request, timeout=60) as response:
            return json.loads(response.read())
    except urllib.error.HTTPError as error:
        raise SupervisorError(f"POST {url} answered {error.code}: {error.read().decode()[:500]}") from error


def _log_says(path: Path, marker: str) -> bool:
    """Whether the child's current run (after the supervisor's last "starting" line) printed the marker."""
    try:
        return marker in path.read_text().rpartition("starting: ")[2]
    except OSError:
        return False
