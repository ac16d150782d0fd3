"""Paired comparison of two methods (bootstrap interval, sign-flip test, verdicts)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import odmd_bench
from odmd_bench import UsageError, ValidationError
from odmd_bench.data.io import write_sets
from odmd_bench.data.registry import get_benchmark, set_file
from odmd_bench.evaluation.compare import (
    A_BETTER,
    B_BETTER,
    TIE,
    Resampled,
    SharedDraws,
    compare_errors,
    compare_files,
    compare_results,
    minimum_resamples,
    resolution_problem,
    smallest_p,
)
from odmd_bench.evaluation.predictions import write_predictions
from odmd_bench.evaluation.scoring import evaluate

SETS = ("normal", "camera", "object", "robot")


def errors(
    seed: int, n: int = 300, shift: float = 0.0
) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    rng = np.random.default_rng(seed)
    a = {s: rng.gamma(2.0, 5.0, n) for s in SETS}
    b = {s: a[s] + shift + rng.normal(0.0, 1.0, n) for s in SETS}
    return a, b


def test_identical_methods_are_not_distinguishable() -> None:
    a, _ = errors(0)
    c = compare_errors(a, {s: v.copy() for s, v in a.items()})
    for d in [*c.sets.values(), c.all]:
        assert (d.difference, d.ci_low, d.ci_high, d.p_value) == (0.0, 0.0, 0.0, 1.0)
        assert d.verdict == TIE


def test_a_clearly_better_and_swapping_mirrors_exactly() -> None:
    a, b = errors(1, shift=1.0)  # B's error is 1 point higher
    ab = compare_errors(a, b, seed=3)
    ba = compare_errors(b, a, seed=3)
    for s in SETS:
        assert ab.sets[s].verdict == A_BETTER and ba.sets[s].verdict == B_BETTER
        assert ab.sets[s].ci_low < -0.7 and ab.sets[s].ci_high < 0
        # same resamples: every bootstrap mean is negated, so the interval mirrors
        assert ba.sets[s].difference == -ab.sets[s].difference
        assert ba.sets[s].ci_low == pytest.approx(-ab.sets[s].ci_high, rel=1e-12)
        assert ba.sets[s].p_value == ab.sets[s].p_value
    assert ab.all.verdict == A_BETTER and ba.all.verdict == B_BETTER


def test_all_is_the_mean_of_set_differences_and_lies_in_its_interval() -> None:
    a, b = errors(2, shift=0.2)
    c = compare_errors(a, b)
    assert c.all.difference == pytest.approx(np.mean([c.sets[s].difference for s in SETS]), rel=1e-13)
    assert c.all.mean_a == pytest.approx(np.mean([a[s].mean() for s in SETS]), rel=1e-13)
    assert c.all.ci_low < c.all.difference < c.all.ci_high
    assert c.all.n == 4 * 300
    # stratified over 4 sets, All's interval is narrower than one set's
    widths = [c.sets[s].ci_high - c.sets[s].ci_low for s in SETS]
    assert c.all.ci_high - c.all.ci_low < min(widths)


def test_reproducible_and_independent_of_other_sets() -> None:
    a, b = errors(4, shift=0.1)
    c1 = compare_errors(a, b, seed=7)
    c2 = compare_errors(a, b, seed=7)
    assert c1 == c2
    only = compare_errors({"robot": a["robot"]}, {"robot": b["robot"]}, seed=7)
    assert only.sets["robot"] == c1.sets["robot"]
    other = compare_errors(a, b, seed=8)
    assert other.sets["robot"].ci_low != c1.sets["robot"].ci_low


def test_bootstrap_interval_has_the_expected_width() -> None:
    # d ~ N(0.5, 1), n = 400: the mean's standard error is 0.05, a 95 % interval ~ +-0.098.
    rng = np.random.default_rng(5)
    d = rng.normal(0.5, 1.0, 400)
    c = compare_errors({"normal": d}, {"normal": np.zeros(400)}, n_resamples=4000)
    se = d.std() / np.sqrt(400)
    assert (c.sets["normal"].ci_high - c.sets["normal"].ci_low) == pytest.approx(2 * 1.96 * se, rel=0.1)
    assert c.sets["normal"].verdict == B_BETTER


def test_verdict_needs_the_test_too() -> None:
    # Five examples all favouring A: the bootstrap interval excludes 0, but the exact
    # sign-flip p-value is 2 / 2**5 = 0.0625, so this is not called a difference.
    a = {"normal": np.array([1.0, 2.0, 3.0, 4.0, 5.0])}
    b = {"normal": a["normal"] + np.array([0.9, 1.0, 1.1, 1.0, 0.95])}
    d = compare_errors(a, b, n_resamples=4000).sets["normal"]
    assert d.ci_high < 0
    assert d.p_value == pytest.approx(0.0625, abs=0.015)
    assert d.verdict == TIE


def test_noise_only_is_not_distinguishable() -> None:
    rng = np.random.default_rng(6)
    a = {s: rng.gamma(2.0, 5.0, 500) for s in SETS}
    b = {s: rng.permutation(a[s]) for s in SETS}  # same distribution, no shift
    c = compare_errors(a, b)
    assert c.all.verdict == TIE and c.all.p_value > 0.05


@pytest.mark.parametrize(
    ("a", "b", "kw", "words"),
    [
        ({"normal": [1.0]}, {"camera": [1.0]}, {}, "same sets"),
        ({}, {}, {}, "no sets"),
        ({"normal": [1.0, 2.0]}, {"normal": [1.0]}, {}, "same non-empty"),
        ({"normal": [1.0]}, {"normal": [np.nan]}, {}, "finite"),
        ({"normal": [1.0]}, {"normal": [1.0]}, {"n_resamples": 0}, "n_resamples"),
        ({"normal": [1.0]}, {"normal": [1.0]}, {"confidence": 1.0}, "confidence"),
    ],
)
def test_bad_arguments(a: dict, b: dict, kw: dict, words: str) -> None:
    with pytest.raises(UsageError, match=words):
        compare_errors(a, b, **kw)


@pytest.mark.parametrize("n_resamples", [2000, 601])
def test_resampled_compares_every_pair_as_compare_errors_does(n_resamples: int) -> None:
    """The leaderboard's shared draws: the same comparison of every pair, up to rounding."""
    rng = np.random.default_rng(11)
    sizes = {"normal": 300, "camera": 250, "object": 199, "robot": 120}
    base = {s: rng.gamma(2.0, 5.0, n) for s, n in sizes.items()}
    methods = {
        "same": {s: v.copy() for s, v in base.items()},
        "base": base,
        "close": {s: v + rng.normal(0.05, 1.0, v.size) for s, v in base.items()},
        "worse": {s: v + 1.0 + rng.normal(0.0, 1.0, v.size) for s, v in base.items()},
        "zeros": {s: np.zeros(n) for s, n in sizes.items()},
    }
    shared = Resampled(methods, n_resamples=n_resamples, seed=4, confidence=0.9)
    verdicts = set()
    for a in methods:
        for b in methods:
            got = shared.compare(a, b)
            want = compare_errors(methods[a], methods[b], n_resamples=n_resamples, seed=4, confidence=0.9)
            assert (got.n_resamples, got.seed, got.confidence) == (n_resamples, 4, 0.9)
            for x, y in [(got.all, want.all), *((got.sets[s], want.sets[s]) for s in sizes)]:
                assert (x.n, x.mean_a, x.mean_b, x.difference) == (y.n, y.mean_a, y.mean_b, y.difference)
                assert (x.verdict, x.p_value) == (y.verdict, y.p_value)
                assert x.ci_low == pytest.approx(y.ci_low, rel=1e-12, abs=1e-12)
                assert x.ci_high == pytest.approx(y.ci_high, rel=1e-12, abs=1e-12)
                verdicts.add(x.verdict)
    assert verdicts == {A_BETTER, B_BETTER, TIE}
    same = shared.compare("base", "same").all
    assert (same.difference, same.ci_low, same.ci_high, same.p_value) == (0.0, 0.0, 0.0, 1.0)


