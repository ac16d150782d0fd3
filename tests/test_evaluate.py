"""Validation and scoring of predictions files (docs/format.md, "Predictions" and "Metrics").

Most tests use tiny sets written into a temporary ``odmd-paper`` folder (an imported
benchmark, so no manifest pins them); the last test scores Box_LS on the real imported
``odmd-paper`` test sets against the paper's numbers.
"""

from __future__ import annotations

import contextlib
import csv
import hashlib
import io
import os
import string
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import odmd_bench
from odmd_bench import Examples, OdmdError, UsageError, ValidationError, fill_missing
from odmd_bench.data.io import write_sets
from odmd_bench.data.registry import get_benchmark, set_file
from odmd_bench.evaluation.coverage import check_coverage
from odmd_bench.evaluation.parse import parse_predictions
from odmd_bench.evaluation.predictions import write_predictions
from odmd_bench.evaluation.scoring import SHOWN, EvaluationResult, evaluate
from odmd_bench.inputs.records import records

BENCH = "odmd-paper"


def own(r: EvaluationResult) -> tuple[str, ...]:
    """The warnings about the predictions, without the one about the module's unpinned sets."""
    return tuple(w for w in r.warnings if "not the pinned version" not in w)


SIZES = {
    "test": {"normal": 7, "camera": 5, "object": 6, "robot": 4},
    "val": {s: 3 for s in ("normal", "camera", "object", "robot")},
}
PERTURB = {"normal": "normal", "camera": "camera", "object": "object", "robot": "both"}


@pytest.fixture(scope="module")
def sets_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    data = tmp_path_factory.mktemp("eval-data")
    for k, (split, sizes) in enumerate(SIZES.items()):
        sets = {
            s: odmd_bench.generate(n, perturbation=PERTURB[s], rng=10 * k + i)
            for i, (s, n) in enumerate(sizes.items())
        }
        write_sets(
            set_file(get_benchmark(BENCH), split, data), sets, file_attrs={"benchmark": BENCH, "split": split}
        )
    return data


