"""The import contracts in pyproject.toml hold, catch each of the cross-imports the layering removed, and cover
every module (a new module must be classified as pure computation or as I/O before it lands)."""

from __future__ import annotations

import pkgutil
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
PACKAGES = ("uavcore", "planner", "adrc_offboard", "sitl_quad", "gcs", "stack")
LINT_IMPORTS = Path(sys.executable).with_name("lint-imports")

# Modules that do I/O on purpose (MAVLink, sockets, HTTP, files, processes): everything else must be listed in
# the "pure-computation" contract.
IO_MODULES = {
    "uavcore.mavlink",
    "adrc_offboard.cli",
    "adrc_offboard.node",
    "adrc_offboard.__main__",
    "sitl_quad.ais_out",
    "sitl_quad.cli",
    "sitl_quad.server",
    "sitl_quad.flight_logs",  # writes the ULog files (sitl_quad.ulog encodes them, pure)
    "sitl_quad.lockstep_harness",
    "sitl_quad.__main__",
    "planner.__main__",
}
IO_PACKAGES = ("gcs", "sitl_quad.mavlink", "stack")


def _contracts() -> dict[str, dict]:
    config = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["importlinter"]
    return {contract["id"]: contract for contract in config["contracts"]}


def _lint_imports(root: Path) -> subprocess.CompletedProcess:
    return subprocess.run(
        [str(LINT_IMPORTS), "--config", str(root / "pyproject.toml"), "--no-cache"],
        cwd=root,
        env={"PYTHONPATH": str(root), "PATH": "/usr/bin:/bin"},
        capture_output=True,
        text=True,
        timeout=120,
    )


@pytest.mark.integration  # runs lint-imports
def test_the_repository_keeps_every_contract():
    result = _lint_imports(REPO)
    assert result.returncode == 0, result.stdout + result.stderr
    assert "0 broken" in result.stdout


# Each of the cross-imports the vocabulary move removed, put back into a copy of the tree.
VIOLATIONS = [
    ("gcs/domain/planning.py", "from sitl_quad.mavlink import mission", "The ground station needs neither"),
    ("adrc_offboard/outer_loop.py", "import sitl_quad.vehicle", "Layers"),
    ("sitl_quad/vehicle.py", "from adrc_offboard import adrc_attitude", "The vehicle is given its controllers"),
    ("sitl_quad/navigator.py", "import planner.scenario", "The vehicle is given its controllers"),
    ("uavcore/state.py", "import gcs.settings", "Layers"),
    ("gcs/api/app.py", "import stack.up", "Layers"),  # the ground station starts no vehicle: the launcher sits above it
    # inside the ground station: the vocabulary needs no storage, storage no reports, the vehicle link no missions
    ("gcs/domain/status.py", "import gcs.storage", "Ground station"),
    ("gcs/storage/base.py", "from gcs.reports import views", "Ground station"),
    ("gcs/vehicle/link.py", "from gcs.missions import lifecycle", "Ground station"),
    ("gcs/reports/report.py", "from gcs.vehicle import link", "Ground station"),  # reports and the link: siblings
    ("gcs/charts.py", "from gcs.vehicle import link", "Ground station"),  # the chart reader and the link too
    ("gcs/domain/charted_marks.py", "import gcs.charts", "Ground station"),  # the mapping is pure: no reading
    ("sitl_quad/wind.py", "import socket", "Pure computation"),
    ("adrc_offboard/adrc.py", "from uavcore.mavlink import mavlink", "Pure computation"),
]


@pytest.mark.integration  # runs lint-imports on a copy of the tree
@pytest.mark.parametrize(("path", "line", "contract"), VIOLATIONS, ids=[v[0] + ":" + v[1] for v in VIOLATIONS])
def test_a_cross_import_breaks_its_contract(tmp_path, path, line, contract):
    for package in PACKAGES:
        shutil.copytree(REPO / package, tmp_path / package, ignore=shutil.ignore_patterns("__pycache__", "web"))
    shutil.copy(REPO / "pyproject.toml", tmp_path / "pyproject.toml")
    target = tmp_path / path
    target.write_text(f"{line}  # injected by the test\n" + target.read_text())
    result = _lint_imports(tmp_path)
    assert result.returncode != 0, result.stdout
    broken = [block for block in result.stdout.split("\n\n") if "BROKEN" in block]
    assert any(contract in block for block in broken), result.stdout


def _all_modules(package: str) -> set[str]:
    root = REPO / package.replace(".", "/")
    modules = {package}
    for info in pkgutil.walk_packages([str(root)], prefix=package + "."):
        modules.add(info.name)
    return modules


def test_every_module_is_classified_as_pure_or_io():
    pure = _contracts()["pure-computation"]["source_modules"]

    def covered(module: str) -> bool:
        return (
            any(module == p or module.startswith(p + ".") for p in pure)
            or module in IO_MODULES
            or any(module == p or module.startswith(p + ".") for p in IO_PACKAGES)
        )

    unclassified = sorted(
        m
        for package in PACKAGES
        for m in _all_modules(package)
        if not covered(m) and "." in m  # packages' __init__
    )
    assert not unclassified, f"classify these in pyproject's pure-computation contract or in IO_MODULES: {unclassified}"
