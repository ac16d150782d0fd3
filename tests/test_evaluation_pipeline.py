"""Evaluation as a pipeline: parse (text only) -> coverage (sizes) -> score; and arrays.

Tiny ``odmd-paper`` sets are written into a temporary data folder (an imported
benchmark, so no manifest pins them).
"""

from __future__ import annotations

import gzip
import hashlib
import io
import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import odmd_bench
from odmd_bench import ParsedPredictions, UsageError, ValidationError, parse_predictions
from odmd_bench.data.io import write_sets
from odmd_bench.data.registry import get_benchmark, set_file
from odmd_bench.evaluation.compare import compare_results
from odmd_bench.evaluation.coverage import check_coverage
from odmd_bench.evaluation.kinds import MAX_ABS_DEPTH
from odmd_bench.evaluation.report import format_comparison, format_json
from odmd_bench.evaluation.scoring import evaluate, score
from odmd_bench.inputs.problems import MAX_LINE_CHARS
from odmd_bench.inputs.source import MAX_PREDICTIONS_BYTES

BENCH = "odmd-paper"
N = {"normal": 6, "camera": 5, "object": 4, "robot": 3}
HEADER = "split,set,index,depth\n"


@pytest.fixture()
def data(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    d = tmp_path / "data"
    sets = {s: odmd_bench.generate(n, perturbation="both", rng=i) for i, (s, n) in enumerate(N.items())}
    write_sets(
        set_file(get_benchmark(BENCH), "test", d), sets, file_attrs={"benchmark": BENCH, "split": "test"}
    )
    monkeypatch.setenv("ODMD_BENCH_DATA", str(d))
    return d


def noisy(seed: int = 0) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    truth = {s: ex.depth for s, ex in odmd_bench.load_split("test", BENCH).items()}
    return {s: z * (1 + rng.normal(0, 0.1, z.shape)) for s, z in truth.items()}


def csv_text(depths: dict[str, np.ndarray], split: str = "test") -> str:
    rows = [f"{split},{s},{i},{v!r}" for s, d in depths.items() for i, v in enumerate(d.tolist())]
    return HEADER + "\n".join(rows) + "\n"


# --- parse: pure, from the text alone ----------------------------------------------


def test_parse_needs_no_data(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("ODMD_BENCH_DATA", str(tmp_path / "nothing-here"))
    text = HEADER + "test,robot,1,2.5\ntest,normal,0,-1\n"
    p = parse_predictions(text.encode(), name="mine.csv")
    assert isinstance(p, ParsedPredictions)
    assert (p.name, p.benchmark, p.split, p.n_rows) == ("mine.csv", "odmd-v1", "test", 2)
    assert [p.set_names[c] for c in p.codes] == ["robot", "normal"]
    assert p.indices.tolist() == [1, 0] and p.depths.tolist() == [2.5, -1.0] and p.lines.tolist() == [2, 3]
    assert not (tmp_path / "nothing-here").exists()


def test_parse_reads_paths_bytes_files_and_gzip_alike(tmp_path: Path) -> None:
    raw = (HEADER + "val,camera,0,1.25\n").encode()
    plain, packed = tmp_path / "p.csv", tmp_path / "p.csv.gz"
    plain.write_bytes(raw)
    packed.write_bytes(gzip.compress(raw))
    results = [
        parse_predictions(plain),
        parse_predictions(str(packed)),
        parse_predictions(raw),
        parse_predictions(io.BytesIO(gzip.compress(raw))),
    ]
    assert {r.sha256 for r in results} == {hashlib.sha256(raw).hexdigest()}
    assert all(r.depths.tolist() == [1.25] for r in results)
    with pytest.raises(UsageError, match="binary file"):
        parse_predictions(io.StringIO(raw.decode()))  # type: ignore[arg-type]


def test_parse_names_every_text_problem_at_once() -> None:
    text = HEADER + "test,normal,0,1\ntest,normal,0,2\ntest,nromal,1,x\nval,robot,1.5,1e308\n"
    with pytest.raises(ValidationError) as e:
        parse_predictions(text.encode(), benchmark=BENCH)
    got = e.value.problems
    assert any(q.startswith("a file holds one split, this one has 2") for q in got)
    assert any("'nromal': did you mean 'normal'?" in q for q in got)
    assert "depth is not a number (1 row): line 4 ('x')" in got
    assert "index is not an integer (1 row): line 5 ('1.5')" in got
    assert any(q.startswith("depth is out of range") and "line 5 ('1e308')" in q for q in got)
    assert "duplicate (set, index) (1 row): line 3 repeats line 2 (normal 0)" in got


def test_non_strict_parse_keeps_problems_for_coverage_to_report_in_one_error() -> None:
    text = HEADER + "test,normal,0,oops\n" + "".join(f"test,{s},0,1\n" for s in ("camera", "object", "robot"))
    parsed = parse_predictions(text.encode(), benchmark=BENCH, strict=False)
    assert parsed.problems  # the bad depth
    with pytest.raises(ValidationError) as e:
        check_coverage(parsed, {"normal": 2, "camera": 1, "object": 1, "robot": 1})
    assert e.value.problems == [
        "depth is not a number (1 row): line 2 ('oops')",
        "1 of the 2 examples of set 'normal' have no row (missing indices 1)",
    ]
    assert parsed.problems.lines() == ["depth is not a number (1 row): line 2 ('oops')"]  # unchanged


def test_coverage_places_estimates_and_warns() -> None:
    text = HEADER + "test,robot,1,0.0\ntest,robot,0,2\ntest,normal,0,1\n"
    parsed = parse_predictions(text.encode(), benchmark=BENCH)
    preds = check_coverage(parsed, {"robot": 2}, sets=["robot"])
    assert preds.depths["robot"].tolist() == [2.0, 0.0]
    assert preds.warnings == (
        "1 depth is zero or negative (scored as given): line 2 (robot 1: 0.0)",
        "ignored rows of sets not asked for: normal (1 rows)",
    )
    with pytest.raises(UsageError, match="no size given"):
        check_coverage(parsed, {})


def test_error_texts_are_bounded() -> None:
    garbage = b"x" * 100_000
    for data in (garbage, garbage + b"\n" + garbage, b"split,set,index,depth," + garbage + b"\n" + garbage):
        with pytest.raises(ValidationError) as e:
            parse_predictions(data)
        assert len(str(e.value)) < 2_000
        assert all(len(q) <= MAX_LINE_CHARS for q in e.value.problems)


def test_inputs_over_the_cap_are_refused_early() -> None:
    with pytest.raises(ValidationError, match="larger than 64 MiB"):
        parse_predictions(b"a" * (MAX_PREDICTIONS_BYTES + 1))
    bomb = gzip.compress(HEADER.encode() + b"\n" * (MAX_PREDICTIONS_BYTES + 1), compresslevel=1)
    assert len(bomb) < 1_000_000
    with pytest.raises(ValidationError, match="the decompressed file is larger than 64 MiB"):
        parse_predictions(bomb)
    with pytest.raises(ValidationError, match="not a readable gzip file"):
        parse_predictions(gzip.compress(HEADER.encode())[:-5])


@pytest.mark.skipif(not Path("/dev/zero").exists(), reason="no /dev/zero")
def test_dev_zero_is_refused() -> None:
    with pytest.raises(ValidationError, match="/dev/zero cannot be scored") as e:
        parse_predictions("/dev/zero")
    assert "larger than 64 MiB" in e.value.problems[0]


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=400))
def test_any_bytes_give_parsed_predictions_or_a_validation_error(data: bytes) -> None:
    try:
        p = parse_predictions(data)
    except ValidationError:
        return
    assert isinstance(p, ParsedPredictions) and not p.problems
    assert p.codes.shape == p.indices.shape == p.depths.shape == p.lines.shape
    assert np.all(np.abs(p.depths) <= MAX_ABS_DEPTH)


