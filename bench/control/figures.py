"""The paper's figures drawn from seed 0 of each controller: tracking around the gust (Fig. 6: altitude, yaw,
pitch, roll), the six ESOs' estimates against the truth (Fig. 7: outer x, y, z, inner roll, pitch, yaw), the flown
tracks over the planned route (Fig. 10), yaw at the turns (Fig. 11), and the step responses; Fig. 9 (route and
the CHNN-GA per iteration) is drawn by bench/paper_figures.py with Fig. 6 and 7 (`tracking_figure`,
`eso_figure`, `route_figure`)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from bench.control import REPO
from bench.control.flight import LABELS
from bench.control.scenario import OUTER_RATE_HZ, STEP_M, Scenario
from gcs.domain.planning import FIRST_BUOY_SEQ


def draw_figures(scenario: Scenario, series: dict[str, dict], steps: dict[str, np.ndarray], out_dir: Path) -> list[str]:
    """Draw the figures into out_dir; returns their paths (relative to the repository when inside it)."""
    import matplotlib  # here, not at the top: --no-figures runs never load it

    matplotlib.use("Agg")  # files only, no display
    import matplotlib.pyplot as plt

    colours = COLOURS
    paths = []
    t_gust = scenario.wind.gust_start_s

    def since_takeoff(s):
        return s["t"][1:] - s["t"][0]

    # Figure 6: altitude, yaw, pitch, roll (and the horizontal error) around the gust; Figure 7: the ADRC's six
    # extended state observers (outer x, y, z; inner roll, pitch, yaw) against the truth
    gust = (t_gust, t_gust + scenario.wind.gust_rise_time_s)
    paths.append(
        tracking_figure(
            series, gust, out_dir / "control_gust_tracking.png", "Tracking around the gust (seed 0; paper Fig. 6)"
        )
    )
    if "adrc" in series:
        title = "ADRC extended state observers around the gust (seed 0; paper Fig. 7)"
        paths.append(eso_figure(series["adrc"], gust, out_dir / "control_eso.png", title))

    # Figure 10: flown tracks over the planned route, with a zoom on a turn
    waypoints = np.asarray([*scenario.waypoints_ne, [0.0, 0.0]])
    fig, (ax, zoom) = plt.subplots(1, 2, figsize=(13, 6))
    corner = waypoints[min(7, len(waypoints) - 2)]  # the paper zooms on its 7th, 9th and 12th buoys
    for a in (ax, zoom):
        a.plot(waypoints[:, 1], waypoints[:, 0], "b-", lw=1, label="planned route")
        a.plot(waypoints[1:-1, 1], waypoints[1:-1, 0], "o", mfc="none", color="tab:red", label="buoys")
        for kind, s in series.items():
            a.plot(s["y"], s["x"], color=colours[kind], lw=0.8, label=LABELS[kind])
    for i, (n, e) in enumerate(waypoints[1:-1], start=1):
        ax.annotate(str(i), (e, n), fontsize=7)
    ax.set_aspect("equal")
    ax.set_xlabel("east (m)")
    ax.set_ylabel("north (m)")
    ax.legend(fontsize=7)
    zoom.set_xlim(corner[1] - 6, corner[1] + 6)
    zoom.set_ylim(corner[0] - 6, corner[0] + 6)
    zoom.set_aspect("equal")
    zoom.set_title("zoom: 7th buoy")
    zoom.set_xlabel("east (m)")
    fig.suptitle("Flown tracks over the planned route (seed 0; paper Fig. 10)")
    paths.append(_save(fig, out_dir / "control_tracks.png"))

    # Figure 11: yaw desired vs actual at the 7th, 9th and 12th buoys
    fig, axes = plt.subplots(1, 3, figsize=(13, 4))
    for ax, buoy in zip(axes, (7, 9, 12), strict=True):
        for kind, s in series.items():
            seq = s["seq"][1:]
            t = since_takeoff(s)
            at = np.flatnonzero((seq == FIRST_BUOY_SEQ + buoy) & (np.abs(s["yaw_rate_ref"][1:]) > 1e-3))
            if at.size == 0:
                continue
            w = (t >= t[at[0]] - 1) & (t <= t[at[-1]] + 3)
            ax.plot(t[w], np.degrees(np.unwrap(s["yaw"][:-1][w])), color=colours[kind], label=LABELS[kind])
            if kind == "adrc":
                ax.plot(t[w], np.degrees(np.unwrap(s["yaw_ref"][1:][w])), "b:", label="desired")
        ax.set_title(f"turn at buoy {buoy} (toward buoy {buoy + 1})")
        ax.set_xlabel("time since takeoff (s)")
    axes[0].set_ylabel("yaw (deg)")
    axes[0].legend(fontsize=7)
    fig.suptitle("Yaw at the turns (seed 0; paper Fig. 11)")
    paths.append(_save(fig, out_dir / "control_yaw_turns.png"))

    # step responses
    if steps:
        fig, ax = plt.subplots(figsize=(8, 4))
        for kind, trace in steps.items():
            ax.plot(trace[:, 0], trace[:, 1], color=colours[kind], label=LABELS[kind])
        ax.axhline(STEP_M, color="b", ls=":")
        ax.set_xlabel("time since the step (s)")
        ax.set_ylabel("east (m)")
        ax.legend(fontsize=7)
        ax.set_title(f"{STEP_M:g} m lateral position step at hover (seed 0)")
        paths.append(_save(fig, out_dir / "control_step.png"))
    return paths


def _save(fig, path: Path) -> str:
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    import matplotlib.pyplot as plt

    plt.close(fig)
    path = path.resolve()
    return str(path.relative_to(REPO) if path.is_relative_to(REPO) else path)


# ----- the paper's Figures 6, 7 and 9 complete (bench/paper_figures.py draws them; draw_figures above too)
COLOURS = {
    "adrc": "tab:green",
    "adrc_paper": "tab:olive",
    "pid": "tab:red",
    "geometric": "tab:orange",
    "px4": "tab:purple",
}
SHORT = {
    "adrc": "ADRC",
    "adrc_paper": "ADRC (paper's form)",
    "pid": "PID",
    "geometric": "geometric",
    "px4": "PX4 defaults",
}


def mission_time(s: dict[str, np.ndarray]) -> np.ndarray:
    """Each tick's end on the disturbance clock (seconds since the mission start command, where the wind's and
    the gust's times count): the first recorded tick ends one outer period after the start."""
    return s["t"] - s["t"][0] + 1.0 / OUTER_RATE_HZ


