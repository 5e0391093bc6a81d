"""Route drawings in the style of the paper's Figure 8: buoys, depot, the closed tour, its length."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")  # files only; never a window
import matplotlib.pyplot as plt
import numpy as np


def draw_route(ax, points: np.ndarray, order, title: str, unit: str = "m") -> None:
    """Draw one closed tour on a matplotlib axis: red circles for buoys, a square for the depot."""
    points = np.asarray(points, dtype=float)
    closed = np.asarray([*order, order[0]])
    ax.plot(points[closed, 0], points[closed, 1], "-", color="tab:blue", lw=1.5, zorder=1)
    ax.scatter(points[1:, 0], points[1:, 1], s=40, facecolors="none", edgecolors="red", zorder=2, label="buoy")
    ax.scatter(points[:1, 0], points[:1, 1], s=70, marker="s", color="black", zorder=3, label="depot")
    for rank, node in enumerate(order[1:], start=1):  # label = visiting rank
        ax.annotate(str(rank), points[node], textcoords="offset points", xytext=(4, 4), fontsize=7)
    ax.set_title(title, fontsize=9)
    ax.set_xlabel(f"x ({unit})")
    ax.set_ylabel(f"y ({unit})")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, alpha=0.3)


def save_route_png(path: str, points: np.ndarray, order, length: float, method: str, unit: str = "m") -> None:
    """One route, as a PNG file."""
    fig, ax = plt.subplots(figsize=(7, 5))
    draw_route(ax, points, order, f"{method}: closed tour {length:.1f} {unit}, {len(order)} nodes", unit)
    ax.legend(loc="best", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
