"""bench.campaign: serial and Ray give the same results, the store resumes, a torn line and a raise are handled."""

from __future__ import annotations

import contextlib
import json
from pathlib import Path

import pytest

from bench.campaign import load_store, probe, run_tasks


def _tasks(n: int, fail: int | None = None) -> list[tuple[str, dict]]:
    return [(f"t{i}", {"x": i, "fail": i == fail}) for i in range(n)]


def _strip(results: dict[str, dict]) -> dict[str, dict]:
    return {k: {f: v for f, v in r.items() if f != "pid"} for k, r in results.items()}


def _store_keys(store: Path) -> list[str]:
    keys = []
    for line in store.read_text().splitlines():
        with contextlib.suppress(json.JSONDecodeError):
            keys.append(json.loads(line)["key"])
    return keys


def test_serial_runs_every_task_and_stores_it(tmp_path: Path) -> None:
    store = tmp_path / "s.jsonl"
    results = run_tasks(probe, _tasks(5), store, workers="serial", progress=False)
    assert _strip(results) == {f"t{i}": {"x": i, "square": i * i} for i in range(5)}
    assert sorted(_store_keys(store)) == [f"t{i}" for i in range(5)]
    assert load_store(store) == results


def test_resume_runs_only_missing_keys_and_ignores_a_torn_line(tmp_path: Path) -> None:
    store = tmp_path / "s.jsonl"
    run_tasks(probe, _tasks(3), store, workers="serial", progress=False)
    with store.open("a") as f:
        f.write('{"key": "t3", "result": {"x"')  # killed while writing t3's line
    results = run_tasks(probe, _tasks(6), store, workers="serial", progress=False)
    assert _strip(results) == {f"t{i}": {"x": i, "square": i * i} for i in range(6)}
    keys = _store_keys(store)
    assert sorted(keys) == [f"t{i}" for i in range(6)]  # each task ran (was stored) exactly once
    assert run_tasks(probe, _tasks(6), store, workers="serial", progress=False) == results
    assert len(_store_keys(store)) == 6  # nothing ran again


def test_a_raising_task_is_recorded_and_the_campaign_goes_on(tmp_path: Path) -> None:
    store = tmp_path / "s.jsonl"
    results = run_tasks(probe, _tasks(4, fail=2), store, workers="serial", progress=False)
    assert results["t2"] == {"error": "ValueError: probe 2 asked to fail"}
    assert results["t3"]["square"] == 9
    assert load_store(store)["t2"] == results["t2"]


@pytest.mark.integration  # starts a local Ray (a few processes, ~3 s)
def test_ray_equals_serial_resumes_and_records_errors(tmp_path: Path) -> None:
    serial = run_tasks(probe, _tasks(6, fail=4), workers="serial", progress=False)
    store = tmp_path / "r.jsonl"
    run_tasks(probe, _tasks(2), store, workers="serial", progress=False)
    ray_results = run_tasks(probe, _tasks(6, fail=4), store, workers="ray", num_cpus=2, progress=False)
    assert _strip(ray_results) == _strip(serial)
    assert ray_results["t4"] == {"error": "ValueError: probe 4 asked to fail"}
    assert sorted(_store_keys(store)) == [f"t{i}" for i in range(6)]


@pytest.mark.integration
def test_ray_in_a_second_process_does_not_clash(tmp_path: Path) -> None:
    """Run beside the test above under `pytest -n 2`: each process starts its own local Ray on ports Ray picks."""
    results = run_tasks(probe, _tasks(4), tmp_path / "q.jsonl", workers="ray", num_cpus=1, progress=False)
    assert _strip(results) == {f"t{i}": {"x": i, "square": i * i} for i in range(4)}