@pytest.fixture()
def data(sets_dir: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setenv("ODMD_BENCH_DATA", str(sets_dir))
    return sets_dir


def truth(split: str = "test") -> dict[str, np.ndarray]:
    return {s: ex.depth for s, ex in odmd_bench.load_split(split, BENCH).items()}


def rows(split: str = "test", depths: dict[str, np.ndarray] | None = None) -> list[str]:
    depths = depths if depths is not None else truth(split)
    return [f"{split},{s},{i},{v!r}" for s, d in depths.items() for i, v in enumerate(d.tolist())]


def write(tmp_path: Path, text: str | bytes, name: str = "p.csv") -> Path:
    p = tmp_path / name
    p.write_bytes(text.encode() if isinstance(text, str) else text)
    return p


def problems_of(path: Path, **kw: object) -> list[str]:
    with pytest.raises(ValidationError) as e:
        evaluate(path, benchmark=BENCH, **kw)  # type: ignore[arg-type]
    return e.value.problems


# --- correctness ----------------------------------------------------------------


def test_ground_truth_scores_exactly_zero_everywhere(data: Path, tmp_path: Path) -> None:
    p = tmp_path / "gt.csv"
    write_predictions(p, "test", truth())
    r = evaluate(p, benchmark=BENCH)
    assert list(r.sets) == ["normal", "camera", "object", "robot"]
    for s, m in r.sets.items():
        assert m["n"] == SIZES["test"][s]
        for err in ("percent_error", "absolute_error"):
            assert m[err] == {"mean": 0.0, "median": 0.0, "min": 0.0, "max": 0.0, "std": 0.0}
    assert r.all_percent_error_mean == 0.0
    # The module's sets are written here, not imported from the release: scored, and marked.
    assert r.warnings == (
        f"{BENCH} test normal, camera, object, robot: not the pinned version of the benchmark (imported "
        "with --allow-unknown, or written by other means); these scores do not compare with the paper's "
        "or the leaderboard's",
    )
    assert r.provenance["unpinned_sets"] == ["normal", "camera", "object", "robot"]


def test_shuffling_rows_changes_nothing(data: Path, tmp_path: Path) -> None:
    rng = np.random.default_rng(0)
    depths = {s: d * rng.uniform(0.5, 1.5, d.shape) for s, d in truth().items()}
    body = rows(depths=depths)
    a = evaluate(
        write(tmp_path, "split,set,index,depth\n" + "\n".join(body) + "\n", "a.csv"), benchmark=BENCH
    )
    shuffled = [body[i] for i in rng.permutation(len(body))]
    b = evaluate(
        write(tmp_path, "split,set,index,depth\n" + "\n".join(shuffled) + "\n", "b.csv"), benchmark=BENCH
    )
    assert a.sets == b.sets
    assert a.all_percent_error_mean == b.all_percent_error_mean
    assert a.provenance["predictions_sha256"] != b.provenance["predictions_sha256"]
    for s in depths:
        assert np.array_equal(a.predictions[s], depths[s])  # read back bit for bit


def _tiny(depth: list[float]) -> Examples:
    n = len(depth)
    return Examples(
        boxes=np.full((n, 2, 4), 0.1),
        detected=np.ones((n, 2), dtype=bool),
        camera=np.zeros((n, 2, 3)),
        depth=np.array(depth),
    )


def test_hand_computed_small_case(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    data = tmp_path / "data"
    write_sets(
        set_file(get_benchmark(BENCH), "val", data),
        {
            "normal": _tiny([2.0, 4.0]),
            "camera": _tiny([1.0]),
            "object": _tiny([0.5, 1.0]),
            "robot": _tiny([8.0]),
        },
    )
    monkeypatch.setenv("ODMD_BENCH_DATA", str(data))
    text = (
        "split,set,index,depth\n"
        "val,normal,0,1.0\nval,normal,1,5.0\n"  # 50 %, 25 %
        "val,camera,0,1.0\n"  # 0 %
        "val,object,1,0.75\nval,object,0,-0.5\n"  # 25 %, 200 % (a negative estimate)
        "val,robot,0,10.0\n"  # 25 %
    )
    r = evaluate(write(tmp_path, text), benchmark=BENCH)
    assert r.sets["normal"]["percent_error"] == {
        "mean": 37.5,
        "median": 37.5,
        "min": 25.0,
        "max": 50.0,
        "std": 12.5,
    }
    assert r.sets["normal"]["absolute_error"] == {
        "mean": 1.0,
        "median": 1.0,
        "min": 1.0,
        "max": 1.0,
        "std": 0.0,
    }
    assert r.sets["camera"]["percent_error"]["mean"] == 0.0
    assert r.sets["object"]["percent_error"] == {
        "mean": 112.5,
        "median": 112.5,
        "min": 25.0,
        "max": 200.0,
        "std": 87.5,
    }
    assert r.sets["object"]["absolute_error"]["max"] == 1.0
    assert r.sets["robot"]["absolute_error"]["mean"] == 2.0
    assert r.all_percent_error_mean == (37.5 + 0.0 + 112.5 + 25.0) / 4 == 43.75
    assert len(own(r)) == 1 and "1 depth is zero or negative" in r.warnings[0] and "line 6" in r.warnings[0]


def test_provenance(data: Path, tmp_path: Path) -> None:
    p = tmp_path / "gt.csv"
    write_predictions(p, "test", truth())
    r = evaluate(p, benchmark=BENCH)
    prov = r.to_dict()["provenance"]
    assert prov["predictions_sha256"] == hashlib.sha256(p.read_bytes()).hexdigest()
    assert prov["version"] == odmd_bench.__version__
    assert (prov["benchmark"], prov["split"]) == (BENCH, "test")
    loaded = odmd_bench.load_split("test", BENCH)
    assert prov["sets_content_sha256"] == {s: ex.attrs["content_sha256"] for s, ex in loaded.items()}
    d = r.to_dict()
    assert {"benchmark", "split", "sets", "all", "provenance"} <= set(d)
    assert set(d["sets"]["normal"]) >= {"n", "percent_error", "absolute_error"}
    assert d["all"]["percent_error_mean"] == 0.0


# --- what is accepted ------------------------------------------------------------


def test_bom_crlf_extra_columns_quotes_blank_lines_benchmark_column(data: Path, tmp_path: Path) -> None:
    body = [f'"{r.split(",")[0]}",{r},note {i},{BENCH}' for i, r in enumerate(rows())]
    # columns: a quoted extra column first, the benchmark column last
    text = "\ufeffextra,split,set,index,depth,comment,benchmark\r\n" + "\r\n".join(body) + "\r\n\r\n"
    p = write(tmp_path, text)
    before = p.read_bytes()
    r = evaluate(p)  # benchmark from the column
    assert r.benchmark == BENCH and r.all_percent_error_mean == 0.0
    assert r.provenance["ignored_columns"] == ["extra", "comment"]
    assert p.read_bytes() == before


def test_utf16_with_bom_is_read(data: Path, tmp_path: Path) -> None:
    text = "split,set,index,depth\n" + "\n".join(rows()) + "\n"
    r = evaluate(write(tmp_path, text.encode("utf-16")), benchmark=BENCH)
    assert r.all_percent_error_mean == 0.0


def test_zero_and_negative_depths_are_scored_and_warned(data: Path, tmp_path: Path) -> None:
    depths = truth()
    depths["object"] = depths["object"].copy()
    depths["object"][:3] = [0.0, -1.0, -0.0]
    r = evaluate(write(tmp_path, "split,set,index,depth\n" + "\n".join(rows(depths=depths))), benchmark=BENCH)
    assert r.sets["object"]["percent_error"]["max"] > 100.0
    assert np.array_equal(r.predictions["object"][:3], [0.0, -1.0, 0.0])
    assert len(own(r)) == 1 and r.warnings[0].startswith("3 depths are zero or negative")


@pytest.mark.parametrize(
    ("factor", "expected"),
    [
        (
            1000.0,
            "a median 1000 times the true depths: depths are in metres; were they written in millimetres?",
        ),
        (97.0, "a median 97 times the true depths: depths are in metres; were they written in centimetres?"),
        (0.001, "were they written in kilometres?"),
        (30.0, "a median 30 times the true depths: depths are in metres (scored as given)"),
        (5.0, None),
        (0.2, None),
    ],
)
def test_depths_in_another_unit_are_warned(
    data: Path, tmp_path: Path, factor: float, expected: str | None
) -> None:
    p = tmp_path / "p.csv"
    write_predictions(p, "test", {s: d * factor for s, d in truth().items()}, benchmark=BENCH)
    result = evaluate(p)
    units = [w for w in result.warnings if "times the true depths" in w]
    assert len(units) == (expected is not None), units
    assert expected is None or expected in units[0]
    assert result.all_percent_error_mean == pytest.approx(abs(factor - 1) * 100)  # scored as given


def test_sets_subset(data: Path, tmp_path: Path) -> None:
    t = truth()
    only = {"robot": t["robot"], "normal": t["normal"]}
    p = write(tmp_path, "split,set,index,depth\n" + "\n".join(rows(depths=only)))
    problems = problems_of(p)
    assert [q for q in problems if "has no rows" in q][0].startswith("set 'camera'")
    assert any("--sets normal,object,robot" in q for q in problems if "'camera'" in q)
    r = evaluate(p, benchmark=BENCH, sets=["robot", "normal"])
    assert list(r.sets) == ["normal", "robot"]  # benchmark order
    assert r.to_dict()["all"]["sets"] == ["normal", "robot"]
    # a full file scored on a subset: the other rows are ignored, with a warning
    full = write(tmp_path, "split,set,index,depth\n" + "\n".join(rows()), "full.csv")
    r = evaluate(full, benchmark=BENCH, sets=["camera"])
    assert list(r.sets) == ["camera"] and "ignored rows" in r.warnings[0]
    with pytest.raises(UsageError, match="unknown set 'robt'.*did you mean 'robot'"):
        evaluate(full, benchmark=BENCH, sets=["robt"])


def test_a_set_whose_rows_all_failed_is_not_told_to_use_sets(data: Path, tmp_path: Path) -> None:
    # --sets would not help: those rows are checked anyway. Say what would.
    floats = [
        r.replace(f",{r.split(',')[2]},", f",{r.split(',')[2]}.0,") if ",robot," in r else r for r in rows()
    ]
    problems = problems_of(write(tmp_path, HEADER + "\n".join(floats)))
    assert (
        "set 'robot' of benchmark 'odmd-paper' has no usable row (each of its rows has a problem)" in problems
    )
    assert not any("--sets" in q for q in problems)
    renamed = [r.replace(",camera,", ",perturb_motion,") for r in rows()]  # the original release's name
    problems = problems_of(write(tmp_path, HEADER + "\n".join(renamed)))
    assert any("('perturb_motion': did you mean 'camera'?)" in q for q in problems), problems
    assert (
        "set 'camera' of benchmark 'odmd-paper' has no rows (check the set names refused above)" in problems
    )


def test_rows_of_sets_left_out_are_still_checked(data: Path, tmp_path: Path) -> None:
    """A file is refused or not whatever --sets says.

    Rows of the other sets are checked like any row, their indices against the sizes
    pinned in splits/ (the robot test set of odmd-paper: 3000 examples), and only then
    ignored.
    """
    body = "split,set,index,depth\n" + "\n".join(rows())
    bad = write(tmp_path, body + "\ntest,robot,3000,1.0\ntest,object,-1,1.0\ntest,robot,0,nan\n")
    problems = problems_of(bad, sets=["camera"])
    ranged = [q for q in problems if q.startswith("index out of range")]
    assert len(ranged) == 1 and "(2 rows)" in ranged[0], problems
    assert "robot 3000; robot has 3000 examples" in ranged[0] and "object -1" in ranged[0]
    assert any(q.startswith("depth is NaN") for q in problems), problems
    # within the pinned sizes they are ignored, as before
    ok = write(tmp_path, body + "\ntest,robot,2999,1.0\n", "ok.csv")
    r = evaluate(ok, benchmark=BENCH, sets=["camera"])
    assert list(r.sets) == ["camera"] and any("ignored rows" in w for w in r.warnings)


def test_file_is_never_modified(data: Path, tmp_path: Path) -> None:
    for text in ("split,set,index,depth\n" + "\n".join(rows()), "split,set,index,depth\ntest,normal,0,x\n"):
        p = write(tmp_path, text)
        os.utime(p, (1_000_000_000, 1_000_000_000))
        before = p.read_bytes()
        with contextlib.suppress(ValidationError):
            evaluate(p, benchmark=BENCH)
        assert p.read_bytes() == before and p.stat().st_mtime == 1_000_000_000
        assert sorted(x.name for x in tmp_path.iterdir()) == ["p.csv"]


# --- what is refused ------------------------------------------------------------


HEADER = "split,set,index,depth\n"


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        (b"", "the file is empty"),
        (b"  \n\n", "the file is empty"),
        (b"\x89PNG\r\n\x1a\n\x00\x00\x00", "binary"),
        ("split,set,index,depth\ntest,normal,0,1.0\n".encode("latin-1") + b"\xe9\n", "not UTF-8"),
        (HEADER, "header but no rows"),
        (
            "split,set,index,Depth\ntest,normal,0,1\n",
            "missing column 'depth' (the header has 'Depth': misspelt?)",
        ),
        ("split,set,idx,depht\ntest,normal,0,1\n", "missing column 'depth' (the header has 'depht'"),
        ("split;set;index;depth\ntest;normal;0;1\n", "semicolons"),
        (
            "sequence,observation,x1,y1,x2,y2,cam_x,cam_y,cam_z\na,1,1,1,9,9,0,0,0\n",
            "this is a sequences file (boxes and camera motion for `odmd-bench predict`)",
        ),
        ("split,set,index,depth,depth\ntest,normal,0,1,1\n", "column 'depth' appears more than once"),
        ('split,set,index,depth\ntest,"normal,0,1\n', "not valid CSV"),
        # a quote never closed, early in a long file: named where it opens, not where the
        # CSV reader's field limit stops it thousands of lines later
        (
            HEADER + 'test,normal,0,1\ntest,normal,1,"1\n' + "test,normal,2,1\n" * 20000,
            "not valid CSV: a quote opened after line 2 is never closed",
        ),
    ],
)
def test_unreadable_files(data: Path, tmp_path: Path, text: str | bytes, expected: str) -> None:
    problems = problems_of(write(tmp_path, text))
    assert any(expected in q for q in problems), problems


