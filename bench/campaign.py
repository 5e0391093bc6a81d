"""A small generic campaign runner: many independent tasks (typically one lockstep flight each), run serially or
on Ray, with a resumable JSONL store.

    from bench.campaign import run_tasks
    results = run_tasks(fly_one, [("adrc/seed0", {"kind": "adrc", "seed": 0}), ...], store=Path("flights.jsonl"))

- A task is a (key, kwargs) pair; `fn(**kwargs)` returns a JSON-serialisable dict. `fn` must be a module-level
  function (Ray pickles it by reference: the workers import its module, so the repository must be importable
  on every node).
- The store is a JSONL file, one line `{"key": ..., "result": ...}` appended, flushed and fsynced as each task
  finishes. On a rerun the keys already in the store are not run again (resume after an interruption); a torn
  last line (the process killed while writing it) is ignored and its task runs again.
- A task that raises is stored as `{"error": "<type>: <message>"}` and the campaign goes on.
- workers="ray": each task is a `ray.remote(num_cpus=1)` call, collected with `ray.wait` as it finishes (a tqdm
  bar on stderr); workers="serial": the same tasks one after another in this process (the reference for the
  speed-up, bench/campaign_speedup.py). docs/campaigns.md has how to run a campaign on a cluster.
"""

from __future__ import annotations

import json
import logging
import os
import re
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

__all__ = ["load_store", "run_tasks", "start_ray"]


def start_ray(address: str | None = None, num_cpus: int | None = None) -> None:
    """Connect to Ray once (idempotent). address None: a local Ray on this machine with `num_cpus` CPUs (default
    os.cpu_count()); "auto" or "ray://host:10001": an existing cluster."""
    import ray

    if ray.is_initialized():
        return
    kwargs: dict[str, Any] = {
        "include_dashboard": False,
        "log_to_driver": False,
        "logging_level": logging.WARNING,
        "configure_logging": True,
    }
    try:
        if address is None:
            ray.init(num_cpus=num_cpus or os.cpu_count() or 1, **kwargs)
        else:
            ray.init(address=address, **kwargs)
    except (ConnectionError, RuntimeError, TimeoutError) as exc:
        where = "a local Ray" if address is None else f"the Ray cluster at {address!r}"
        raise SystemExit(
            f"campaign: cannot reach {where}: {type(exc).__name__}: {exc}\n"
            "  (a cluster's head: `ray start --head`; then --address auto on the head, or "
            "--address ray://HEAD:10001 from elsewhere)"
        ) from exc


def load_store(store: Path) -> dict[str, dict]:
    """The results in a store, by key (later lines win); unreadable lines (a torn last line) are skipped."""
    results: dict[str, dict] = {}
    if not store.exists():
        return results
    with store.open("r", encoding="utf-8") as f:
        for line in f:
            line = line.strip()
            if not line:
                continue
            try:
                row = json.loads(line)
                results[str(row["key"])] = row["result"]
            except (json.JSONDecodeError, KeyError, TypeError):
                continue
    return results


class _Store:
    def __init__(self, path: Path | None) -> None:
        self.path = path
        self._file = None
        if path is not None:
            path.parent.mkdir(parents=True, exist_ok=True)
            needs_newline = path.exists() and path.stat().st_size > 0 and not path.read_bytes().endswith(b"\n")
            self._file = path.open("a", encoding="utf-8")
            if needs_newline:  # a torn last line: end it so the next record starts on its own line
                self._file.write("\n")

    def append(self, key: str, result: dict) -> None:
        if self._file is None:
            return
        self._file.write(json.dumps({"key": key, "result": result}, default=_jsonable) + "\n")
        self._file.flush()
        os.fsync(self._file.fileno())

    def close(self) -> None:
        if self._file is not None:
            self._file.close()


def _jsonable(value: Any) -> Any:
    if hasattr(value, "tolist"):  # numpy scalars and arrays
        return value.tolist()
    return str(value)


def _importable(fn: Callable[..., dict]) -> Callable[..., dict]:
    """fn as its module's attribute: a function of a module run as `python -m pkg.mod` lives in `__main__`,
    which Ray's workers cannot import; the same function imported as pkg.mod pickles by reference."""
    if getattr(fn, "__module__", None) != "__main__":
        return fn
    spec = getattr(sys.modules["__main__"], "__spec__", None)
    if spec is None:  # a script run by path: cloudpickle sends the function by value
        return fn
    import importlib

    return getattr(importlib.import_module(spec.name), fn.__name__)


def _call(fn: Callable[..., dict], kwargs: dict) -> dict:
    try:
        result = fn(**kwargs)
    except Exception as exc:
        return {"error": f"{type(exc).__name__}: {exc}"}
    # Round-trip through JSON so that serial and Ray results are the same plain values as the store's.
    return json.loads(json.dumps(result, default=_jsonable))


def run_tasks(
    fn: Callable[..., dict],
    tasks: Sequence[tuple[str, dict]],
    store: Path | None = None,
    *,
    workers: str = "ray",
    address: str | None = None,
    num_cpus: int | None = None,
    desc: str = "flights",
    progress: bool = True,
) -> dict[str, dict]:
    """Run fn(**kwargs) for every (key, kwargs) not already in `store`; returns all results by key."""
    if workers not in ("ray", "serial"):
        raise ValueError(f"workers must be 'ray' or 'serial', not {workers!r}")
    keys = [key for key, _ in tasks]
    if len(set(keys)) != len(keys):
        raise ValueError("task keys must be unique")
    done = load_store(store) if store is not None else {}
    results = {key: done[key] for key in keys if key in done}
    todo = [(key, kwargs) for key, kwargs in tasks if key not in done]
    if not todo:
        return results
    from tqdm import tqdm

    out = _Store(store)
    bar = tqdm(total=len(tasks), initial=len(results), desc=desc, file=sys.stderr, disable=not progress)
    try:
        if workers == "serial":
            for key, kwargs in todo:
                results[key] = _call(fn, kwargs)
                out.append(key, results[key])
                bar.update(1)
        else:
            import ray

            start_ray(address, num_cpus)
            remote = ray.remote(num_cpus=1)(_call)
            fn_ref = ray.put(_importable(fn))
            pending = {remote.remote(fn_ref, kwargs): key for key, kwargs in todo}
            while pending:
                ready, _ = ray.wait(list(pending), num_returns=1)
                for ref in ready:
                    key = pending.pop(ref)
                    try:
                        results[key] = ray.get(ref)
                    except Exception as exc:
                        message = re.sub(r"\x1b\[[0-9;]*m", "", str(exc))
                        results[key] = {"error": f"{type(exc).__name__}: {message}"}
                    out.append(key, results[key])
                    bar.update(1)
    finally:
        bar.close()
        out.close()
    return results


def probe(x: int, fail: bool = False) -> dict:
    """A cheap deterministic task (tests, and a first check that a cluster's workers import the repository)."""
    if fail:
        raise ValueError(f"probe {x} asked to fail")
    return {"x": x, "square": x * x, "pid": os.getpid()}
