"""`buoy-gcs up`: the whole stack (vehicle, offboard controller, service) as supervised children, and with
`--demo` the paper's demo flown through the service (stack.demo); `--compare` then restarts the stack with the
PID cascade on the same seed and weather, flies again and prints both side by side."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from gcs.domain.status import MissionStatus
from gcs.storage import redacted
from gcs.vehicle.connection import parse_connection
from stack.children import children, vehicle_name
from stack.demo import COMPARISON_FIGURE, DemoFlight, DemoPlan, comparison, demo_report, fly_demo, prepare
from stack.options import LOOPS, UpOptions
from stack.sim_speed import watch_at
from stack.supervisor import ChildSpec, Supervisor, SupervisorError
from uavcore.mavlink import parse_signing_key

REPO = Path(__file__).resolve().parent.parent  # the children run from here (the checkout, or site-packages)


def run_up(options: UpOptions, say=print) -> int:
    """Start the stack and keep it running (Ctrl-C stops it); with `demo` fly the demo first (with `compare`
    once per cascade, the stack restarted in between), with `exit_after_demo` stop after it (exit code 0 when
    every flight completed)."""
    options.settings.data_dir.mkdir(parents=True, exist_ok=True)
    options, demo = prepare(options)
    controllers = [options.controller]
    if demo is not None and options.compare and options.controller != "pid":
        controllers.append("pid")
    flights: list[DemoFlight] = []
    for number, controller in enumerate(controllers, start=1):
        keep_running = number == len(controllers) and not options.exit_after_demo
        code = _run_stack(replace(options, controller=controller), demo, flights, keep_running, say)
        if code is not None:
            return code
    if len(flights) > 1:
        say(comparison(flights, options.settings.data_dir / COMPARISON_FIGURE))
    return 0 if all(f.mission["status"] == MissionStatus.COMPLETED for f in flights) else 1


def _run_stack(
    options: UpOptions, demo: DemoPlan | None, flights: list[DemoFlight], keep_running: bool, say
) -> int | None:
    """One life of the stack: start it, fly the demo if any, then keep it running or stop it. Returns an exit
    code to end `up` with, or None to go on (the demo flew and the stack is to stop)."""
    settings = options.settings
    supervisor = Supervisor(children(options), settings.data_dir / "logs", REPO, say=say)
    supervisor.install_signal_handlers()
    base = options.base_url
    pacing = "lockstep" if options.lockstep else f"speed {options.speed:g}x"
    if options.simulate:
        outer, inner = LOOPS[options.controller]
        fleet = f"{options.vehicles} vehicles, system ids 1-{options.vehicles}" if options.vehicles > 1 else "vehicle"
        say(f"starting {fleet} ({pacing}, seed {options.seed}; inner loop: {inner}), outer loop: {outer}; service ...")
    else:
        say(f"starting the service for the vehicle at {settings.vehicle_url} ...")
    try:
        supervisor.start_all()
        say(f"map page:   {base}/")
        say(f"API docs:   {base}/docs")
        database = redacted(str(settings.database))
        say(f"data:       {settings.data_dir.resolve()} (vehicle.params, logs/); database {database}")
        if demo is not None:
            flight = fly_demo(base, options, demo, supervisor, say)
            flights.append(flight)
            say(demo_report(flight, options, demo))
            if not keep_running:
                return None
        if options.simulate and options.watch_speed is not None:  # after the demo: it flew at full speed
            key = parse_signing_key(settings.signing_key) if settings.signing_key else None
            watch_at(simulated_vehicles(options, supervisor), options.watch_speed, key, say)
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


def simulated_vehicles(options: UpOptions, supervisor: Supervisor) -> list[tuple[ChildSpec, int, int]]:
    """Each simulated vehicle's (child spec, UDP port, system id): system ids 1..N on ports from vehicle_url's."""
    first = parse_connection(options.settings.vehicle_url).port
    specs = {child.spec.name: child.spec for child in supervisor.children}
    return [(specs[vehicle_name(sysid)], first + sysid - 1, sysid) for sysid in range(1, options.vehicles + 1)]