def _parse_both_ways(data: bytes, benchmark: str | None, block: int = 64) -> tuple[object, object, bool]:
    """What parse_predictions gives (the result's fields, or the error) in bulk and row by row.

    The bulk pass reads blocks of ``block`` characters (64: a small file spans several).
    """
    from unittest import mock

    from odmd_bench.evaluation import rows

    def outcome() -> object:
        try:
            p = parse_predictions(data, benchmark=benchmark, strict=False)
        except ValidationError as e:
            return ("error", e.message, e.problems)
        arrays = [(a.dtype.str, a.tobytes()) for a in (p.codes, p.indices, p.depths, p.lines)]
        fields = (p.name, p.sha256, p.benchmark, p.split, p.n_rows, p.ignored_columns, p.set_names)
        return fields, arrays, p.nonpositive, p.problems.lines(), p.benchmark_column

    taken = []
    bulk = rows.Rows.add_clean

    def spy(self: rows.Rows, *args: object) -> bool:
        taken.append(bulk(self, *args))  # type: ignore[arg-type]
        return taken[-1]

    with mock.patch.object(rows, "_BLOCK_CHARS", block), mock.patch.object(rows.Rows, "add_clean", spy):
        fast = outcome()
    with mock.patch.object(rows.Rows, "add_clean", lambda self, *args: False):
        slow = outcome()
    return fast, slow, any(taken)