def test_missing_file_and_folder(data: Path, tmp_path: Path) -> None:
    assert "no such file" in problems_of(tmp_path / "nope.csv")[0]
    assert "is a folder" in problems_of(tmp_path)[0]


def _replace(body: list[str], line: int, new: str) -> list[str]:
    """Replace data row ``line`` (file line numbers: header is 1)."""
    out = list(body)
    out[line - 2] = new
    return out


@pytest.mark.parametrize(
    ("line", "new", "expected"),
    [
        (3, "test,normal,1,abc", "depth is not a number (1 row): line 3 ('abc')"),
        (3, "test,normal,1,", "depth is not a number (1 row): line 3 ('')"),
        (3, "test,normal,1,nan", "depth is NaN or infinite (1 row): line 3 ('nan')"),
        (3, "test,normal,1,-Infinity", "depth is NaN or infinite"),
        (3, "test,normal,1,1e400", "depth is too large to be a finite float64"),
        (3, "test,normal,1,1_0", "depth is not a number"),
        (3, "test,normal,1,0x1p3", "depth is not a number"),
        (3, "test,normal,1.0,1", "index is not an integer (1 row): line 3 ('1.0')"),
        (3, "test,normal,one,1", "index is not an integer"),
        (
            3,
            "test,nromal,1,1",
            "unknown set for benchmark 'odmd-paper' (1 row): line 3 ('nromal': did you mean 'normal'?)",
        ),
        (3, "test,Normal,1,1", "did you mean 'normal'?"),
        (
            3,
            "tset,normal,1,1",
            "unknown split in column 'split' (1 row): line 3 ('tset': did you mean 'test'?)",
        ),
        (3, "test,normal,1", "wrong number of fields (1 row): line 3 (3 fields)"),
        (3, "test,normal,1,1,1", "wrong number of fields"),
        (3, "test,normal,0,1", "duplicate (set, index) (1 row): line 3 repeats line 2 (normal 0)"),
        (
            3,
            "test,normal,7,1",
            "index out of range (1 row): line 3 (normal 7; normal has 7 examples, indices 0..6)",
        ),
        (3, "test,normal,-1,1", "index out of range"),
        (3, "test,normal,123456789012345678901234567890,1", "index out of range"),
    ],
)
def test_each_problem_is_named_with_its_line(
    data: Path, tmp_path: Path, line: int, new: str, expected: str
) -> None:
    problems = problems_of(write(tmp_path, HEADER + "\n".join(_replace(rows(), line, new)) + "\n"))
    assert any(expected in q for q in problems), problems