def _mark_onset(ax, onset: tuple[float, float], label: bool = False) -> None:
    """Shade the disturbance (start, end) and draw its onset."""
    ax.axvspan(*onset, color="0.85", zorder=0, label="disturbance (wind change)" if label else None)
    ax.axvline(onset[0], color="k", lw=0.8, ls="--", zorder=1)


def tracking_figure(
    series: dict[str, dict[str, np.ndarray]],
    onset: tuple[float, float],
    path: Path,
    title: str,
    before_s: float = 2.0,
    after_s: float = 8.0,
) -> str:
    """Fig. 6: altitude, yaw, pitch and roll, the reference against each controller's output, in a window
    around the disturbance onset; a fifth panel gives the horizontal tracking error. The attitude references
    are what each outer loop asked its attitude loop for (the ADRC's and the PID's differ), drawn dashed in
    the controller's colour; altitude and yaw share one reference (the navigator's), drawn in blue."""
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(5, 1, figsize=(10, 12), sharex=True)
    reference_drawn = False
    for kind, s in series.items():
        # as metrics.flight_metrics: the truth at the start of tick k (the end of tick k - 1) against the
        # reference computed for that instant (row k); the attitude target of row k acts during tick k
        t = mission_time(s)[:-1]
        w = (t >= onset[0] - before_s) & (t <= onset[0] + after_s)
        colour, name = COLOURS.get(kind, "k"), SHORT.get(kind, kind)
        if not reference_drawn:  # the navigator's reference, the same for every controller
            axes[0].plot(t[w], -s["z_ref"][1:][w], "b:", lw=1.5, label="input reference")
            axes[1].plot(t[w], np.degrees(np.unwrap(s["yaw_ref"])[1:][w]), "b:", lw=1.5, label="input reference")
            reference_drawn = True
        axes[0].plot(t[w], -s["z"][:-1][w], color=colour, label=f"{name} output")
        # yaw near the reference: the reference unwrapped plus the output's error to it taken the short way
        yaw_ref = np.unwrap(s["yaw_ref"])[1:]
        yaw = yaw_ref + (s["att_yaw"][:-1] - yaw_ref + math.pi) % (2 * math.pi) - math.pi
        axes[1].plot(t[w], np.degrees(yaw[w]), color=colour, label=f"{name} output")
        for ax, axis in ((axes[2], "pitch"), (axes[3], "roll")):
            target = np.degrees(s[f"att_ref_{axis}"][1:][w])
            ax.plot(t[w], target, color=colour, ls="--", lw=1, label=f"{name} reference")
            ax.plot(t[w], np.degrees(s[f"att_{axis}"][:-1][w]), color=colour, label=f"{name} output")
        error = np.hypot(s["x"][:-1] - s["x_ref"][1:], s["y"][:-1] - s["y_ref"][1:])
        axes[4].plot(t[w], error[w], color=colour, label=name)
    labels = ("altitude (m)", "yaw angle (deg)", "pitch angle (deg)", "roll angle (deg)", "horizontal error (m)")
    for i, (ax, label) in enumerate(zip(axes, labels, strict=True)):
        _mark_onset(ax, onset, label=i == 0)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="upper right", ncol=2)
    axes[-1].set_xlabel(f"time since the mission start (s); disturbance from {onset[0]:.2f} s to {onset[1]:.2f} s")
    fig.suptitle(title)
    return _save(fig, path)


