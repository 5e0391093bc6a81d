"""What the reports draw with (gcs.reports.report, gcs.reports.fleet_report): matplotlib figures through its object API
(no pyplot state, so reports can be drawn from worker threads), the sorties' colours and dashes, the page style, and a
column of stored samples as an array."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:  # matplotlib is imported when a report is drawn, not with the service
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

DPI = 110
SORTIE_COLOURS = ("#0072b2", "#e69f00", "#009e73", "#cc79a7", "#d55e00", "#56b4e9")
SORTIE_DASHES = ((0, (5, 3)), (0, (1, 3)), (0, (7, 2, 1, 2)))


def column(samples: list[dict[str, Any]], name: str) -> np.ndarray:
    """One field of the samples as floats (NaN where a sample has none)."""
    return np.array([np.nan if s.get(name) is None else float(s[name]) for s in samples], dtype=float)


def new_figure(height: float = 3.2) -> tuple[Figure, Axes]:
    """A report figure (9 in wide, `height` in high) and its one axes."""
    from matplotlib.figure import Figure

    figure = Figure(figsize=(9, height), dpi=DPI, layout="constrained")
    return figure, figure.add_subplot()


def save_figure(figure: Figure, path: Path) -> None:
    """Draw `figure` to a PNG at `path` (the Agg canvas: no display, no pyplot)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    FigureCanvasAgg(figure)
    figure.savefig(path)


def sortie_style(sortie: int) -> dict[str, Any]:
    """Sortie k's line colour and dash (matplotlib keywords)."""
    return {
        "color": SORTIE_COLOURS[sortie % len(SORTIE_COLOURS)],
        "linestyle": SORTIE_DASHES[sortie // len(SORTIE_COLOURS) % len(SORTIE_DASHES)],
    }


# The report's only inline content: the service's Content-Security-Policy allows it by its hash
# (gcs.api.http_headers); the page has no script. Every text from the mission goes through html.escape. The sortie
# table's swatches are classes (.sortie-k), since a style attribute would need the policy to allow it too.
REPORT_STYLE = (
    "body{font-family:sans-serif;max-width:1000px;margin:1em auto} table{border-collapse:collapse}\n"
    "th,td{border:1px solid #ccc;padding:2px 8px;text-align:left} img{max-width:100%}\n"
    ".swatch{display:inline-block;width:1.5em;height:.6em;margin-right:.4em}\n"
    + "\n".join(f".sortie-{k}{{background:{colour}}}" for k, colour in enumerate(SORTIE_COLOURS))
)
