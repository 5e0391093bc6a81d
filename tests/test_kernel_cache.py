"""uavcore.kernel_cache: a cached kernel is compiled afresh when a module it imports from the project changes, and
loaded from the cache when nothing did. Each run is a fresh Python process, as a vehicle or a service started
after a `git pull` is."""

from __future__ import annotations

import ast
import os
import subprocess
import sys
from pathlib import Path

import pytest

from uavcore.kernel_cache import PACKAGES, ROOT, closure_digest, import_statements, imported_modules, source_closure

REPO = Path(__file__).resolve().parents[1]

CALLEE = """
from numba import njit

SCALE = {scale}


@njit(cache=True)
def scaled(x):
    return x * SCALE
"""

# probe_kernels.caller's kernel calls probe_kernels.callee's: numba compiles the callee, and its constant, into it
CALLER = """
from probe_kernels.callee import scaled
{decorator_import}


@{decorator}
def plus_one(x):
    return scaled(x) + 1
"""

# Runs in the child: the kernel module found under the temporary root, the project's locators told that root is
# the project's (as the repository's own directory is to the real kernels), and numba's cache events reported.
RUN = """
import sys
sys.path.insert(0, sys.argv[1])
from pathlib import Path
from uavcore import kernel_cache
kernel_cache.ROOT = Path(sys.argv[1]).resolve()
kernel_cache.PACKAGES = ("probe_kernels",)
from probe_kernels.caller import plus_one
print(plus_one(1))
print(sum(plus_one.stats.cache_hits.values()), sum(plus_one.stats.cache_misses.values()))
"""


def write_probe(root: Path, scale: int, decorator: str) -> None:
    package = root / "probe_kernels"
    package.mkdir(parents=True, exist_ok=True)
    (package / "__init__.py").write_text("")
    (package / "callee.py").write_text(CALLEE.format(scale=scale))
    imports = {
        "njit(cache=True)": "from numba import njit",
        "cached_kernel": "from uavcore.kernel_cache import cached_kernel",
    }
    (package / "caller.py").write_text(CALLER.format(decorator=decorator, decorator_import=imports[decorator]))


def run(root: Path) -> tuple[int, int, int]:
    """plus_one(1) in a fresh process, and how often its dispatcher hit and missed the on-disk cache."""
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    env.pop("NUMBA_CACHE_DIR", None)  # the in-tree cache beside the probe's sources
    out = subprocess.run([sys.executable, "-c", RUN, str(root)], env=env, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    first, counts = out.stdout.splitlines()
    hits, misses = map(int, counts.split())
    return int(first), hits, misses


@pytest.mark.slow
def test_numbas_own_cache_runs_a_changed_callee_stale_and_the_projects_compiles_it_afresh(tmp_path):
    """The failure this module mends, shown with numba's own njit(cache=True); then the same change with
    cached_kernel: the new constant is used, and an unchanged tree loads the kernel from the cache."""
    stale, fresh = tmp_path / "numba", tmp_path / "project"
    write_probe(stale, 2, "njit(cache=True)")
    assert run(stale) == (3, 0, 1)  # compiled, then saved
    write_probe(stale, 5, "njit(cache=True)")
    assert run(stale) == (3, 1, 0)  # loaded from the cache: 1 * 2 + 1, the old SCALE

    write_probe(fresh, 2, "cached_kernel")
    assert run(fresh) == (3, 0, 1)
    assert run(fresh) == (3, 1, 0)  # nothing changed: loaded
    write_probe(fresh, 5, "cached_kernel")
    assert run(fresh) == (6, 0, 1)  # the callee changed: compiled afresh, 1 * 5 + 1
    assert run(fresh) == (6, 1, 0)


def test_the_closure_follows_project_imports_and_the_digest_moves_with_any_of_them(tmp_path):
    write_probe(tmp_path, 2, "cached_kernel")
    package = tmp_path / "probe_kernels"
    caller = package / "caller.py"
    closure = source_closure(caller, tmp_path, ("probe_kernels",))
    assert closure == sorted(p.resolve() for p in (caller, package / "callee.py", package / "__init__.py"))
    before = closure_digest(caller, tmp_path, ("probe_kernels",))
    closure_digest.cache_clear()
    (package / "__init__.py").write_text("# touched\n")
    assert closure_digest(caller, tmp_path, ("probe_kernels",)) != before
    closure_digest.cache_clear()


def test_imports_of_other_packages_and_relative_ones_are_not_followed():
    source = "import numpy\nfrom uavcore.geodesy import x\nimport planner.tour\nfrom . import y\n"
    source += "def inner():\n    from sitl_quad import rotors\n"
    assert imported_modules(source, ("uavcore", "planner", "sitl_quad")) == {
        "uavcore.geodesy",
        "uavcore.geodesy.x",
        "planner.tour",
        "sitl_quad",
        "sitl_quad.rotors",
    }


def test_every_kernel_of_the_project_is_a_cached_kernel():
    """A kernel left on numba's own cache would be stale after a pull that changed what it calls."""
    plain = [
        str(path.relative_to(ROOT))
        for package in PACKAGES
        for path in (ROOT / package).rglob("*.py")
        if "njit(cache=True)" in path.read_text(encoding="utf-8") and path.name != "kernel_cache.py"
    ]
    assert plain == []


def test_the_import_lines_read_give_the_imports_a_full_parse_gives_for_every_module_of_the_project():
    for package in PACKAGES:
        for path in (ROOT / package).rglob("*.py"):
            source = path.read_text(encoding="utf-8")
            full = {ast.dump(n) for n in ast.walk(ast.parse(source)) if isinstance(n, ast.Import | ast.ImportFrom)}
            assert {ast.dump(node) for node in import_statements(source)} == full, path


def test_a_docstring_line_that_begins_like_an_import_is_passed_over_and_a_parenthesised_one_is_read_whole():
    source = (
        '"""\nimport the frames from the camera\n"""\nfrom planner.tour import (  # the API\n    plan,\n    X,\n)\n'
    )
    assert imported_modules(source, ("planner",)) == {"planner.tour", "planner.tour.plan", "planner.tour.X"}