def test_missing_examples_are_listed(data: Path, tmp_path: Path) -> None:
    body = [r for r in rows() if not r.startswith(("test,object,2,", "test,object,4,"))]
    problems = problems_of(write(tmp_path, HEADER + "\n".join(body)))
    assert problems == ["2 of the 6 examples of set 'object' have no row (missing indices 2, 4)"]


def test_mixed_splits(data: Path, tmp_path: Path) -> None:
    body = rows()
    body[5] = body[5].replace("test,", "val,", 1)
    problems = problems_of(write(tmp_path, HEADER + "\n".join(body)))
    assert any(
        q.startswith("a file holds one split, this one has 2: test (21 rows")
        and "val (1 row, first on line 7)" in q
        for q in problems
    )


def test_mixed_and_conflicting_benchmarks(data: Path, tmp_path: Path) -> None:
    body = [r + f",{BENCH}" for r in rows()]
    body[0] = body[0].replace(BENCH, "odmd-v1")
    p = write(tmp_path, "split,set,index,depth,benchmark\n" + "\n".join(body))
    with pytest.raises(ValidationError) as e:
        evaluate(p)
    assert any("a file holds one benchmark, this one has 2" in q for q in e.value.problems)
    body = [r + ",odmd-v1" for r in rows()]
    p = write(tmp_path, "split,set,index,depth,benchmark\n" + "\n".join(body))
    assert any(
        "the file's benchmark column says 'odmd-v1' but --benchmark is 'odmd-paper'" in q
        for q in problems_of(p)
    )
    body = [r + ",odmd-v2" for r in rows()]
    p = write(tmp_path, "split,set,index,depth,benchmark\n" + "\n".join(body))
    assert any(q.startswith("unknown benchmark in column 'benchmark' (22 rows)") for q in problems_of(p))


