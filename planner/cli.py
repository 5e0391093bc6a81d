"""`python -m planner FILE` / `buoy-plan FILE`: plan a route from GeoJSON, CSV of lat,lon or TSPLIB `.tsp`.

GeoJSON and CSV positions are projected to the local tangent plane at the depot (uavcore.geodesy) and the
length is in metres. A TSPLIB file is planned on TSPLIB's own integer distances, so its length compares
exactly with the published optima. Exit status: 0 planned, 2 bad input or options, 1 could not write output.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from planner.errors import InputError, PlannerError
from planner.formats import parse_csv, parse_depot_option, parse_geojson
from planner.methods import METHODS
from planner.tsplib import parse_tsp
from uavcore.geodesy import LocalFrame

EXIT_INPUT = 2
EXIT_OUTPUT = 1


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="buoy-plan", description=__doc__.splitlines()[0])
    parser.add_argument("file", help="mission file: .geojson/.json, .csv (lat,lon) or TSPLIB .tsp")
    parser.add_argument(
        "--method",
        choices=METHODS,
        default="chnn-ga",
        help="chnn-ga (default), chnn (network alone), exact (Held-Karp, <= 16 nodes), "
        "auto (exact when it is fast, else chnn-ga)",
    )
    parser.add_argument("--seed", type=int, default=0, help="random seed (same seed, same route)")
    parser.add_argument(
        "--time-limit", type=float, default=2.0, metavar="SECONDS", help="planning time budget (default 2)"
    )
    parser.add_argument("--depot", metavar="LAT,LON", help="depot position; then every point in the file is a buoy")
    parser.add_argument("--json", action="store_true", help="print {order, length, method, elapsed_s}")
    parser.add_argument("--plot", metavar="FILE.png", help="draw the route (like the paper's Figure 8)")
    return parser


def load_mission(path: Path, depot_option: str | None) -> tuple[np.ndarray, np.ndarray | None, str]:
    """Read a mission file: (plot coordinates, distance matrix or None for Euclidean, length unit)."""
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read {path}: {exc}") from None
    suffix = path.suffix.lower()
    if suffix == ".tsp":
        if depot_option:
            raise InputError("--depot does not apply to a TSPLIB file (its node 1 is the start)")
        instance = parse_tsp(text)
        coords = instance.coords[:, ::-1] if instance.edge_weight_type == "GEO" else instance.coords
        return coords, instance.distance_matrix(), "units"
    depot = parse_depot_option(depot_option) if depot_option else None
    if suffix in (".geojson", ".json"):
        lat_lon = parse_geojson(text, depot)
    elif suffix == ".csv":
        lat_lon = parse_csv(text, depot)
    else:
        raise InputError(f"unknown file type {suffix or '(none)'}: use .geojson, .json, .csv or .tsp")
    frame = LocalFrame(float(lat_lon[0, 0]), float(lat_lon[0, 1]))
    return frame.project(lat_lon), None, "m"


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    try:
        points, distance, unit = load_mission(Path(args.file), args.depot)
        from planner.tour import plan_tour  # the solvers (and numba) load only once the input is good

        if distance is not None:
            result = plan_tour(
                None, method=args.method, seed=args.seed, time_limit_s=args.time_limit, distance=distance
            )
        else:
            result = plan_tour(points, method=args.method, seed=args.seed, time_limit_s=args.time_limit)
    except PlannerError as exc:
        print(f"buoy-plan: error: {exc}", file=sys.stderr)
        return EXIT_INPUT
    length = round(result.length) if distance is not None else result.length
    if args.plot:
        from planner.plot import save_route_png  # matplotlib only when a plot is asked for

        try:
            save_route_png(args.plot, points, result.order, result.length, result.method, unit)
        except OSError as exc:
            print(f"buoy-plan: error: cannot write {args.plot}: {exc}", file=sys.stderr)
            return EXIT_OUTPUT
    if args.json:
        print(
            json.dumps(
                {
                    "order": result.order,
                    "length": length,
                    "method": result.method,
                    "elapsed_s": round(result.elapsed_s, 6),
                }
            )
        )
    else:
        print(
            f"{len(result.order)} nodes (depot + {len(result.order) - 1} buoys), {result.method}, "
            f"{result.elapsed_s:.3f} s: closed tour {result.length:.1f} {unit}"
        )
        print("order: " + " ".join(map(str, [*result.order, result.order[0]])))
        if args.plot:
            print(f"route drawn in {args.plot}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
