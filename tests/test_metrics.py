"""The metrics of docs/format.md ("Metrics") as pure functions."""

from __future__ import annotations

import math

import numpy as np
import pytest

from odmd_bench import UsageError
from odmd_bench.evaluation.metrics import (
    STATS,
    absolute_error,
    all_sets_mean,
    percent_error,
    set_metrics,
    summarize,
)


def test_hand_computed_case_to_the_last_digit() -> None:
    # |2-1|/2 = 50 %, |4-5|/4 = 25 %, |0.5-0.5| = 0 %; absolute 1, 1, 0 m.
    m = set_metrics([2.0, 4.0, 0.5], [1.0, 5.0, 0.5])
    assert m["n"] == 3
    assert m["percent_error"] == {
        "mean": 25.0,
        "median": 25.0,
        "min": 0.0,
        "max": 50.0,
        "std": math.sqrt((25.0**2 + 0.0 + 25.0**2) / 3),  # ddof = 0
    }
    a = m["absolute_error"]
    assert (a["median"], a["min"], a["max"]) == (1.0, 0.0, 1.0)
    assert a["mean"] == pytest.approx(2 / 3, rel=1e-15)
    assert a["std"] == pytest.approx(math.sqrt(2 / 9), rel=1e-15)


def test_std_is_population_std() -> None:
    e = np.array([1.0, 2.0, 4.0, 8.0])
    assert summarize(e)["std"] == float(np.std(e, ddof=0))
    assert summarize(e)["std"] != float(np.std(e, ddof=1))


def test_negative_and_zero_estimates_are_scored_as_given() -> None:
    assert percent_error([1.0, 2.0], [-1.0, 0.0]).tolist() == [200.0, 100.0]
    assert absolute_error([1.0, 2.0], [-1.0, 0.0]).tolist() == [2.0, 2.0]


def test_perfect_estimates_score_zero() -> None:
    z = np.random.default_rng(0).uniform(0.1, 5.0, 100)
    m = set_metrics(z, z.copy())
    for err in ("percent_error", "absolute_error"):
        assert all(m[err][k] == 0.0 for k in STATS)


@pytest.mark.parametrize("func", [percent_error, absolute_error])
def test_invariances(func) -> None:  # type: ignore[no-untyped-def]
    rng = np.random.default_rng(1)
    t = rng.uniform(0.5, 2.0, 50)
    p = t + rng.normal(0, 0.1, 50)
    perm = rng.permutation(50)
    base = func(t, p)
    # list vs array, and a permutation of the examples permutes the errors
    assert np.array_equal(func(t.tolist(), p.tolist()), base)
    assert np.array_equal(func(t[perm], p[perm]), base[perm])
    s, sp = summarize(base), summarize(func(t[perm], p[perm]))
    for k in ("median", "min", "max"):
        assert s[k] == sp[k]
    for k in ("mean", "std"):
        assert s[k] == pytest.approx(sp[k], rel=1e-13)


def test_inputs_are_not_changed() -> None:
    t = np.array([1.0, 2.0])
    p = np.array([1.5, 1.0])
    t0, p0 = t.copy(), p.copy()
    set_metrics(t, p)
    assert np.array_equal(t, t0) and np.array_equal(p, p0)


@pytest.mark.parametrize(
    ("t", "p", "words"),
    [
        ([1.0, 2.0], [1.0], "y_true has 2 values"),
        ([[1.0]], [[1.0]], "1-D"),
        ([1.0, float("nan")], [1.0, 1.0], "true depths"),
        ([0.0], [1.0], "true depths must be finite and > 0"),
        ([1.0], [float("inf")], "estimated depths must be finite"),
    ],
)
def test_bad_inputs_raise_the_package_error(t: list, p: list, words: str) -> None:
    with pytest.raises(UsageError, match="cannot compute") as e:
        percent_error(t, p)
    assert any(words in line for line in e.value.problems)


def test_summarize_refuses_empty() -> None:
    with pytest.raises(UsageError):
        summarize([])


def test_all_is_the_mean_of_set_means_not_of_examples() -> None:
    a = set_metrics([1.0] * 3, [1.1] * 3)  # 10 %, 3 examples
    b = set_metrics([1.0], [1.3])  # 30 %, 1 example
    means = {"a": a["percent_error"]["mean"], "b": b["percent_error"]["mean"]}
    assert all_sets_mean(means) == pytest.approx(20.0, rel=1e-14)  # not 15 (example-weighted)
    with pytest.raises(UsageError):
        all_sets_mean({})