@pytest.mark.parametrize("n_resamples", [2000, 601])
def test_shared_draws_give_bit_for_bit_what_drawing_again_gives(
    n_resamples: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Boards with sets of one name and size (the leaderboard's) draw each stream once."""
    from odmd_bench.evaluation import resampling as compare

    monkeypatch.setattr(compare, "_BLOCK_BYTES", 16 * 300 * 250 * 2)  # blocks of 500 resamples
    drawn: list[int] = []
    counted = compare._counted
    monkeypatch.setattr(compare, "_counted", lambda n, *args: drawn.append(n) or counted(n, *args))
    rng = np.random.default_rng(5)

    def board(sizes: dict[str, int]) -> dict[str, dict[str, np.ndarray]]:
        return {
            m: {s: rng.gamma(2.0, 5.0, n) + shift for s, n in sizes.items()}
            for m, shift in (("a", 0.0), ("b", 0.5))
        }

    boards = [
        board({"normal": 300, "camera": 250}),
        board({"normal": 300, "camera": 251, "robot": 120}),  # normal again; camera of another size
        board({"camera": 250, "normal": 300}),
    ]
    kw = {"n_resamples": n_resamples, "seed": 3, "confidence": 0.9}
    draws = SharedDraws()
    shared = [Resampled(b, draws=draws, **kw) for b in boards]  # type: ignore[arg-type]
    assert drawn == [300, 250, 251, 120]
    for b, got in zip(boards, shared, strict=True):
        fresh = Resampled(b, **kw)  # type: ignore[arg-type]
        for s in b["a"]:
            assert got._boot[s].tobytes() == fresh._boot[s].tobytes()
            assert got._flip[s].tobytes() == fresh._flip[s].tobytes()
        assert got.compare("a", "b") == fresh.compare("a", "b")
    drawn.clear()
    other = Resampled(boards[0], draws=draws, n_resamples=n_resamples, seed=4)  # another seed
    assert drawn == [300, 250]
    assert other.compare("a", "b") == Resampled(boards[0], n_resamples=n_resamples, seed=4).compare("a", "b")


@pytest.mark.parametrize(
    ("errors_", "kw", "words"),
    [
        ({"a": {"normal": [1.0]}, "b": {"camera": [1.0]}}, {}, "same sets"),
        ({"a": {}}, {}, "no sets"),
        ({"a": {"normal": [1.0, 2.0]}, "b": {"normal": [1.0]}, "c": {"normal": [1.0]}}, {}, "same non-empty"),
        ({"a": {"normal": [1.0]}, "b": {"normal": [np.inf]}}, {}, "finite"),
        ({"a": {"normal": [1.0]}}, {"n_resamples": 0}, "n_resamples"),
    ],
)
def test_resampled_bad_arguments(errors_: dict, kw: dict, words: str) -> None:
    with pytest.raises(UsageError, match=words):
        Resampled(errors_, **kw)
    with pytest.raises(UsageError, match="unknown method 'x'; expected one of a, b"):
        Resampled({"a": {"s": [1.0]}, "b": {"s": [2.0]}}).compare("a", "x")


@pytest.fixture()
def data(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    d = tmp_path / "data"
    for k, split in enumerate(("val", "test")):
        sets = {s: odmd_bench.generate(40, rng=10 * k + i) for i, s in enumerate(SETS)}
        write_sets(set_file(get_benchmark("odmd-paper"), split, d), sets)
    monkeypatch.setenv("ODMD_BENCH_DATA", str(d))
    return d


def _preds(tmp_path: Path, name: str, scale: float, seed: int, split: str = "test") -> Path:
    rng = np.random.default_rng(seed)
    truth = {s: ex.depth for s, ex in odmd_bench.load_split(split, "odmd-paper").items()}
    p = tmp_path / name
    write_predictions(p, split, {s: z * (1 + rng.normal(0, scale, z.shape)) for s, z in truth.items()})
    return p


def test_compare_files(data: Path, tmp_path: Path) -> None:
    a = _preds(tmp_path, "a.csv", 0.01, 1)
    b = _preds(tmp_path, "b.csv", 0.3, 2)
    c, ra, rb = compare_files(a, b, benchmark="odmd-paper")
    assert c.all.verdict == A_BETTER
    assert c.all.mean_a == pytest.approx(ra.all_percent_error_mean, rel=1e-13)
    assert c.all.mean_b == pytest.approx(rb.all_percent_error_mean, rel=1e-13)
    d = c.to_dict()
    assert d["provenance"]["a"]["predictions_file"] == "a.csv" and d["method"]["seed"] == 0
    assert (d["benchmark"], d["split"]) == ("odmd-paper", "test")


def test_compare_files_names_the_problems_of_both(data: Path, tmp_path: Path) -> None:
    a = tmp_path / "a.csv"
    a.write_text("split,set,index,depth\ntest,normal,0,x\n")
    b = tmp_path / "b.csv"
    b.write_text("split,set,index\n")
    with pytest.raises(ValidationError) as e:
        compare_files(a, b, benchmark="odmd-paper")
    assert any(p.startswith("A (") and "depth is not a number" in p for p in e.value.problems)
    assert any(p.startswith("B (") and "missing column 'depth'" in p for p in e.value.problems)


def test_compare_results_refuses_different_splits(data: Path, tmp_path: Path) -> None:
    ra = evaluate(_preds(tmp_path, "a.csv", 0.1, 1), benchmark="odmd-paper")
    rb = evaluate(_preds(tmp_path, "b.csv", 0.1, 1, split="val"), benchmark="odmd-paper")
    with pytest.raises(UsageError, match="cannot be compared"):
        compare_results(ra, rb)


def test_compare_pairs_gives_what_compare_errors_gives() -> None:
    from odmd_bench.evaluation.compare import compare_pairs

    a, b = errors(3, n=400, shift=0.4)
    c, _ = errors(4, n=400)
    methods = {"a": a, "b": b, "c": c, "a2": {s: v.copy() for s, v in a.items()}}
    pairs = [("a", "b"), ("a", "c"), ("b", "c"), ("a", "a2"), ("c", "a")]
    got = compare_pairs(methods, pairs, n_resamples=500, seed=3)
    assert list(got) == pairs
    verdicts = set()
    for x, y in pairs:
        want = compare_errors(methods[x], methods[y], n_resamples=500, seed=3)
        for mine, theirs in [
            (got[(x, y)].all, want.all),
            *((got[(x, y)].sets[s], want.sets[s]) for s in SETS),
        ]:
            assert (mine.verdict, mine.p_value, mine.n, mine.mean_a, mine.mean_b) == (
                theirs.verdict,
                theirs.p_value,
                theirs.n,
                theirs.mean_a,
                theirs.mean_b,
            )
            assert np.allclose(
                [mine.difference, mine.ci_low, mine.ci_high],
                [theirs.difference, theirs.ci_low, theirs.ci_high],
                rtol=0,
                atol=1e-12,
            )
        verdicts.add(want.all.verdict)
    assert verdicts == {A_BETTER, B_BETTER, TIE}
    assert got[("a", "a2")].all.difference == 0 and got[("a", "a2")].all.ci_low == 0


def test_compare_pairs_checks_its_input() -> None:
    from odmd_bench.evaluation.compare import compare_pairs

    a, b = errors(1, n=50)
    assert compare_pairs({"a": a}, []) == {}
    with pytest.raises(UsageError, match="same non-empty 1-D errors"):
        compare_pairs({"a": a, "b": {s: v[:-1] for s, v in b.items()}}, [("a", "b")])
    with pytest.raises(UsageError, match="n_resamples must be between"):
        compare_pairs({"a": a, "b": b}, [("a", "b")], n_resamples=0)
    with pytest.raises(UsageError, match="must cover the same sets"):
        compare_pairs({"a": a, "b": {"normal": b["normal"]}}, [("a", "b")])


@pytest.mark.parametrize("confidence", [0.5, 0.9, 0.95, 0.99, 0.999, 0.9999, 0.987654])
def test_settings_that_could_never_find_a_difference_are_refused(confidence: float) -> None:
    # A difference as large as it gets: every example favours A by 9 points.
    a = {"normal": np.linspace(1.0, 2.0, 200)}
    b = {"normal": a["normal"] + 9.0}
    least = minimum_resamples(confidence)
    with pytest.raises(UsageError, match=f"can never find a difference.*use at least {least} resamples"):
        compare_errors(a, b, n_resamples=least - 1, confidence=confidence)
    # one resample more and the verdict follows the interval
    d = compare_errors(a, b, n_resamples=least, confidence=confidence).sets["normal"]
    assert d.ci_high < 0 and d.p_value < 1 - confidence and d.verdict == A_BETTER


def test_the_smallest_p_value_is_the_floor_checked() -> None:
    for n in (1, 9, 10, 19, 20, 99, 100, 1999):
        for confidence in (0.9, 0.95, 0.99):
            refused = resolution_problem(n, confidence) is not None
            assert refused == (smallest_p(n) >= 1 - confidence)
            assert refused == (n < minimum_resamples(confidence))
