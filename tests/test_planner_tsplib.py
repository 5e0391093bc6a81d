"""TSPLIB parsing and distance functions: the published optimal tours have exactly the published lengths."""

from pathlib import Path

import numpy as np
import pytest

from planner.distances import closed_tour_length
from planner.errors import InputError
from planner.tsplib import parse_tour, parse_tsp, tsplib_distance_matrix

TSPLIB = Path(__file__).resolve().parent / "data" / "tsplib"  # TSPLIB95 instances, see its README.md


def optima() -> dict[str, int]:
    rows = [
        line.split()
        for line in (TSPLIB / "OPTIMA.txt").read_text().splitlines()
        if line.strip() and not line.startswith("#")
    ]
    return {name: int(value) for name, value in rows}


@pytest.mark.parametrize("name", ["burma14", "ulysses16", "ulysses22", "eil51", "berlin52", "st70"])
def test_the_optimal_tour_has_the_published_length(name):
    instance = parse_tsp((TSPLIB / f"{name}.tsp").read_text())
    order = parse_tour((TSPLIB / f"{name}.opt.tour").read_text())
    assert sorted(order) == list(range(len(instance.coords)))
    assert closed_tour_length(order, instance.distance_matrix()) == optima()[name]


def test_euc_2d_rounds_to_nearest_and_ceil_2d_rounds_up():
    coords = np.array([[0.0, 0.0], [3.0, 4.2], [1.0, 1.0]])
    euc = tsplib_distance_matrix(coords, "EUC_2D")
    ceil = tsplib_distance_matrix(coords, "CEIL_2D")
    assert euc[0, 1] == 5.0 and ceil[0, 1] == 6.0  # sqrt(26.64) = 5.16
    assert euc[0, 2] == 1.0 and ceil[0, 2] == 2.0  # sqrt(2) = 1.41


def test_att_is_the_pseudo_euclidean_distance():
    # r = sqrt((dx^2 + dy^2) / 10); t = nint(r); d = t + 1 if t < r else t
    coords = np.array([[0.0, 0.0], [10.0, 0.0], [30.0, 40.0]])
    att = tsplib_distance_matrix(coords, "ATT")
    assert att[0, 1] == 4.0  # r = 3.162, t = 3 < r -> 4
    assert att[0, 2] == 16.0  # r = 15.811, t = 16 >= r -> 16
    assert att[1, 2] == 15.0  # r = sqrt(2000/10) = 14.142, t = 14 < r -> 15


def test_geo_reads_degrees_dot_minutes():
    # 0.30 is 30 minutes = 0.5 degree; along the equator 1 degree is about 111.3 km on TSPLIB's sphere
    coords = np.array([[0.0, 0.0], [0.0, 0.30], [0.0, 1.0]])
    geo = tsplib_distance_matrix(coords, "GEO")
    assert geo[0, 1] == 56.0
    assert geo[0, 2] == 112.0


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("NAME: x\nTYPE: TSP\nEDGE_WEIGHT_TYPE: EXPLICIT\nNODE_COORD_SECTION\n1 0 0\nEOF", "not supported"),
        ("NAME: x\nTYPE: ATSP\nEDGE_WEIGHT_TYPE: EUC_2D\nNODE_COORD_SECTION\n1 0 0\nEOF", "ATSP"),
        ("NAME: x\nTYPE: TSP\nEDGE_WEIGHT_TYPE: EUC_2D\nEOF", "no NODE_COORD_SECTION"),
        ("NAME: x\nEDGE_WEIGHT_TYPE: EUC_2D\nNODE_COORD_SECTION\n1 0 zero\nEOF", "not numbers"),
        ("NAME: x\nEDGE_WEIGHT_TYPE: EUC_2D\nNODE_COORD_SECTION\n1 0\nEOF", "index x y"),
        ("NAME: x\nEDGE_WEIGHT_TYPE: EUC_2D\nDIMENSION: 3\nNODE_COORD_SECTION\n1 0 0\n2 1 1\nEOF", "DIMENSION"),
        ("EDGE_WEIGHT_TYPE: EUC_2D\nEDGE_WEIGHT_SECTION\n0 1\nEOF", "not supported"),
        ("EDGE_WEIGHT_TYPE: EUC_2D\nNODE_COORD_SECTION\n1 0 nan\nEOF", "non-finite"),
    ],
)
def test_unusable_files_raise_input_error(text, message):
    with pytest.raises(InputError, match=message):
        parse_tsp(text)
