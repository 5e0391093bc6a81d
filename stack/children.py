"""The stack's children: each simulated vehicle (sitl_quad) and its offboard controller (adrc_offboard), then the
ground station (gcs serve), as the supervisor's ChildSpecs; the service alone for a real vehicle.

The weather is handed to the vehicle as its SIM_* parameters, every one of them each time (the vehicle keeps its
parameters in the data directory, so an unnamed one would carry over from the last run); so is SIM_SPEEDUP, 0 (full
lockstep speed: `up --real-time` sets it once the demo has flown, stack.sim_speed). Secrets (the API token,
the MAVLink signing key, a database URL) go by the environment, never a command line.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from adrc_offboard.design import load_design, pid_attitude_gains
from gcs.settings import Settings
from gcs.vehicle.connection import parse_connection
from planner.scenario import Weather
from stack.options import ATTITUDE_LOOP, CONTROLLERS, UpOptions
from stack.service_api import http_ok
from stack.sim_speed import speedup_arg
from stack.supervisor import ChildSpec, current_run, python_module
from uavcore.airframe import Airframe
from uavcore.geodesy import LocalFrame
from uavcore.mavlink import SIGNING_KEY_ENV

PAD_SPACING_M = 3.0  # vehicles sharing a depot stand this far apart, west to east


def weather_params(weather: Weather) -> list[str]:
    """The vehicle's `--param NAME=VALUE` arguments for a weather: all of the air's parameters."""
    values = {
        "SIM_WIND_SPD": weather.wind_m_s,
        "SIM_WIND_DIR": weather.wind_from_deg,
        "SIM_GUST_AMP": weather.gust_m_s,
        "SIM_GUST_DIR": weather.gust_from_deg,
        "SIM_GUST_T0": weather.gust_start_s,
        "SIM_GUST_RISE": weather.gust_rise_s,
        "SIM_GUST_HOLD": weather.gust_hold_s,
        "SIM_TURB_W20": weather.turbulence_w20_m_s,
        **{f"SIM_DIST_V{axis}": weather.disturbance_variance for axis in ("X", "Y", "Z", "R", "P", "YAW")},
    }
    return [f"{name}={value:.7g}" for name, value in values.items()]


def children(options: UpOptions) -> list[ChildSpec]:
    """The children in start order (each vehicle and its offboard controller unless `px4`, then the service;
    the service alone for a real vehicle), with how to tell each is ready."""
    settings = options.settings
    if not options.simulate:
        return [_service(options, settings.vehicles or [settings.vehicle_url])]
    if options.controller not in CONTROLLERS:
        raise ValueError(f"controller must be one of {CONTROLLERS}, got {options.controller!r}")
    first_port = parse_connection(settings.vehicle_url).port
    children, links = [], []
    for sysid in range(1, options.vehicles + 1):
        vehicle, controller = _vehicle_children(options, sysid, first_port + sysid - 1)
        children += [vehicle, *controller]
        url = f"udpout:127.0.0.1:{first_port + sysid - 1}"  # the children all run on this machine
        links.append(url if options.vehicles == 1 else f"{sysid}={url}")  # a fleet names each one's system id
    children.append(_service(options, links, world_ais(options)))
    return children


def world_ais(options: UpOptions) -> list[str]:
    """The AIS source the service listens on for the simulated world's reports (none without a world)."""
    return [f"udp://127.0.0.1:{options.world_ais_port}"] if options.world is not None and options.world_ais_port else []


def vehicle_home(options: UpOptions, sysid: int) -> tuple[float, float, float] | None:
    """Where vehicle `sysid` stands: its depot (i mod the depots given, else the default home), each vehicle of
    a depot on its own pad PAD_SPACING_M east of the one before; None for a lone vehicle at the default home."""
    if options.vehicles == 1 and not options.depots:
        return None
    depots = options.depots or (options.settings.home[:2],)
    lat, lon = depots[(sysid - 1) % len(depots)]
    pad = (sysid - 1) // len(depots)
    home = LocalFrame(lat, lon, options.settings.home[2]).from_ned(0.0, pad * PAD_SPACING_M, 0.0)
    return float(home[0]), float(home[1]), options.settings.home[2]