def test_all_problems_in_one_pass_with_counts(data: Path, tmp_path: Path) -> None:
    body = rows()
    for i in range(8):  # 8 bad depths: 5 shown, "3 more"
        body[i] = body[i].rsplit(",", 1)[0] + ",oops"
    body[10] = "test,normal,1.5,1"
    body[11] = "test,robt,0,1"
    body.append(body[15])
    text = HEADER + "\n".join(body)
    problems = problems_of(write(tmp_path, text))
    assert problems[0] == (
        "depth is not a number (8 rows): line 2 ('oops'), line 3 ('oops'), line 4 ('oops'), "
        "line 5 ('oops'), line 6 ('oops'), ... (3 more)"
    )
    assert len(problems) == 5  # depth, index, set, duplicate, missing
    assert any(q.startswith("index is not an integer (1 row): line 12") for q in problems)
    assert any(q.startswith("duplicate (set, index) (1 row): line 24 repeats line 17") for q in problems)
    assert SHOWN == 5


def test_unknown_benchmark_argument(data: Path, tmp_path: Path) -> None:
    with pytest.raises(UsageError, match="unknown benchmark 'odmd-v9'"):
        evaluate(write(tmp_path, HEADER + "\n".join(rows())), benchmark="odmd-v9")


# --- property tests: never anything but the package's own error -------------------