def _window(t: np.ndarray, onset: tuple[float, float], before_s: float, after_s: float) -> np.ndarray:
    return (t >= onset[0] - before_s) & (t <= onset[0] + after_s)


def eso_figure(
    s: dict[str, np.ndarray],
    onset: tuple[float, float],
    path: Path,
    title: str,
    before_s: float = 2.0,
    after_s: float = 8.0,
) -> str:
    """Fig. 7 for one ADRC flight: every ESO's z1, z2, z3 against what it estimates, columns the outer loop's
    north, east, down channels and the inner loop's roll, pitch, yaw. z1 is shown as its error (the signals
    are ramps at 10 m/s or gyro-integrated angles); z2 against the true velocity or body rate; z3 against the
    true disturbance: for the outer loop the simulator's external acceleration (drag + D terms), for the
    inner loop the true total disturbance of the channel's model (FlightRecorder's if_*) and its external part
    (gyroscopic coupling + D terms). The outer ESO's states at tick k describe the tick's start (the truth
    recorded at the end of tick k-1: see metrics.eso_errors); the inner ESO's are sampled at the end of the
    outer tick, the last of its five 250 Hz steps."""
    import matplotlib.pyplot as plt

    dt = 1.0 / OUTER_RATE_HZ
    t_end = mission_time(s)  # the end of each tick: where the truth and the inner ESO's samples are
    t_start = t_end - dt  # the outer ESO's estimate at tick k is for the tick's start
    fig, axes = plt.subplots(3, 6, figsize=(22, 10), sharex=True)
    names = {"x": "outer: north (x)", "y": "outer: east (y)", "z": "outer: down (z)"}
    for col, axis in enumerate("xyz"):
        w = _window(t_start, onset, before_s, after_s)
        we = _window(t_end, onset, before_s, after_s)
        truth_pos = np.concatenate([[np.nan], s[axis][:-1]])
        truth_vel = np.concatenate([[np.nan], s[f"v{axis}"][:-1]])
        axes[0, col].plot(t_start[w], (s[f"z1_{axis}"] - truth_pos)[w], color="tab:blue", label="z1 - true position")
        axes[1, col].plot(t_start[w], truth_vel[w], "k", lw=2, alpha=0.5, label="true velocity")
        axes[1, col].plot(t_start[w], s[f"z2_{axis}"][w], color="tab:green", label="z2 (velocity estimate)")
        axes[2, col].plot(t_end[we], s[f"ext_{axis}"][we], "k", lw=2, alpha=0.5, label="true external acceleration")
        axes[2, col].plot(t_start[w], s[f"z3_{axis}"][w], color="tab:red", lw=1, label="z3 (total disturbance)")
        axes[0, col].set_title(names[axis])
    for col, axis in enumerate(("roll", "pitch", "yaw"), start=3):
        w = _window(t_end, onset, before_s, after_s)
        axes[0, col].plot(
            t_end[w], np.degrees(s[f"iz1_{axis}"] - s[f"itheta_{axis}"])[w], color="tab:blue", label="z1 - theta"
        )
        axes[1, col].plot(t_end[w], np.degrees(s[f"rate_{axis}"])[w], "k", lw=2, alpha=0.5, label="true body rate")
        axes[1, col].plot(t_end[w], np.degrees(s[f"iz2_{axis}"])[w], color="tab:green", label="z2 (rate estimate)")
        axes[2, col].plot(t_end[w], s[f"if_{axis}"][w], "k", lw=2, alpha=0.5, label="true total disturbance")
        axes[2, col].plot(t_end[w], s[f"iext_{axis}"][w], color="tab:orange", lw=1, label="its external part")
        axes[2, col].plot(t_end[w], s[f"iz3_{axis}"][w], color="tab:red", lw=1, label="z3 (total disturbance)")
        axes[0, col].set_title(f"inner: {axis}")
    for col in range(6):
        for row in range(3):
            _mark_onset(axes[row, col], onset)
            axes[row, col].grid(alpha=0.3)
            axes[row, col].legend(fontsize=7, loc="upper right")
        axes[2, col].set_xlabel("time since the mission start (s)")
    axes[0, 0].set_ylabel("z1 error (m)")
    axes[1, 0].set_ylabel("velocity (m/s)")
    axes[2, 0].set_ylabel("acceleration (m/s^2)")
    axes[0, 3].set_ylabel("z1 error (deg)")
    axes[1, 3].set_ylabel("body rate (deg/s)")
    axes[2, 3].set_ylabel("angular acceleration (rad/s^2)")
    fig.suptitle(title)
    return _save(fig, path)


