"""The resampling engine against scipy.stats (a dev-only dependency), within Monte Carlo error.

``scipy.stats.bootstrap`` and ``scipy.stats.permutation_test`` draw their own resamples, so
the engine's figures and scipy's agree only up to Monte Carlo error: each tolerance below
is ``Z`` standard errors of the difference of two independent estimates, each from ``B``
resamples (the formulas are beside each test). ``Z = 5``: two correct estimators differ by
more with probability under 1e-6, while each test's planted mistake (a wrong confidence,
a one-sided count, a test that ignores the data's sign) moves the figure by more than the
tolerance, which each test checks as well: a test that cannot fail is a defect.

Without scipy these tests skip on a developer's machine and fail in CI (``CI`` set), where
the ``dev`` extra installs it.
"""

from __future__ import annotations

import inspect
import os
from types import ModuleType
from typing import Any

import numpy as np
import pytest

from odmd_bench.evaluation import resampling as rs

B = 20_000
Z = 5.0


@pytest.fixture(scope="module")
def stats() -> ModuleType:
    try:
        from scipy import stats as scipy_stats
    except ImportError:
        if os.environ.get("CI"):
            pytest.fail(
                "scipy is not installed: the dev extra installs it, and CI must run these", pytrace=False
            )
        pytest.skip("scipy is not installed (pip install -e '.[dev]')")
    return scipy_stats


def _rng(stats: ModuleType, seed: int) -> dict[str, Any]:
    """The seeding keyword of scipy: ``rng`` from scipy 1.15, ``random_state`` before."""
    key = "rng" if "rng" in inspect.signature(stats.bootstrap).parameters else "random_state"
    return {key: np.random.default_rng(seed)}


def _mean(*samples: np.ndarray, axis: int = -1) -> np.ndarray:
    return np.mean(samples[0], axis=axis)


def _quantile_se(spread: float, q: float, n_resamples: int) -> float:
    """Standard error of the ``q`` quantile of ``n_resamples`` draws of a normal of sd ``spread``.

    ``sqrt(q (1 - q) / B) / f(x_q)``, with ``f`` the normal density at the quantile: the
    bootstrap distribution of a mean of many examples is close to normal.
    """
    from statistics import NormalDist

    density = NormalDist().pdf(NormalDist().inv_cdf(q)) / spread
    return float(np.sqrt(q * (1 - q) / n_resamples) / density)


def _p_se(p: float, n_resamples: int) -> float:
    """Standard error of a p-value estimated by ``n_resamples`` random permutations."""
    return float(np.sqrt(max(p * (1 - p), 1.0 / n_resamples) / n_resamples))


def test_the_paired_bootstrap_interval_is_scipys_percentile_interval(stats: ModuleType) -> None:
    """The interval of a mean difference (compare_errors): ``paired_draws`` and ``percentile_interval``."""
    d = np.random.default_rng(1).gamma(2.0, 3.0, 200) - 5.0  # skewed per-example differences
    boot, _ = rs.paired_draws(d, B, rs.named_stream(0, "normal"))
    mine = rs.percentile_interval(boot, 0.95)
    theirs = stats.bootstrap((d,), _mean, n_resamples=B, method="percentile", **_rng(stats, 2))
    theirs = np.array([theirs.confidence_interval.low, theirs.confidence_interval.high])
    spread = float(d.std() / np.sqrt(d.size))  # sd of the bootstrap distribution of the mean
    tolerance = Z * np.sqrt(2) * _quantile_se(spread, 0.025, B)
    assert np.abs(mine - theirs).max() <= tolerance
    # a 90% interval in place of the 95% one is caught
    assert np.abs(rs.percentile_interval(boot, 0.90) - theirs).min() > tolerance


@pytest.mark.parametrize("shift", [0.0, 0.15, 0.3])
def test_the_sign_flip_p_value_is_scipys_exact_paired_test(stats: ModuleType, shift: float) -> None:
    """Ten differences: scipy enumerates all 2**10 sign flips (exact); the engine draws ``B``.

    The engine's p estimates the exact one with standard error ``sqrt(p (1 - p) / B)``.
    """
    d = np.random.default_rng(3).normal(shift, 0.3, 10)
    _, flip = rs.paired_draws(d, B, rs.named_stream(0, "camera"))
    mine = rs.sign_flip_p(flip, float(d.mean()))
    exact = stats.permutation_test(
        (d,), _mean, permutation_type="samples", n_resamples=2**10, vectorized=True, **_rng(stats, 4)
    ).pvalue
    assert abs(mine - exact) <= Z * _p_se(exact, B) + 1 / (B + 1)
    # counting one side only (half the two-sided p) is caught wherever the p-value is not tiny
    if exact > 0.05:
        one_sided = rs.p_value(int(np.count_nonzero(flip >= abs(d.mean()))), B)
        assert abs(one_sided - exact) > Z * _p_se(exact, B) + 1 / (B + 1)