def _sizes(bench: str, split: str) -> dict[str, int]:
    return (
        dict(SIZES[split])
        if bench == BENCH
        else {s: 3 for s in odmd_bench.data.registry.get_benchmark(bench).sets}
    )


def _check_never_crashes(tmp_path: Path, data: bytes) -> None:
    p = tmp_path / "h.csv"
    p.write_bytes(data)
    try:
        parsed = parse_predictions(p, benchmark=BENCH, strict=False)
        if parsed.benchmark is None or parsed.split is None:
            raise parsed.problems.error(parsed.name)
        preds = check_coverage(parsed, _sizes(parsed.benchmark, parsed.split))
    except OdmdError:
        return
    for s, d in preds.depths.items():
        assert d.shape == (SIZES[preds.split][s],) and np.isfinite(d).all()


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.binary(max_size=300))
def test_arbitrary_bytes_raise_only_package_errors(tmp_path: Path, data: bytes) -> None:
    _check_never_crashes(tmp_path, data)


_cells = {
    "split": st.sampled_from(["test", "val", "tst", "", " test ", "TEST"]),
    "set": st.sampled_from(["normal", "camera", "object", "robot", "nromal", "", '"robot"']),
    "index": st.one_of(
        st.integers(-2, 9).map(str), st.sampled_from(["1.0", "x", "", "+3", "007", "9" * 30, "٣"])
    ),
    "depth": st.one_of(
        st.floats(allow_nan=True, allow_infinity=True).map(repr),
        st.sampled_from(["", "abc", "1e400", "-0", ".5", "5.", "1,5", '"1.5"', "0x10", "1_0"]),
        st.text(string.printable, max_size=5),
    ),
}