def route_figure(
    scenario: Scenario,
    series: dict[str, dict[str, np.ndarray]],
    ga: dict,
    onset_s: float,
    path: Path,
    title: str,
) -> str:
    """Fig. 9: (a) the buoys, the planned (desired) route and the flown (effective) tracks, with the CHNN-GA
    route's waypoints as stars; (b) the flown tracks' deviation from the planned leg around the disturbance
    (at 10 m/s a map zoom cannot show a 0.2 m deviation); (c) the CHNN-GA's solutions per
    genetic iteration: every feasible tour of the population and every child (blue), the best so far (red),
    generation 0's CHNN outputs as decoded (before the local-search repair), the optimum and the input order.

    ga: {"points_ne": (n, 2) depot then buoys, "order": the CHNN-GA's order (node 0 first), "length",
    "history": chnn_ga's history, "optimum_m", "input_order_m"}."""
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(17, 6.5))
    grid = fig.add_gridspec(1, 3, width_ratios=[1.3, 0.8, 1.1])
    ax, zoom, history_ax = (fig.add_subplot(grid[0, i]) for i in range(3))
    planned = np.asarray([*scenario.waypoints_ne, [0.0, 0.0]])
    points = np.asarray(ga["points_ne"])
    ga_route = points[[*ga["order"], ga["order"][0]]]
    for a in (ax,):
        a.plot(planned[:, 1], planned[:, 0], "b-", lw=1.2, label="desired trajectory (planned route)")
        a.plot(ga_route[:, 1], ga_route[:, 0], "*", color="tab:blue", ms=9, label="CHNN-GA solution (waypoints)")
        a.plot(points[1:, 1], points[1:, 0], "o", mfc="none", mec="red", ms=10, mew=1.5, label="buoys")
        a.plot(0.0, 0.0, "ks", ms=7, label="depot")
        for kind, s in series.items():
            a.plot(s["y"], s["x"], color=COLOURS.get(kind, "k"), lw=0.9, label=f"effective trajectory, {SHORT[kind]}")
            t = mission_time(s)
            at = int(np.searchsorted(t, onset_s))
            if at < t.size:
                a.plot(s["y"][at], s["x"][at], "^", color=COLOURS.get(kind, "k"), ms=8)
    for i, (n, e) in enumerate(scenario.waypoints_ne[1:], start=1):
        ax.annotate(str(i), (e, n), textcoords="offset points", xytext=(6, 6), fontsize=8)
    ax.set_aspect("equal")
    ax.set_xlabel("east (m)")
    ax.set_ylabel("north (m)")
    ax.set_title(f"(a) route {scenario.route_length_m:.1f} m; triangles: where the disturbance began")
    ax.legend(fontsize=7, loc="best")
    _cross_track_panel(zoom, planned, series, onset_s)

    history = ga["history"]
    first = history[0] if history else {}
    chnn = first.get("chnn_lengths", [])
    if chnn:
        history_ax.plot(
            np.full(len(chnn), -0.25), chnn, "x", color="0.4", label="CHNN outputs, before repair (generation 0)"
        )
    feasible_label, best_label = "feasible solutions (population, children)", "optimal solution so far"
    for h in history:
        g = h["generation"]
        lengths = [*h.get("lengths", []), *h.get("child_lengths", [])]
        history_ax.plot(np.full(len(lengths), g), lengths, "*", color="tab:blue", ms=9, label=feasible_label)
        history_ax.plot(g + 0.15, h["best_length"], "*", color="red", ms=11, label=best_label)
        feasible_label = best_label = None
    history_ax.axhline(ga["optimum_m"], color="tab:green", ls="--", lw=1, label=f"optimum {ga['optimum_m']:.1f} m")
    history_ax.axhline(ga["input_order_m"], color="0.5", ls=":", lw=1, label=f"input order {ga['input_order_m']:.0f} m")
    history_ax.set_xlabel("genetic iteration (generation)")
    history_ax.set_ylabel("route length (m)")
    history_ax.set_title(f"(c) CHNN-GA per iteration: {ga['length']:.1f} m after {len(history) - 1} generations")
    history_ax.legend(fontsize=7, loc="upper right")
    history_ax.grid(alpha=0.3)
    fig.suptitle(title)
    return _save(fig, path)


