"""`cached_kernel`: numba's `njit(cache=True)` whose on-disk cache is also invalidated when a module the kernel's
module imports from this project changes.

numba keys a cached kernel by its own source file only. A kernel that calls a kernel of another module compiles
that one into itself, and a module-level constant it reads is frozen into the machine code: after a `git pull`
that changed only the callee or the constant, numba loaded the old machine code and the vehicle flew, or the
planner planned, with the old one. Here each kernel's cache stamp is numba's stamp together with a digest of
every project module its file imports, transitively (the imports read from the source, not executed), so such a
change compiles afresh. Cached kernels of other libraries are left to numba's own locators.
"""

from __future__ import annotations

import ast
import functools
import hashlib
import re
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any, TypeVar

from numba import njit
from numba.core import config
from numba.core.caching import InTreeCacheLocator, UserProvidedCacheLocator, UserWideCacheLocator

ROOT = Path(__file__).resolve().parents[1]  # the directory holding the project's packages (checkout or site-packages)
PACKAGES = ("uavcore", "sitl_quad", "adrc_offboard", "planner")  # those with kernels, and all they import from

Function = TypeVar("Function", bound=Callable[..., Any])


@functools.cache
def module_file(name: str, root: Path) -> Path | None:
    """The source of module `name` under root (a package's __init__.py), or None if it is not a module there."""
    base = root.joinpath(*name.split("."))
    for path in (base.with_suffix(".py"), base / "__init__.py"):
        if path.is_file():
            return path
    return None


IMPORT_LINE = re.compile(r"^[ \t]*(?:from[ \t]+[\w.]+[ \t]+import|import)[ \t(]", re.MULTILINE)


def import_statements(source: str) -> Iterator[ast.stmt]:
    """The import statements of a module's source, at any depth (imports inside functions count too). Only the
    lines that begin one are parsed (with the lines a parenthesised one continues on): parsing whole modules
    cost a process with kernels most of a second on a busy machine. A docstring's line that merely begins like
    an import does not parse, and is passed over."""
    lines = source.splitlines()
    for match in IMPORT_LINE.finditer(source):
        first = source.count("\n", 0, match.start())
        statement = [lines[first].strip()]
        if "(" in statement[0]:  # from a import (b,\n c,\n) up to the closing parenthesis
            row = first
            while ")" not in statement[-1] and row + 1 < len(lines):
                row += 1
                statement.append(lines[row].split("#")[0])
        try:
            yield from ast.parse("\n".join(statement)).body
        except SyntaxError:
            continue


def imported_modules(source: str, packages: tuple[str, ...]) -> set[str]:
    """The modules of `packages` that the module `source` imports, or imports from (`from a.b import c`: a.b,
    and a.b.c should c be a module)."""
    names: set[str] = set()
    for node in import_statements(source):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module)
            names.update(f"{node.module}.{alias.name}" for alias in node.names)
    return {name for name in names if name.split(".")[0] in packages}


@functools.cache
def _imported_files(path: Path, root: Path, packages: tuple[str, ...]) -> tuple[Path, ...]:
    """The files of the modules `path` imports from packages under root (a package's __init__.py too, as
    importing a module runs it); parsed once per file and process."""
    files = []
    for name in imported_modules(path.read_text(encoding="utf-8"), packages):
        parts = name.split(".")
        for depth in range(1, len(parts) + 1):  # a.b.c runs a/__init__ and a/b/__init__ first
            found = module_file(".".join(parts[:depth]), root)
            if found is not None:
                files.append(found.resolve())
    return tuple(files)


def source_closure(path: Path, root: Path, packages: tuple[str, ...]) -> list[Path]:
    """`path` and every module of `packages` under root it imports, transitively."""
    seen: set[Path] = set()
    todo = [path.resolve()]
    while todo:
        current = todo.pop()
        if current not in seen:
            seen.add(current)
            todo.extend(_imported_files(current, root, packages))
    return sorted(seen)


@functools.cache
def closure_digest(path: Path, root: Path, packages: tuple[str, ...]) -> str:
    """SHA-256 over the names and contents of source_closure(path) (once per file and process)."""
    digest = hashlib.sha256()
    for source in source_closure(path, root, packages):
        name = source.relative_to(root) if source.is_relative_to(root) else source
        digest.update(f"{name}\0".encode())
        digest.update(source.read_bytes())
        digest.update(b"\0")
    return digest.hexdigest()


class _ClosureStamped:
    """A numba cache locator mixin: the stamp an index is saved with and checked against carries the digest of
    the kernel's module and all it imports from the project; locates project files only."""

    _py_file: str

    @classmethod
    def from_function(cls, py_func: Callable[..., Any], py_file: str) -> Any:
        if not Path(py_file).resolve().is_relative_to(ROOT):
            return None
        return super().from_function(py_func, py_file)  # type: ignore[misc]

    def get_source_stamp(self) -> Any:
        stamp = super().get_source_stamp()  # type: ignore[misc]
        return stamp, closure_digest(Path(self._py_file).resolve(), ROOT, PACKAGES)


class ClosureUserProvidedLocator(_ClosureStamped, UserProvidedCacheLocator):
    """NUMBA_CACHE_DIR, when set (benchmarks and tests measuring a cold start set it)."""


class ClosureInTreeLocator(_ClosureStamped, InTreeCacheLocator):
    """The __pycache__ beside the source, numba's default."""


class ClosureUserWideLocator(_ClosureStamped, UserWideCacheLocator):
    """The user's cache directory, where the package's own directory cannot be written (a system install)."""


# numba reads the list when a cached dispatcher is made (numba.core.caching._CacheImpl); its own locators
# follow, for a kernel the project's cannot place.
_LOCATORS = ",".join(
    f"{__name__}.{locator.__name__}"
    for locator in (ClosureUserProvidedLocator, ClosureInTreeLocator, ClosureUserWideLocator)
)
_LOCATORS += ",UserProvidedCacheLocator,InTreeCacheLocator,UserWideCacheLocator,IPythonCacheLocator,ZipCacheLocator"


def cached_kernel(function: Function) -> Function:
    """`njit(cache=True)(function)`, its cache stamped with the digest of what its module imports (see above).
    The locator list is numba's setting for the moment the dispatcher is made, then put back."""
    saved = config.CACHE_LOCATOR_CLASSES  # type: ignore[attr-defined]  # numba >= 0.68; not in its stubs
    config.CACHE_LOCATOR_CLASSES = _LOCATORS  # type: ignore[attr-defined]
    try:
        return njit(cache=True)(function)  # type: ignore[return-value]  # a Dispatcher, called as the function
    finally:
        config.CACHE_LOCATOR_CLASSES = saved  # type: ignore[attr-defined]