_CLEAN_CELLS = {
    "split": st.sampled_from(["test", "val"]),
    "set": st.sampled_from(["normal", "camera", "robot", "Normal", "nope", ""]),
    "index": st.integers(0, 10**6).map(str) | st.sampled_from(["007", "0" * 18]),
    "depth": st.floats(-1e3, 1e6).map(repr) | st.sampled_from(["0", "-0.0", "1e3", ".5", "3.", "+2", "1E-2"]),
    "benchmark": st.sampled_from(["odmd-v1", "odmd-paper"]),
    "note": st.sampled_from(["", "x y", "a;b", "1"]),
}
# Each turns a clean file into one the bulk pass must leave to the row-by-row pass (or not).
_EDITS = [
    lambda s: s,
    lambda s: s[:-2] + '"' + s[-2:],
    lambda s: s.replace("\n", "\n\n", 1),
    lambda s: s + "\n \n",
    lambda s: s[: s.index("\n") + 1] + s[s.index("\n") + 1 :].replace("\n", "\r", 1),  # a lone \r
    lambda s: s.replace("\n", "\n,,,,,,\n", 1),
    lambda s: s.replace(",", ",,", 2),
    lambda s: s.replace("test", " test", 1),
    lambda s: s.replace("normal", "normal\t", 1),
    lambda s: s.replace("test", "tëst", 1),
    lambda s: s.replace("0", "nan", 1),
    lambda s: s.replace("1", "1e999", 1),
    lambda s: s.replace("2", "2_0", 1),
    lambda s: s.replace(",1,", ",+1,", 1),
    lambda s: s.replace("4", "", 1),
    lambda s: s.replace("5", "x", 1),
    lambda s: s.replace("odmd-v1", "odmd-v2", 1),
    lambda s: s.replace("val", "train", 1),
]


@st.composite
def _prediction_files(draw: st.DrawFn) -> tuple[str, bool]:
    extra = draw(st.sampled_from([[], ["benchmark"], ["note"], ["benchmark", "note"]]))
    columns = draw(st.permutations(["split", "set", "index", "depth", *extra]))
    rows = draw(
        st.lists(st.tuples(*(_CLEAN_CELLS[c] for c in columns)).map(",".join), min_size=1, max_size=30)
    )
    end = draw(st.sampled_from(["\n", "\r\n"]))
    text = end.join([",".join(columns), *rows]) + draw(st.sampled_from([end, ""]))
    edit = draw(st.sampled_from(range(len(_EDITS))))
    return _EDITS[edit](text), edit == 0


@settings(max_examples=150, deadline=None)
@given(_prediction_files(), st.sampled_from([None, "odmd-v1"]))
def test_clean_files_read_in_bulk_give_what_row_by_row_gives(
    file: tuple[str, bool], benchmark: str | None
) -> None:
    text, clean = file
    fast, slow, bulk = _parse_both_ways(text.encode(), benchmark)
    assert fast == slow
    if clean:  # (an edited file may be clean too, or be left to the rows)
        assert bulk


_CLEAN = (
    "split,set,index,depth,benchmark,note\n"
    "test,normal,0,1.25,odmd-v1,a\ntest,camera,1,-0.5,odmd-v1,\nval,robot,12,3.0e2,odmd-v1,x y\n"
    "test,normal,4,0,odmd-v1,1\ntest,normal,5,7.,odmd-v1,b\n"
)


@pytest.mark.parametrize("edit", range(len(_EDITS)))
def test_each_unclean_row_is_left_to_the_row_by_row_pass(edit: int) -> None:
    fast, slow, bulk = _parse_both_ways(_EDITS[edit](_CLEAN).encode(), None)
    assert fast == slow
    assert bulk == (edit == 0)


def test_a_committed_entry_is_read_in_bulk_as_row_by_row() -> None:
    path = Path(__file__).resolve().parents[1] / "leaderboard/entries/box-ls/odmd-v1-test/predictions.csv.gz"
    fast, slow, bulk = _parse_both_ways(path.read_bytes(), None, block=50_000)  # 5 blocks
    assert bulk and fast == slow


# --- overflow and strict JSON -----------------------------------------------------


def test_huge_depths_are_refused_with_their_lines(data: Path, tmp_path: Path) -> None:
    depths = noisy()
    text = csv_text(depths).replace(f",{float(depths['object'][2])!r}\n", ",1e308\n")
    p = tmp_path / "huge.csv"
    p.write_text(text)
    with pytest.raises(ValidationError) as e:
        evaluate(p, benchmark=BENCH)
    assert e.value.problems == [
        f"depth is out of range (|depth| > 1e+12 m, where errors can overflow) (1 row): line "
        f"{2 + N['normal'] + N['camera'] + 2} ('1e308')"
    ]


def test_largest_accepted_depth_scores_finite_strict_json(data: Path, tmp_path: Path) -> None:
    depths = noisy()
    depths["robot"][0] = -MAX_ABS_DEPTH
    depths["object"][:] = MAX_ABS_DEPTH
    r = odmd_bench.score(BENCH, "test", depths)
    text = format_json(r)
    json.loads(text, parse_constant=lambda c: pytest.fail(f"non-JSON constant {c}"))
    assert np.isfinite(r.all_percent_error_mean)
    json.loads(format_comparison(compare_results(r, r), "json"))