def _vehicle_children(options: UpOptions, sysid: int, port: int) -> tuple[ChildSpec, list[ChildSpec]]:
    """Vehicle `sysid` (sitl_quad, its own port, seed, parameter file and log) and its offboard controller."""
    settings = options.settings
    suffix = _suffix(sysid)
    params = [f"MC_ATT_CTRL={ATTITUDE_LOOP[options.controller]}", speedup_arg(0.0)]
    if options.controller == "pid":  # the PID family's designed attitude gains; "px4" keeps PX4's defaults
        params += [f"{name.upper()}={value:.6g}" for name, value in designed_pid_attitude().items()]
    params += weather_params(options.weather or Weather())
    vehicle_args = ["--port", str(port), "--sysid", str(sysid), "--seed", str(options.seed + sysid - 1)]
    vehicle_args += ["--params", str(settings.data_dir / f"vehicle{suffix}.params")]
    if (home := vehicle_home(options, sysid)) is not None:
        vehicle_args += ["--home", ",".join(f"{value:.8f}" for value in home)]
    vehicle_args += [arg for param in params for arg in ("--param", param)]
    if options.world is not None:  # a camera on a gimbal, seeing these buoys; its images in the data directory
        vehicle_args += ["--world", str(options.world), "--image-dir", str(settings.data_dir / f"images{suffix}")]
        if sysid == 1 and options.world_ais_port:  # one station for the world: a fleet's vehicles share it
            vehicle_args += ["--ais-out", f"127.0.0.1:{options.world_ais_port}"]
    vehicle_args += ["--lockstep"] if options.lockstep else ["--speed", f"{options.speed:g}"]
    signing = _signing_env(settings)
    vehicle_log = settings.data_dir / "logs" / f"sitl_quad{suffix}.log"
    vehicle = ChildSpec(
        vehicle_name(sysid),
        python_module("sitl_quad", *vehicle_args),
        ready=lambda: _log_says(vehicle_log, "listening"),
        env=signing,
        port_option="--vehicle-port",
    )
    if options.controller == "px4":
        return vehicle, []
    connect = ["--connect", f"udpout:127.0.0.1:{port}", "--sysid", str(sysid), "--controller", options.controller]
    return vehicle, [ChildSpec(f"adrc_offboard{suffix}", python_module("adrc_offboard", *connect), env=signing)]


def vehicle_name(sysid: int) -> str:
    """The child name of vehicle `sysid` (its log is data/logs/NAME.log)."""
    return f"sitl_quad{_suffix(sysid)}"


def _suffix(sysid: int) -> str:
    return "" if sysid == 1 else f"-{sysid}"  # a lone vehicle keeps the names it always had


def _signing_env(settings: Settings) -> dict[str, str]:
    """The vehicle's and the offboard controller's MAVLink signing key, by the environment (not argv: see below)."""
    return {SIGNING_KEY_ENV: settings.signing_key} if settings.signing_key else {}


def _service(options: UpOptions, vehicles: list[str], extra_ais: Sequence[str] = ()) -> ChildSpec:
    settings = options.settings
    gcs_args = [
        "serve",
        *(arg for vehicle in vehicles for arg in ("--vehicle", vehicle)),
        "--host",
        settings.host,
        "--port",
        str(settings.port),
        *(arg for source in [*settings.ais_sources, *extra_ais] for arg in ("--ais", source)),
    ]
    # the token, the signing key and a database URL (it may hold a password) go by the environment: a command line
    # is written to the child's log and shown by ps
    secrets = {"token": settings.token, "signing_key": settings.signing_key}
    env = {Settings.env_name(name): value for name, value in secrets.items() if value}
    if settings.db is None:
        gcs_args += ["--db", str(settings.db_path)]
    else:
        env[Settings.env_name("db")] = settings.db
    base = options.base_url
    return ChildSpec(
        "gcs", python_module("gcs", *gcs_args), ready=lambda: http_ok(f"{base}/vehicle"), env=env, port_option="--port"
    )


def _log_says(path: Path, marker: str) -> bool:
    """Whether the child's current run (after the supervisor's last "starting" line) printed the marker."""
    try:
        return marker in current_run(path.read_text())
    except OSError:
        return False


def designed_pid_attitude() -> dict[str, float]:
    """The vehicle's attitude PID gains (PX4 names, lower case) at the PID family's shipped design for the
    simulated airframe (paper Table 2), as adrc_offboard.design derives them."""
    return pid_attitude_gains(Airframe.table2(), load_design("pid"))