def _cross_track_panel(ax, planned: np.ndarray, series: dict[str, dict[str, np.ndarray]], onset_s: float) -> None:
    """Each track's signed distance from the planned leg it is on at the disturbance onset (positive to the
    leg's right), against the distance along that leg, 60 m before to 120 m after the onset's point."""
    leg = None
    for kind, s in series.items():
        t = mission_time(s)
        at = int(np.searchsorted(t, onset_s))
        if at >= t.size:
            continue
        here = np.array([s["x"][at], s["y"][at]])
        if leg is None:  # the planned leg nearest the first controller's position at the onset
            distances = [_segment_distance(here, planned[i], planned[i + 1]) for i in range(len(planned) - 1)]
            leg = int(np.argmin(distances))
            a, b = planned[leg], planned[leg + 1]
            along_unit = (b - a) / np.linalg.norm(b - a)
            right = np.array([-along_unit[1], along_unit[0]])  # NE frame: the right of the direction of travel
            along_onset = float((here - a) @ along_unit)
        rel = np.column_stack([s["x"], s["y"]]) - a
        along, across = rel @ along_unit, rel @ right
        w = (along >= along_onset - 60) & (along <= along_onset + 120) & (np.abs(across) < 5)
        w &= (t > t[at] - 30) & (t < t[at] + 30)  # this pass along the leg only
        colour = COLOURS.get(kind, "k")
        ax.plot(along[w] - along_onset, across[w], color=colour, label=f"effective trajectory, {SHORT[kind]}")
        ax.plot(along[at] - along_onset, across[at], "^", color=colour, ms=8)
    ax.axhline(0.0, color="b", lw=1.2, label="desired trajectory (planned leg)")
    ax.axvline(0.0, color="k", lw=0.8, ls="--", label="disturbance onset")
    ax.set_xlabel("distance along the leg from the onset point (m)")
    ax.set_ylabel("cross-track deviation, + right of travel (m)")
    title = "(b) deviation from the planned leg" + (f" {leg + 1} (to buoy {leg + 1})" if leg is not None else "")
    ax.set_title(title)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="upper right")


def _segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    ab = b - a
    u = float(np.clip((p - a) @ ab / max(float(ab @ ab), 1e-12), 0.0, 1.0))
    return float(np.linalg.norm(p - (a + u * ab)))