# --- arrays: odmd_bench.score --------------------------------------------------------


def test_score_of_arrays_equals_evaluate_of_their_csv(data: Path, tmp_path: Path) -> None:
    depths = noisy(1)
    p = tmp_path / "p.csv"
    odmd_bench.write_predictions(p, "test", depths)
    from_file = odmd_bench.evaluate(p, benchmark=BENCH)
    from_arrays = odmd_bench.score(BENCH, "test", depths, name="p.csv")
    assert from_arrays.to_dict() == from_file.to_dict()
    lists = odmd_bench.score(BENCH, "test", {s: d.astype(np.float32).tolist() for s, d in depths.items()})
    assert lists.sets["robot"]["n"] == N["robot"]


def test_score_of_arrays_names_every_problem(data: Path) -> None:
    depths: dict[str, object] = dict(noisy())
    depths["normal"] = np.array([1.0, np.nan, 2.0, np.inf, 3.0, 1e300])
    depths["camera"] = np.ones((5, 1))
    depths["object"] = ["1", "2", "3", "4"]
    del depths["robot"]
    depths["robt"] = np.ones(3)
    with pytest.raises(ValidationError) as e:
        odmd_bench.score(BENCH, "test", depths)
    got = e.value.problems
    assert "depth is NaN or infinite (2 values): normal 1 (nan), normal 3 (inf)" in got
    assert any(q.startswith("depth is out of range") and "normal 5 (1e+300)" in q for q in got)
    assert "set 'camera': the depths must be a 1-D array in index order, got shape (5, 1)" in got
    assert any(q.startswith("set 'object': the depths must be real numbers") for q in got)
    assert any(q.startswith("unknown set 'robt'") and "did you mean 'robot'" in q for q in got)
    assert any(q.startswith("set 'robot' of benchmark 'odmd-paper' has no depths") for q in got)
    assert any("e.g. sets=['normal', 'camera', 'object'])" in q for q in got), got
    short = dict(noisy())
    short["robot"] = short["robot"][:-1]
    with pytest.raises(ValidationError, match="set 'robot' has 3 examples but 2 depths were given"):
        odmd_bench.score(BENCH, "test", short)


def test_score_of_arrays_subset_and_warnings(data: Path) -> None:
    depths = noisy()
    depths["robot"][1] = -2.0
    r = odmd_bench.score(BENCH, "test", depths, sets=["robot"])
    assert list(r.sets) == ["robot"]
    assert r.warnings[0] == "1 depth is zero or negative (scored as given): robot 1: -2.0"
    assert r.warnings[1].startswith("ignored depths of sets not asked for: normal (6 values)")
    with pytest.raises(UsageError):
        odmd_bench.score(BENCH, "tset", depths)
    with pytest.raises(UsageError, match="mapping"):
        odmd_bench.score(BENCH, "test", [1.0])  # type: ignore[arg-type]


# --- pandas ----------------------------------------------------------------------------


def test_frames(data: Path) -> None:
    pd = pytest.importorskip("pandas")
    r = odmd_bench.score(BENCH, "test", noisy())
    frame = r.to_frame()
    assert list(frame.index) == [*N, "All"]
    assert frame.loc["robot", "percent_error_max"] == r.sets["robot"]["percent_error"]["max"]
    assert frame.loc["All", "percent_error_mean"] == r.all_percent_error_mean
    assert frame.loc["All", "n"] == sum(N.values()) and pd.isna(frame.loc["All", "percent_error_std"])
    per = r.per_example_frame()
    assert len(per) == sum(N.values())
    errors = r.percent_errors()
    assert np.array_equal(per.loc[per["set"] == "camera", "percent_error"].to_numpy(), errors["camera"])
    assert per.groupby("set", sort=False)["percent_error"].mean().to_dict() == pytest.approx(
        {s: m["percent_error"]["mean"] for s, m in r.sets.items()}, rel=1e-12
    )


def test_score_stage_matches_evaluate(data: Path, tmp_path: Path) -> None:
    """The stages composed by hand give evaluate's result (the leaderboard's path)."""
    p = tmp_path / "p.csv.gz"
    p.write_bytes(gzip.compress(csv_text(noisy(2)).encode()))
    examples = odmd_bench.load_split("test", BENCH)
    parsed = parse_predictions(p.read_bytes(), name=p.name, benchmark=BENCH, strict=False)
    preds = check_coverage(parsed, {s: len(ex) for s, ex in examples.items()})
    assert score(preds, examples).to_dict() == evaluate(p, benchmark=BENCH).to_dict()
