"""Statistics over the seeds: mean and 95 % confidence interval per controller, paired tests between them.

A seed fixes the air (wind, turbulence, D terms, sensor noise), and every controller flies every seed, so the
comparison is paired: the per-seed differences between the ADRC and each other controller
are tested with the paired t-test and with the Wilcoxon signed-rank test, which does not assume the
differences are normal (a few gusty seeds make tracking errors skewed).
"""

from __future__ import annotations

import math

import numpy as np

# scipy.stats is imported where it is used: it takes a second to import, and the test suite imports this module
# (through bench.control.__main__) on every run to collect tests that never call it.


def mean_ci(values: np.ndarray) -> dict:
    """Mean and 95 % confidence interval (Student t, n - 1 degrees of freedom) of the finite values; a metric a
    crashed flight never reached is NaN and left out (n says how many counted)."""
    values = values[np.isfinite(values)]
    n = values.size
    if n == 0:
        return {"mean": None, "ci95": None, "n": 0}
    mean = float(values.mean())
    if n < 2:
        return {"mean": mean, "ci95": None, "n": int(n)}
    from scipy import stats

    half = float(stats.t.ppf(0.975, n - 1)) * float(values.std(ddof=1)) / math.sqrt(n)
    return {"mean": mean, "ci95": [mean - half, mean + half], "n": int(n)}


def paired_t_test(a: np.ndarray, b: np.ndarray) -> float:
    """Two-sided p of the paired t-test on a - b (scipy.stats.ttest_rel). When every difference is the same, t
    is undefined (scipy returns NaN): p = 1 if they are all zero (the controllers did not differ at all),
    0 if they are all the same nonzero value."""
    d = a - b
    if float(d.std(ddof=1)) == 0.0:
        return 1.0 if float(d.mean()) == 0.0 else 0.0
    from scipy import stats

    return float(stats.ttest_rel(a, b).pvalue)


def wilcoxon_signed_rank(a: np.ndarray, b: np.ndarray) -> float:
    """Two-sided p of the Wilcoxon signed-rank test on a - b, zero differences dropped first (the "wilcox"
    convention). Without ties among the remaining |differences| the p is exact (scipy.stats.wilcoxon with
    method="exact": the null distribution of the rank sum); with ties that distribution no longer applies, and
    the p comes from the normal approximation with the tie-corrected variance and a 0.5 continuity correction
    (method="asymptotic", correction=True). No nonzero difference at all: p = 1."""
    d = a - b
    d = d[d != 0.0]
    if d.size == 0:
        return 1.0
    ties = np.unique(np.abs(d)).size < d.size
    from scipy import stats

    return float(stats.wilcoxon(d, correction=True, method="asymptotic" if ties else "exact").pvalue)


def summarise(
    per_seed: dict[str, list[dict]], metrics: tuple[str, ...], pairs: tuple[tuple[str, str], ...] = ()
) -> dict:
    """{"per_controller": {row: {metric: mean_ci}}, "paired": {"<a>_vs_<b>": {metric: tests}}} for the `pairs`
    (a, b) of rows of per_seed (default ("adrc", "pid") and ("adrc", "px4")); a metric is tested on the seeds
    where both flights have it, if there are at least 3."""
    out: dict = {"per_controller": {}, "paired": {}}
    for kind, rows in per_seed.items():
        out["per_controller"][kind] = {m: mean_ci(np.array([r[m] for r in rows], dtype=float)) for m in metrics}
    for first, other in pairs or (("adrc", "pid"), ("adrc", "px4")):
        if first not in per_seed or other not in per_seed:
            continue
        tests = {}
        for m in metrics:
            a = np.array([r[m] for r in per_seed[first]], dtype=float)
            b = np.array([r[m] for r in per_seed[other]], dtype=float)
            ok = np.isfinite(a) & np.isfinite(b)
            if ok.sum() < 3:
                continue
            tests[m] = {
                "mean_difference": float(np.mean(a[ok] - b[ok])),
                "paired_t_p": paired_t_test(a[ok], b[ok]),
                "wilcoxon_p": wilcoxon_signed_rank(a[ok], b[ok]),
                "n": int(ok.sum()),
            }
        out["paired"][f"{first}_vs_{other}"] = tests
    return out
