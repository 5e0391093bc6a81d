"""bench.tune: the score, the bound check, and a tiny campaign on Ray that is interrupted and resumed."""

from __future__ import annotations

import json

import optuna
import pytest

from adrc_offboard.design import load_design
from bench.campaign import load_store
from bench.tune import MAX_SATURATED, PENALTY, SPACE, FamilyStudy, bound_check, main, score

FLIGHT = {
    "buildable": True,
    "rms_error_m": 0.05,
    "max_error_m": 0.2,
    "gust_peak_m": 0.1,
    "saturated_fraction": 0.05,
    "thrust_step_rms": 0.02,
    "completed": True,
}


def test_an_admissible_trial_scores_its_mean_rms_error() -> None:
    result = score([FLIGHT, FLIGHT | {"rms_error_m": 0.07}])
    assert result["admissible"] and result["value"] == pytest.approx(0.06)


@pytest.mark.parametrize(
    ("change", "reason"),
    [
        ({"completed": False}, "did not complete"),
        ({"max_error_m": 12.0}, "error over"),
        ({"saturated_fraction": MAX_SATURATED + 0.3}, "saturated"),
        ({"thrust_step_rms": 0.2}, "thrust chatter"),
    ],
)
def test_a_broken_constraint_costs_the_penalty_and_says_which(change: dict, reason: str) -> None:
    result = score([FLIGHT, FLIGHT | change])
    assert not result["admissible"] and reason in result["reason"]
    assert result["value"] > PENALTY  # worse than any admissible trial


def test_an_unbuildable_design_scores_worst() -> None:
    result = score([{"buildable": False, "reason": "ESO unstable at 50 Hz"}])
    assert result["value"] == 2 * PENALTY and result["reason"] == "ESO unstable at 50 Hz"


def test_the_bound_check_flags_a_best_point_on_a_bound() -> None:
    low, high, _ = SPACE["separation"]
    inside = bound_check({"separation": (low * high) ** 0.5})
    assert inside["bracketed"] and inside["positions"]["separation"] == pytest.approx(0.5)
    assert bound_check({"separation": low * 1.01})["on_bound"] == {"separation": "low"}
    assert bound_check({"separation": high})["on_bound"] == {"separation": "high"}


# Two campaigns, each starting a local Ray and its workers, which load the flight kernels: 110 s beside the rest of
# the suite on 2 cores, 333 s beside it and two CPU burners (over the suite's 300 s default).
@pytest.mark.slow
@pytest.mark.timeout(900)
def test_a_tiny_campaign_on_ray_is_resumed_after_an_interruption(tmp_path) -> None:
    out_dir, out = tmp_path / "tune", tmp_path / "tune.json"
    common = ["--families", "pid", "--batch", "1", "--train-seeds", "0", "--holdout-seeds", "100"]
    common += ["--out-dir", str(out_dir), "--out", str(out), "--quiet"]
    assert main(["--trials", "1", *common]) in (0, 3)
    flights = out_dir / "flights.jsonl"
    first = load_store(flights)
    assert set(first) >= {"pid/trial0/seed0"} and any(k.startswith("holdout/pid/shipped/") for k in first)
    # an interruption mid-batch: a trial asked (RUNNING in the study) whose flight never came back
    left = FamilyStudy("pid", f"sqlite:///{out_dir / 'studies.db'}", seed=0).ask()  # the design's every number
    assert left.number == 1
    lines_before = flights.read_text().count("\n")
    assert main(["--trials", "2", *common]) in (0, 3)
    study = optuna.load_study(study_name="pid", storage=f"sqlite:///{out_dir / 'studies.db'}")
    states = [t.state for t in study.get_trials()]
    assert states == [optuna.trial.TrialState.COMPLETE] * 2  # the left trial completed, no third one asked
    store = load_store(flights)
    assert store["pid/trial1/seed0"]["buildable"]  # flown at the design the trial was asked with
    # only the new trial's flight (and no held-out flight already flown) was added to the store
    added = flights.read_text().count("\n") - lines_before
    assert added == len(set(store) - set(first))
    result = json.loads(out.read_text())
    assert result["trials_per_family"] == 2 and len(result["families"]["pid"]["trials"]) == 2
    first = result["families"]["pid"]["trials"][0]
    assert first["params"] == pytest.approx(load_design("pid").values)  # the warm start: the shipped design
