"""The paper's figures drawn from seed 0 of each controller: tracking around the gust (Fig. 6), the ESO's
estimates against the truth (Fig. 7), the flown tracks over the planned route (Fig. 10), yaw at the turns
(Fig. 11), and the step responses."""

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

    colours = {"adrc": "tab:green", "pid": "tab:red", "px4": "tab:purple", "geometric": "tab:orange"}
    paths = []
    t_gust = scenario.wind.gust_start_s

    def since_takeoff(s):
        return s["t"][1:] - s["t"][0]

    # Figure 6: x, y, z, yaw around the gust
    fig, axes = plt.subplots(4, 1, figsize=(9, 10), sharex=True)
    for kind, s in series.items():
        t = since_takeoff(s)
        w = (t >= t_gust - 2) & (t <= t_gust + 8)
        for ax, (name, ref, scale) in zip(
            axes,
            (("x", "x_ref", 1), ("y", "y_ref", 1), ("z", "z_ref", -1), ("yaw", "yaw_ref", 180 / math.pi)),
            strict=True,
        ):
            if name in ("x", "y"):  # at 10 m/s the positions are straight lines: show the error instead
                ax.plot(t[w], (s[name][:-1] - s[ref][1:])[w], color=colours[kind], label=LABELS[kind])
                continue
            ax.plot(t[w], s[name][:-1][w] * scale, color=colours[kind], label=LABELS[kind])
            if kind == "adrc":
                ax.plot(t[w], s[ref][1:][w] * scale, "b:", label="reference")
    for ax, label in zip(
        axes, ("north error x - x_ref (m)", "east error y - y_ref (m)", "altitude (m)", "yaw (deg)"), strict=True
    ):
        ax.set_ylabel(label)
        ax.axvspan(t_gust, t_gust + scenario.wind.gust_rise_time_s, color="0.9")
    axes[0].legend(fontsize=7)
    axes[-1].set_xlabel(f"time since takeoff (s); gust onset {t_gust:g} s (shaded: rise)")
    fig.suptitle("Tracking around the gust (seed 0; paper Fig. 6)")
    paths.append(_save(fig, out_dir / "control_gust_tracking.png"))

    # Figure 7: ESO outputs (ADRC) in the gust window against the true disturbance
    if "adrc" in series:
        s = series["adrc"]
        # tick k ends at t[k] = t[0] + k dt on a clock that starts dt before t[0] (the mission start);
        # z at tick k is the ESO's estimate for t_k, the start of tick k (see eso_errors)
        t = s["t"] - s["t"][0]
        w = (t >= t_gust - 2) & (t <= t_gust + 8)
        fig, axes = plt.subplots(3, 2, figsize=(11, 8), sharex=True)
        ext_t = s["t"] - s["t"][0] + 1.0 / OUTER_RATE_HZ  # reported at the end of its tick
        we = (ext_t >= t_gust - 2) & (ext_t <= t_gust + 8)
        for col, axis in enumerate(("x", "y")):
            # z at tick k describes t_k = the truth recorded at the end of tick k-1
            truth_pos = np.concatenate([[np.nan], s[axis][:-1]])
            truth_vel = np.concatenate([[np.nan], s[f"v{axis}"][:-1]])
            axes[0, col].plot(t[w], (s[f"z1_{axis}"] - truth_pos)[w], label="z1 - true position")
            axes[1, col].plot(t[w], truth_vel[w], "k:", label="true velocity")
            axes[1, col].plot(t[w], s[f"z2_{axis}"][w], "g", label="z2 (velocity estimate)")
            axes[2, col].plot(ext_t[we], s[f"ext_{axis}"][we], color="0.6", label="true external acceleration")
            axes[2, col].plot(t[w], s[f"z3_{axis}"][w], "r", label="z3 (total disturbance estimate)")
            axes[0, col].set_title(f"{'north' if axis == 'x' else 'east'} channel")
            for ax in axes[:, col]:
                ax.axvspan(t_gust, t_gust + scenario.wind.gust_rise_time_s, color="0.9")
                ax.legend(fontsize=7)
        axes[0, 0].set_ylabel("m")
        axes[1, 0].set_ylabel("m/s")
        axes[2, 0].set_ylabel("m/s^2")
        for ax in axes[-1]:
            ax.set_xlabel("time since takeoff (s)")
        fig.suptitle("ADRC extended state observer around the gust (seed 0; paper Fig. 7)")
        paths.append(_save(fig, out_dir / "control_eso.png"))

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