def test_the_sign_flip_p_value_is_scipys_on_a_large_set(stats: ModuleType) -> None:
    """300 differences: both draw ``B`` sign flips; scipy's two-sided p is twice its smaller one-sided p."""
    d = np.random.default_rng(5).normal(0.12, 1.0, 300)
    _, flip = rs.paired_draws(d, B, rs.named_stream(0, "object"))
    mine = rs.sign_flip_p(flip, float(d.mean()))
    theirs = stats.permutation_test(
        (d,), _mean, permutation_type="samples", n_resamples=B, vectorized=True, **_rng(stats, 6)
    ).pvalue
    assert 0.01 < theirs < 0.5  # a p-value away from the edges, where the comparison says something
    # scipy doubles a one-sided count: its standard error is sqrt(2 p (1 - p/2) / B)
    tolerance = Z * np.sqrt(_p_se(theirs, B) ** 2 + 2 * theirs * (1 - theirs / 2) / B)
    assert abs(mine - theirs) <= tolerance


def test_the_paired_means_give_the_draws_of_one_pair() -> None:
    """Many methods at once (rank groups): each pair's means are ``paired_draws``' on its differences."""
    e = np.random.default_rng(7).gamma(2.0, 5.0, (3, 150))
    boot, flip = rs.paired_means(e, 700, 4, "robot")
    one_boot, one_flip = rs.paired_draws(e[0] - e[2], 700, rs.named_stream(4, "robot"))
    np.testing.assert_allclose(boot[0] - boot[2], one_boot, rtol=0, atol=1e-12)
    np.testing.assert_allclose(flip[0] - flip[2], one_flip, rtol=0, atol=1e-12)


def _greater(x: np.ndarray, y: np.ndarray, axis: int = -1) -> np.ndarray:
    return np.mean(x, axis=axis) - np.mean(y, axis=axis)


@pytest.mark.parametrize(("n", "m", "kind"), [(80, 80, "samples"), (60, 97, "independent")])
def test_the_audit_permutation_p_value_is_scipys(stats: ModuleType, n: int, m: int, kind: str) -> None:
    """One-sided, fresh mean - committed mean: as scipy relabels, with ``B`` permutations each.

    One fresh repeat (``m = n``) relabels within pairs, scipy's ``samples`` permutations of
    paired data; other sizes draw random subsets of the pooled errors, scipy's
    ``independent`` permutations. Standard error of each p: ``sqrt(p (1 - p) / B)``.
    """
    rng = np.random.default_rng(8)
    committed = rng.exponential(5.0, n)
    fresh = rng.exponential(5.0, m)  # one law: p = 0.03 and 0.19 on these draws
    p, p_all = rs.permutation_pvalues(
        {"normal": committed[:, None]}, {"normal": fresh[:, None]}, rs.keyed_stream(9, 1), B
    )
    mine = float(p["normal"][0])
    assert mine == float(p_all[0])  # one set: the mean over sets is that set
    theirs = stats.permutation_test(
        (fresh, committed),
        _greater,
        permutation_type=kind,
        alternative="greater",
        n_resamples=B,
        vectorized=True,
        **_rng(stats, 10),
    ).pvalue
    assert 0.01 < theirs < 0.4  # away from the edges, and from 1/2 (the other side's check)
    tolerance = Z * np.sqrt(2) * _p_se(theirs, B)
    assert abs(mine - theirs) <= tolerance
    # the other side's p-value (a test of "fresh is better") is caught
    assert abs((1 - mine) - theirs) > tolerance


def test_the_audit_bootstrap_interval_is_scipys_percentile_interval(stats: ModuleType) -> None:
    """The fresh mean's interval (multinomial resample counts) against scipy's percentile bootstrap."""
    f = np.random.default_rng(11).exponential(5.0, (400, 2))
    by_set, over_sets = rs.stratified_intervals({"normal": f}, rs.keyed_stream(12, 2), B, 0.95)
    np.testing.assert_array_equal(by_set["normal"], over_sets)  # one set: the mean over sets is that set
    for k in range(2):
        ci = stats.bootstrap((f[:, k],), _mean, n_resamples=B, method="percentile", **_rng(stats, 13 + k))
        theirs = np.array([ci.confidence_interval.low, ci.confidence_interval.high])
        tolerance = Z * np.sqrt(2) * _quantile_se(float(f[:, k].std() / np.sqrt(len(f))), 0.025, B)
        assert np.abs(by_set["normal"][k] - theirs).max() <= tolerance
        wrong, _ = rs.stratified_intervals({"normal": f}, rs.keyed_stream(12, 2), B, 0.80)
        assert np.abs(wrong["normal"][k] - theirs).min() > tolerance