@st.composite
def near_valid_csv(draw: st.DrawFn) -> bytes:
    names = ["split", "set", "index", "depth"]
    header = draw(st.permutations(names))
    if draw(st.booleans()):
        header = [*header, draw(st.sampled_from(["benchmark", "extra", "depth", "Depth", "dpeth"]))]
    if draw(st.booleans()) and len(header) > 1:
        header = header[: draw(st.integers(1, len(header) - 1))]
    n = draw(st.integers(0, 12))
    lines = [",".join(header)]
    for _ in range(n):
        cells = []
        for h in header:
            if h in _cells:
                cells.append(draw(_cells[h]))
            elif h == "benchmark":
                cells.append(draw(st.sampled_from([BENCH, "odmd-v1", "odms-detection", "x"])))
            else:
                cells.append(draw(st.text(string.printable, max_size=4)))
        if draw(st.integers(0, 9)) == 0:
            cells = cells[:-1]
        lines.append(",".join(cells))
    eol = draw(st.sampled_from(["\n", "\r\n", "\r"]))
    text = eol.join(lines) + draw(st.sampled_from(["", eol, eol + eol]))
    bom = draw(st.sampled_from(["", "\ufeff"]))
    return (bom + text).encode(draw(st.sampled_from(["utf-8", "utf-16"])), errors="replace")


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(near_valid_csv())
def test_near_valid_csvs_raise_only_package_errors(tmp_path: Path, data: bytes) -> None:
    _check_never_crashes(tmp_path, data)


def _reference_records(text: str) -> list[tuple[int, list[str]]] | str:
    """What ``records`` must give: the csv module read line by line, blank records dropped."""
    reader = csv.reader(io.StringIO(text, newline=""), strict=True)
    out = []
    try:
        for record in reader:
            cells = [c.strip() for c in record]
            if any(cells):
                out.append((reader.line_num, cells))
    except csv.Error:
        return "error"
    return out


@settings(max_examples=300, deadline=None)
@given(
    st.lists(
        st.sampled_from(["a", "b,c", " ", ",", "\t", "\n", "\r", "\r\n", "\n\n", " ,\t\n", ",a"]),
        max_size=30,
    )
)
def test_blank_runs_are_skipped_with_the_line_numbers_of_a_plain_reader(parts: list[str]) -> None:
    # records() passes over runs of blank lines in one match (a file of millions of them
    # is refused in a second); records and line numbers are the csv module's own.
    text = "".join(parts)
    assert list(records(text, "t")) == _reference_records(text)


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ('a,b\n"c,d\n\n\n', "a quote opened after line 1 is never closed"),
        ('a,b\n\n\r\n , \n"c"x,d\n', "line 5: not valid CSV"),
        ("a\n" + "\n" * 100_000 + '"x', "a quote opened after line 1 is never closed"),
    ],
)
def test_csv_errors_after_blank_runs_name_the_right_line(text: str, expected: str) -> None:
    with pytest.raises(ValidationError, match=expected):
        list(records(text, "t"))


def test_millions_of_blank_lines_are_refused_as_a_file_without_rows(data: Path, tmp_path: Path) -> None:
    p = tmp_path / "blank.csv"
    p.write_text(HEADER + " ,\t,\n" * 2_000_000 + "\r\n" * 2_000_000)
    with pytest.raises(ValidationError, match="the file has a header but no rows"):
        evaluate(p, benchmark=BENCH)
    p.write_text(HEADER + "\n" * 2_000_000 + "test,normal,0,abc\n" + "\n".join(rows()[1:]))
    with pytest.raises(ValidationError, match="line 2000002 \\('abc'\\)"):  # counted past the blank run
        evaluate(p, benchmark=BENCH)


# --- the paper's numbers ---------------------------------------------------------


def box_ls(ex: Examples) -> np.ndarray:
    """The paper's Box_LS, per example with np.linalg.lstsq.

    Computed here on purpose (independently of ``baselines/``): A x = b with rows
    ``[w_j, 1, 0]``, ``[h_j, 0, 1]`` and ``b_j = w_j C_Zj``, ``h_j C_Zj`` (camera relative
    to the last observation); missing boxes filled by the shared rule; depth 0 with at
    most one detection.
    """
    b = fill_missing(ex.boxes, ex.detected)
    n, k = len(ex), ex.n_obs
    w, h, cz = b[:, :, 2], b[:, :, 3], ex.camera[:, :, 2]
    a = np.zeros((n, 2 * k, 3))
    rhs = np.zeros((n, 2 * k))
    a[:, 0::2, 0], a[:, 0::2, 1], a[:, 1::2, 0], a[:, 1::2, 2] = w, 1.0, h, 1.0
    rhs[:, 0::2], rhs[:, 1::2] = w * cz, h * cz
    z = np.array([np.linalg.lstsq(a[i], rhs[i], rcond=None)[0][0] for i in range(n)])
    return np.where(ex.detected.sum(axis=1) <= 1, 0.0, z)


def test_box_ls_on_odmd_paper_test_scores_the_papers_numbers(paper_data_dir: Path, tmp_path: Path) -> None:
    sets = odmd_bench.load_split("test", BENCH, paper_data_dir)
    p = tmp_path / "box_ls.csv"
    write_predictions(p, "test", {s: box_ls(ex) for s, ex in sets.items()}, benchmark=BENCH)
    r = evaluate(p, data_dir=paper_data_dir)
    pe = {s: m["percent_error"] for s, m in r.sets.items()}
    assert {s: round(m["mean"], 2) for s, m in pe.items()} == {
        "normal": 0.00,
        "camera": 4.47,
        "object": 21.60,
        "robot": 21.23,
    }
    paper = {"camera": (3.13, 43.02, 4.57), "object": (8.90, 158.04, 28.27), "robot": (12.17, 262.48, 26.92)}
    for s, (median, mx, std) in paper.items():
        assert (round(pe[s]["median"], 2), round(pe[s]["max"], 2), round(pe[s]["std"], 2)) == (
            median,
            mx,
            std,
        )
    assert round(r.all_percent_error_mean, 2) == 11.83
    # The paper's numbers include negative estimates, scored as given (86 on object).
    negative = {s: int((r.predictions[s] < 0).sum()) for s in r.sets}
    assert negative["object"] == 86
    assert "zero or negative" in r.warnings[0]


def test_box_ls_baseline_file_scores_the_papers_numbers(paper_data_dir: Path, tmp_path: Path) -> None:
    """End to end: the shipped baseline writes the file, the CLI scores it."""
    import json

    from click.testing import CliRunner

    from odmd_bench.cli.main import cli

    out = tmp_path / "box_ls.csv"
    data = ["--benchmark", "odmd-paper", "--data-dir", str(paper_data_dir)]
    made = CliRunner().invoke(cli, ["baseline", "box-ls", "--split", "test", "-o", str(out), *data])
    assert made.exit_code == 0, made.output
    scored = CliRunner().invoke(cli, ["evaluate", str(out), "--format", "json", *data])
    assert scored.exit_code == 0, scored.output
    d = json.loads(scored.stdout)
    means = {s: round(m["percent_error"]["mean"], 2) for s, m in d["sets"].items()}
    assert means == {"normal": 0.00, "camera": 4.47, "object": 21.60, "robot": 21.23}
    assert round(d["all"]["percent_error_mean"], 2) == 11.83
    pe = d["sets"]["object"]["percent_error"]
    assert (round(pe["median"], 2), round(pe["max"], 2), round(pe["std"], 2)) == (8.90, 158.04, 28.27)


def test_indices_counted_from_one_are_named(data: Path, tmp_path: Path) -> None:
    shifted = [f"{split},{s},{int(i) + 1},{v}" for split, s, i, v in (r.split(",") for r in rows())]
    problems = problems_of(write(tmp_path, "split,set,index,depth\n" + "\n".join(shifted) + "\n"))
    named = [q for q in problems if "counted from 1" in q]
    assert len(named) == 4 and named[0] == (
        "set 'normal': the indices run 1..7, counted from 1; the format counts from 0 "
        "(0..6, the examples' order in the set): subtract 1 from every index"
    )
    # one index too large is not the same mistake
    last = rows()
    last[3] = last[3].replace("test,normal,3,", "test,normal,7,")
    problems = problems_of(write(tmp_path, "split,set,index,depth\n" + "\n".join(last) + "\n"))
    assert not [q for q in problems if "counted from 1" in q] and any(
        "index out of range" in q for q in problems
    )
