"""The sequences format (pixels and odometry) and ``odmd-bench predict``."""

from __future__ import annotations

import csv
import dataclasses
import gzip
import io
import math
import types
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner, Result

import odmd_bench
from odmd_bench import DataError, Examples, UsageError, ValidationError, methods, predict
from odmd_bench.cli.main import cli
from odmd_bench.data.pixels import boxes_to_corners
from odmd_bench.evaluation.metrics import set_metrics
from odmd_bench.predict import sequences

SIZE = (640, 480)
K = ("--intrinsics", "205.5", "205.5", "320.5", "240.5")
DOCS = Path(__file__).resolve().parents[1] / "docs"


def _with_misses(ex: Examples, rate: float, seed: int) -> Examples:
    """``ex`` with a fraction of its detections removed (zero boxes, as stored)."""
    det = np.random.default_rng(seed).random(ex.detected.shape) >= rate
    return dataclasses.replace(ex, detected=det, boxes=np.where(det[..., None], ex.boxes, 0.0))


def _examples(n: int = 200, seed: int = 0) -> Examples:
    return _with_misses(odmd_bench.generate(n, perturbation="both", rng=seed), 0.05, seed)


def _read(text: str, **kw: object) -> sequences.Sequences:
    return sequences.read_sequences(text.encode(), SIZE, **kw)  # type: ignore[arg-type]


def _problems(text: str) -> ValidationError:
    with pytest.raises(ValidationError) as info:
        _read(text)
    return info.value


def _csv_rows(text: str) -> list[dict[str, str]]:
    return list(csv.DictReader(io.StringIO(text)))


# --- conversion --------------------------------------------------------------------------------


def test_a_generated_set_goes_to_the_csv_and_back_with_the_same_arrays() -> None:
    ex = _examples(300)
    back = _read(sequences.format_sequences(ex)).examples()
    assert back.n_obs == ex.n_obs and len(back) == len(ex)
    np.testing.assert_array_equal(back.detected, ex.detected)
    # Boxes go through pixels and back: equal to rounding; missed ones are zero as stored.
    np.testing.assert_allclose(back.boxes, ex.boxes, rtol=0, atol=1e-15)
    # Camera (already relative to the last observation) and depths are copied exactly.
    np.testing.assert_array_equal(back.camera, ex.camera)
    np.testing.assert_array_equal(back.depth, ex.depth)
    np.testing.assert_array_equal(back.observation_depth, ex.observation_depth)
    assert back.attrs["image_width"] == 640 and back.attrs["image_height"] == 480


def test_pixel_corners_follow_the_packages_convention() -> None:
    # A box from x 100 to 300 and y 60 to 120 in a 400 x 200 image.
    corners = np.array([[[100.0, 60.0, 300.0, 120.0], [np.nan] * 4, [110.0, 70.0, 290.0, 110.0]]])
    camera = np.array([[[1.0, 2.0, 3.0], [1.0, 2.0, 3.5], [1.5, 2.0, 4.0]]])  # any fixed origin
    ex = Examples.from_pixels(corners, camera, (400, 200))
    np.testing.assert_allclose(ex.boxes[0, 0], [200 / 400, 90 / 200, 200 / 400, 60 / 200])
    assert ex.detected.tolist() == [[True, False, True]]
    assert ex.boxes[0, 1].tolist() == [0.0] * 4
    np.testing.assert_array_equal(ex.camera[0], [[-0.5, 0.0, -1.0], [-0.5, 0.0, -0.5], [0.0, 0.0, 0.0]])
    assert np.isnan(ex.depth).all()


def test_examples_take_no_depth() -> None:
    ex = odmd_bench.generate(3, rng=0)
    bare = Examples(ex.boxes, ex.detected, ex.camera)
    assert bare.depth.shape == (3,) and np.isnan(bare.depth).all()


def test_examples_refuse_a_camera_not_relative_to_the_last_observation() -> None:
    ex = odmd_bench.generate(6, "odms", "normal", rng=0)
    world = ex.camera + np.array([2.0, 1.0, 3.0])  # a fixed frame with another origin
    with pytest.raises(DataError) as info:
        Examples(ex.boxes, ex.detected, world, ex.depth)
    text = info.value.render()
    assert "6 example(s) have a nonzero last row" in text and "from_pixels" in text
    one = ex.camera.copy()
    one[4, -1, 0] = 1e-9
    with pytest.raises(DataError, match=r"1 example\(s\) .*first: \[4\]"):
        Examples(ex.boxes, ex.detected, one, ex.depth)


@pytest.mark.parametrize("name", ["box-ls", "robust", "dbox"])
def test_from_pixels_gives_the_same_depths_for_any_origin(name: str) -> None:
    # Robust and DBox read positions relative to the last observation; from_pixels makes them so.
    if name == "dbox":
        pytest.importorskip("torch")
    ex = odmd_bench.generate(20, "odmd", "camera", rng=3)
    size = (ex.attrs["image_width"], ex.attrs["image_height"])
    corners = boxes_to_corners(ex.boxes, ex.detected, size)
    keep = {k: ex.attrs[k] for k in ("fx", "fy", "cx", "cy", "image_width", "image_height")}
    here = Examples.from_pixels(corners, ex.camera, size, ex.depth, attrs=keep)
    world = Examples.from_pixels(corners, ex.camera + np.array([2.0, 1.0, 3.0]), size, ex.depth, attrs=keep)
    np.testing.assert_allclose(world.camera, here.camera, atol=1e-12)
    method = methods.load(name)
    np.testing.assert_allclose(method.predict(world), method.predict(here), rtol=1e-6)


def test_from_pixels_names_every_bad_array() -> None:
    corners = np.array([[[1.0, 1.0, 0.5, 2.0], [1.0, np.nan, 2.0, 2.0], [1.0, 1.0, 2.0, np.inf]]])
    camera = np.zeros((1, 3, 3))
    camera[0, 0, 0] = np.nan
    with pytest.raises(DataError) as info:
        Examples.from_pixels(corners, camera, SIZE, depth=[-1.0])
    text = info.value.render()
    for words in ("partly NaN", "x2 <= x1", "not finite", "camera position", "depth"):
        assert words in text


def test_rows_may_come_in_any_order() -> None:
    text = sequences.format_sequences(_examples(50), names=[f"s{i}" for i in range(50)])
    header, *rows = text.splitlines()
    shuffled = [rows[i] for i in np.random.default_rng(1).permutation(len(rows))]
    a, b = _read(text), _read("\n".join([header, *shuffled]) + "\n")
    order = [b.names.index(name) for name in a.names]
    np.testing.assert_array_equal(b.examples().boxes[order], a.examples().boxes)
    np.testing.assert_array_equal(b.examples().camera[order], a.examples().camera)


def test_the_careful_reader_gives_the_same_numbers_as_the_fast_one() -> None:
    text = sequences.format_sequences(_examples(100))
    # A blank line, CRLF line ends and a BOM each force or test the row-by-row reader.
    for variant in (text.replace("\n", "\n\n", 5), "\ufeff" + text.replace("\n", "\r\n")):
        slow, fast = _read(variant).examples(), _read(text).examples()
        for name in ("boxes", "detected", "camera", "depth", "observation_depth"):
            np.testing.assert_array_equal(getattr(slow, name), getattr(fast, name))


@pytest.mark.parametrize("quoted", [False, True])
def test_lines_of_separators_only_are_skipped_by_both_readers(quoted: bool) -> None:
    # The fast reader would read ",,,,,,,," as a row of empty cells; the careful reader
    # skips it like a blank line (as evaluate does). The same file must read the same.
    text = sequences.format_sequences(_examples(4), names=[f"s{i}" for i in range(4)])
    header, *rows = text.splitlines()
    rows[0] = f'"{rows[0].split(",", 1)[0]}",{rows[0].split(",", 1)[1]}' if quoted else rows[0]
    blank = "," * (len(header.split(",")) - 1)
    variant = "\n".join([header, rows[0], blank, blank, *rows[1:], blank]) + "\n"
    assert len(blank.split(",")) == len(header.split(","))
    got, want = _read(variant), _read(text)
    assert got.names == want.names
    np.testing.assert_array_equal(got.examples().boxes, want.examples().boxes)


def test_both_readers_parse_decimals_of_any_length_alike() -> None:
    rng = np.random.default_rng(7)
    rows = []
    for i in range(3000):
        digits = int(rng.integers(1, 20))
        x1, y1 = (f"{v:.{digits}g}" for v in rng.uniform(0, 300, 2))
        x2, y2 = (f"{v:.{digits}g}" for v in rng.uniform(400, 900, 2))
        cam = ",".join(f"{v:.{digits}e}" for v in rng.normal(0, 1, 3))
        rows.append(f"s{i // 3},{i % 3},{x1},{y1},{x2},{y2},{cam}")
    text = ",".join(sequences.REQUIRED_COLUMNS) + "\n" + "\n".join(rows) + "\n"
    # A quoted cell sends the file to the row-by-row reader.
    fast, slow = _read(text).examples(), _read(text.replace("\ns0,", '\n"s0",', 1))
    assert slow.names == _read(text).names
    np.testing.assert_array_equal(slow.examples().boxes, fast.boxes)
    np.testing.assert_array_equal(slow.examples().camera, fast.camera)


def test_sequences_of_different_lengths_are_grouped_and_kept_in_file_order() -> None:
    ex = _examples(30)
    lengths = [2, 3, 10, 3, 2, 7] * 5
    parts = []
    for i, n in enumerate(lengths):
        one = (
            predict.select_observations(ex.subset(slice(i, i + 1)), n)
            if n < 10
            else ex.subset(slice(i, i + 1))
        )
        body = sequences.format_sequences(one, names=[f"q{i}"]).splitlines()[1:]
        parts += body
    text = ",".join(sequences.REQUIRED_COLUMNS) + ",depth\n" + "\n".join(parts) + "\n"
    seqs = _read(text)
    assert seqs.names == tuple(f"q{i}" for i in range(30))
    assert seqs.n_obs.tolist() == lengths
    assert [g[1].n_obs for g in seqs.groups] == [2, 3, 7, 10]
    result = predict.predict_sequences(seqs, "box-ls", "fill")  # (the paper's rule: box_ls.predict's)
    from odmd_bench_baselines import box_ls

    for index, group in seqs.groups:
        np.testing.assert_array_equal(result.depth[index], box_ls.predict(group))
    assert result.observations.tolist() == lengths
    with pytest.raises(UsageError, match="different lengths"):
        seqs.examples()


def test_observation_selection_keeps_the_first_and_the_last_evenly() -> None:
    assert predict.observation_indices(10, 10).tolist() == list(range(10))
    assert predict.observation_indices(19, 10).tolist() == list(range(0, 19, 2))
    for n in range(10, 60):
        idx = predict.observation_indices(n, 10)
        assert idx[0] == 0 and idx[-1] == n - 1 and (np.diff(idx) >= 1).all()
        assert np.diff(idx).max() - np.diff(idx).min() <= 1


def _fake_method(count: int | None) -> types.SimpleNamespace:
    seen: list[Examples] = []

    def predict_report(examples: Examples) -> tuple[np.ndarray, dict[str, int]]:
        seen.append(examples)
        # Depth = the camera z of the first observation it was given, to see the selection.
        return -examples.camera[:, 0, 2].copy(), {"n": len(examples)}

    return types.SimpleNamespace(
        name="fake", observations=count, predict=predict_report, predict_report=predict_report, seen=seen
    )


def test_a_method_built_for_k_observations_gets_k_chosen_evenly_or_a_clear_error() -> None:
    ex = _examples(4)
    seqs = _read(sequences.format_sequences(ex))
    method = _fake_method(4)
    result = predict.predict_sequences(seqs, method)
    given = method.seen[0]
    assert given.n_obs == 4 and result.observations.tolist() == [4] * 4
    keep = predict.observation_indices(10, 4)
    np.testing.assert_array_equal(given.camera, ex.camera[:, keep])
    np.testing.assert_array_equal(given.detected, ex.detected[:, keep])
    short = _read(sequences.format_sequences(predict.select_observations(ex, 3)))
    with pytest.raises(UsageError, match="takes 4 observations per sequence; 4 of 4 sequences have fewer"):
        predict.predict_sequences(short, method)
    # A method declaring nothing takes every observation.
    free = _fake_method(None)
    predict.predict_sequences(seqs, free, "fill")
    assert free.seen[0].n_obs == 10
    with pytest.raises(UsageError, match="use --missing fill"):
        predict.predict_sequences(seqs, method, "omit")


def test_dbox_declares_its_ten_observations() -> None:
    assert predict.method_observations(methods.load("dbox")) == 10
    assert predict.method_observations(methods.load("box-ls")) is None


# --- strict reading ----------------------------------------------------------------------------

GOOD = (
    "sequence,observation,x1,y1,x2,y2,cam_x,cam_y,cam_z,depth\n"
    "a,1,100,100,140,150,0,0,0,\n"
    "a,2,,,,,0,0,0.1,\n"
    "a,3,90,90,150,160,0,0,0.2,1.5\n"
)


def test_an_empty_box_is_a_missed_detection() -> None:
    ex = _read(GOOD).examples()
    assert ex.detected.tolist() == [[True, False, True]]
    assert ex.depth.tolist() == [1.5]


def test_every_bad_row_is_located_and_counted() -> None:
    text = (
        "sequence,observation,x1,y1,x2,y2,cam_x,cam_y,cam_z,depth\n"
        "a,1,100,100,140,150,0,0,0,\n"  # 2 fine
        "a,2,100,,140,150,0,0,0.1,\n"  # 3 partly empty box
        "a,3,140,100,100,150,0,0,0.2,1.5\n"  # 4 x2 <= x1
        "b,1,1,1,2,2,zero,0,0,\n"  # 5 not a number
        "b,2,1,1,2,2,0,0,inf,\n"  # 6 not finite
        "b,2,1,1,2,2,0,0,0.3,-1\n"  # 7 repeated observation, negative depth
        "c,1,1,1,2,2,0,0,0\n"  # 8 wrong number of fields
        ",1,1,1,2,2,0,0,0,\n"  # 9 empty sequence
        "d,1,1,1,2,2,0,0,,\n"  # 10 empty cam_z; d has one observation
    )
    problems = _problems(text).problems
    expected = {
        "box partly empty": "(1 row): line 3",
        "box with x2 <= x1": "(1 row): line 4",
        "cam_x is not a number": "(1 row): line 5 ('zero')",
        "cam_z is not finite": "(1 row): line 6",
        "depth must be > 0": "(1 row): line 7 ('-1.0')",
        "observation repeated within a sequence": "(1 row): lines 6 and 7 (sequence 'b', observation 2)",
        "wrong number of fields (every row must have 10": "(1 row): line 8 (9)",
        "sequence is empty": "(1 row): line 9",
        "cam_z is empty": "(1 row): line 10",
        "sequence with one observation": "(1 row): line 10 ('d')",
    }
    assert len(problems) == len(expected)
    for kind, where in expected.items():
        line = next(p for p in problems if p.startswith(kind))
        assert line.endswith(where), line


def test_a_file_of_many_bad_rows_gives_a_short_message() -> None:
    rows = [f"s{i // 2},{i % 2},1,1,0,2,0,0,{i % 2}" for i in range(100_000)]
    text = ",".join(sequences.REQUIRED_COLUMNS) + "\n" + "\n".join(rows) + "\n"
    error = _problems(text)
    assert error.problems == [
        "box with x2 <= x1 (100000 rows): line 2, line 3, line 4, line 5, line 6, ... (99995 more)"
    ]
    assert len(error.render()) < 300


def test_header_problems_name_the_missing_and_misspelt_columns() -> None:
    error = _problems("sequence,observation,x1,y1,x2,y_2,cam_x,cam_y,camz\na,1,1,1,2,2,0,0,0\n")
    text = "\n".join(error.problems)
    assert "missing column 'y2' (the header has 'y_2': misspelt?)" in text
    assert "missing column 'cam_z' (the header has 'camz': misspelt?)" in text
    assert "semicolons" in "\n".join(_problems("sequence;observation;x1\n").problems)
    assert _problems("").problems[0].startswith("the file is empty")
    assert "no rows" in _problems(",".join(sequences.REQUIRED_COLUMNS) + "\n").problems[0]
    with pytest.raises(ValidationError, match="not UTF-8"):
        sequences.read_sequences(GOOD.replace("a,1", "\xe9,1").encode("latin-1"), SIZE)


def test_quoted_names_and_extra_columns_are_read() -> None:
    text = GOOD.replace("sequence,", "note,sequence,").replace("\na,", '\nx,"a, the mug",')
    seqs = _read(text)
    assert seqs.names == ("a, the mug",) and seqs.ignored_columns == ("note",)


def test_a_gzip_file_is_read_like_the_plain_one(tmp_path: Path) -> None:
    path = tmp_path / "s.csv.gz"
    path.write_bytes(gzip.compress(GOOD.encode()))
    a, b = sequences.read_sequences(path, SIZE).examples(), _read(GOOD).examples()
    np.testing.assert_array_equal(a.boxes, b.boxes)
    path.write_bytes(gzip.compress(GOOD.encode())[:20])
    with pytest.raises(ValidationError, match="gzip"):
        sequences.read_sequences(path, SIZE)


def test_box_ls_depends_on_the_image_size_only_through_its_aspect_ratio() -> None:
    # As docs/own-data.md says: a resized copy's size gives the same depths, a swapped W, H does not.
    text = sequences.format_sequences(_examples(20))
    box_ls = methods.load("box-ls")

    def depths(size: tuple[int, int]) -> np.ndarray:
        return box_ls.predict(sequences.read_sequences(text.encode(), size).examples().without_truth())

    np.testing.assert_allclose(depths((SIZE[0] * 3, SIZE[1] * 3)), depths(SIZE), rtol=1e-9)
    assert np.abs(depths((SIZE[1], SIZE[0])) / depths(SIZE) - 1).max() > 1e-3


def test_image_size_and_intrinsics_are_checked() -> None:
    with pytest.raises(UsageError, match="image size"):
        sequences.read_sequences(GOOD.encode(), (0, 480))
    with pytest.raises(UsageError, match="intrinsics"):
        sequences.read_sequences(GOOD.encode(), SIZE, (1.0, 2.0, 3.0))


# --- the command -------------------------------------------------------------------------------


def _invoke(args: list[str], stdin: str | None = None) -> Result:
    return CliRunner().invoke(cli, args, input=stdin, catch_exceptions=False)


def test_predict_box_ls_equals_baseline_box_ls_on_the_same_sequences(
    tmp_path: Path, v1_data_dir: Path
) -> None:
    preds = tmp_path / "preds.csv"
    r = _invoke(["baseline", "box-ls", "--data-dir", str(v1_data_dir), "-o", str(preds)])
    assert r.exit_code == 0, r.output
    expected = {(row["set"], int(row["index"])): float(row["depth"]) for row in _csv_rows(preds.read_text())}
    sets = odmd_bench.load_split("test", data_dir=v1_data_dir)
    for set_name, ex in sets.items():
        seq_csv = tmp_path / f"{set_name}.csv"
        names = [f"{set_name}-{i}" for i in range(len(ex))]
        sequences.write_sequences(seq_csv, ex, names=names)
        out = tmp_path / f"{set_name}-depths.csv"
        r = _invoke(
            ["predict", str(seq_csv), "--method", "box-ls", "--image-size", "640", "480", "-o", str(out)]
            + ["--missing", "fill"]  # (the paper's rule, as the benchmark)
        )
        assert r.exit_code == 0, r.output
        got = _csv_rows(out.read_text())
        assert [row["sequence"] for row in got] == names
        want = np.array([expected[(set_name, i)] for i in range(len(ex))])
        depth = np.array([float(row["depth"] or "nan") for row in got])
        reason = np.array([row["reason"] for row in got])
        # The benchmark scores the paper's fallback (0 m); predict gives no depth and says why.
        unsolved = want == 0.0
        assert all(r.startswith(("fallback ", "too little forward motion")) for r in reason[unsolved])
        assert (
            reason[unsolved & ~np.char.startswith(reason, "too little")] == "fallback single_detection"
        ).all()
        given = reason == ""
        assert np.isnan(depth[~given]).all() and not unsolved[given].any()
        np.testing.assert_allclose(depth[given], want[given], rtol=1e-9, atol=0)
        # Too little forward motion: Box_LS's answer there is far off (the benchmark keeps it).
        little = np.char.startswith(reason, "too little forward motion")
        if little.any():
            assert np.median(np.abs(want[little] / ex.depth[little] - 1)) > 0.2
        # Truth was in the file: the summary is evaluate's, from the metrics module.
        m = set_metrics(ex.depth[given], depth[given])
        assert f"{m['percent_error']['mean']:9.2f}" in r.output


def test_predict_writes_stdout_with_dash_and_keeps_messages_off_it(tmp_path: Path) -> None:
    path = tmp_path / "s.csv"
    path.write_text(GOOD)
    r = _invoke(["predict", str(path), "--method", "box-ls", "--image-size", "640", "480", "-o", "-"])
    assert r.exit_code == 0
    rows = _csv_rows(r.stdout)
    assert list(rows[0]) == [
        "sequence",
        "depth",
        "observations",
        "detections",
        "true_depth",
        "percent_error",
        "reason",
    ]
    # The missed detection omitted (the default): the method is given the two detections.
    assert rows[0]["sequence"] == "a" and rows[0]["observations"] == "2" and rows[0]["detections"] == "2"
    assert "error against the true depths" in r.stderr


def test_predict_reads_stdin_and_writes_a_default_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    r = _invoke(["predict", "-", "--method", "expansion", "--image-size", "640", "480"], stdin=GOOD)
    assert r.exit_code == 0, r.output
    assert (tmp_path / "depths-expansion.csv").is_file()
    assert "depths-expansion.csv" in r.output


def test_methods_that_need_intrinsics_say_so(tmp_path: Path) -> None:
    path = tmp_path / "s.csv"
    path.write_text(GOOD)
    for method in ("parallax", "robust"):
        r = _invoke(["predict", str(path), "--method", method, "--image-size", "640", "480"])
        assert r.exit_code == 2
        assert "needs the camera intrinsics" in r.output and "--intrinsics" in r.output
        ok = _invoke(["predict", str(path), "--method", method, "--image-size", "640", "480", *K, "-o", "-"])
        assert ok.exit_code == 0, ok.output


def test_bad_files_and_options_exit_2_without_a_traceback(tmp_path: Path) -> None:
    path = tmp_path / "s.csv"
    path.write_text(GOOD.replace("a,2,,,,,", "a,2,1,,,,"))
    args = ["predict", str(path), "--image-size", "640", "480"]
    r = _invoke([*args, "--method", "box-ls"])
    assert r.exit_code == 2 and "line 3" in r.output and "Traceback" not in r.output
    assert _invoke(["predict", str(path), "--method", "box-ls"]).exit_code == 2
    r = _invoke([*args, "--method", "no-such-method"])
    assert r.exit_code == 2 and "no-such-method" in r.output
    path.write_text(GOOD)
    r = _invoke([*args, "--method", "box-ls", "--config", "p"])
    assert r.exit_code == 2 and "--config" in r.output


def _documented_row_matches(row: str, doc: str) -> bool:
    """Whether ``doc`` shows an output row with the same fields as ``row``, numbers to 1e-9.

    The last digits of a float printed in full depend on the CPU's arithmetic (the docs
    were written on one machine, the tests run on others), so numbers are compared as
    numbers, every other field exactly.
    """
    fields = row.split(",")
    for line in doc.splitlines():
        shown = line.split(",")
        if len(shown) != len(fields) or shown[0] != fields[0]:
            continue
        same = True
        for a, b in zip(fields, shown, strict=True):
            try:
                same &= math.isclose(float(a), float(b), rel_tol=1e-9, abs_tol=1e-12)
            except ValueError:
                same &= a == b
        if same:
            return True
    return False


def test_the_documented_example_gives_the_documented_depths() -> None:
    example = DOCS / "sequences-example.csv"
    doc = (DOCS / "own-data.md").read_text(encoding="utf-8")
    size = ["--image-size", "4032", "3024"]
    for method, extra in (("box-ls", []), ("robust", ["--intrinsics", "3100", "3100", "2016", "1512"])):
        r = _invoke(["predict", str(example), "--method", method, *size, *extra, "-o", "-"])
        assert r.exit_code == 0, r.output
        rows = r.stdout.splitlines()
        assert len(rows) == 3 and rows[0] in doc
        for row in rows[1:]:
            assert _documented_row_matches(row, doc), row
        if method == "box-ls":
            summary = r.stderr.splitlines()[-4:]
            assert all(line in doc for line in summary)


def test_the_estimates_never_replace_the_sequences_file(tmp_path: Path) -> None:
    seqs = tmp_path / "s.csv"
    seqs.write_bytes((DOCS / "sequences-example.csv").read_bytes())
    r = _invoke(["predict", str(seqs), "--method", "box-ls", "--image-size", "4032", "3024", "-o", str(seqs)])
    assert r.exit_code == 2 and "is the sequences file being read" in r.stderr
    assert seqs.read_bytes() == (DOCS / "sequences-example.csv").read_bytes()


def test_boxes_wholly_outside_the_image_are_warned_of(tmp_path: Path) -> None:
    """A box outside the image size given is likely a wrong --image-size (a photo's full size)."""
    assert _read(GOOD).warnings == ()
    assert _read(GOOD.replace("a,1,100,100,140,150", "a,1,-50,100,0,150")).warnings == (
        "1 of 2 boxes lie wholly outside the 640 x 480 image (line 2): is the image size that of "
        "the images the boxes were drawn in (width, height, pixels)?",
    )
    # partly outside (a box cut by the border) is fine
    assert _read(GOOD.replace("a,1,100,100,140,150", "a,1,-50,100,10,150")).warnings == ()
    path = tmp_path / "s.csv"
    path.write_text(GOOD)
    r = _invoke(["predict", str(path), "--method", "box-ls", "--image-size", "64", "48", "-o", "-"])
    assert r.exit_code == 0
    assert "warning: 2 of 2 boxes lie wholly outside the 64 x 48 image (lines 2, 4)" in r.stderr
    assert "warning" not in r.stdout


def test_the_error_summary_keeps_its_columns_apart_for_large_errors() -> None:
    from odmd_bench.cli.predict import error_summary

    # Millimetres written as metres: errors of a million per cent and more.
    text = error_summary(np.array([0.001, 2.0, np.nan]), np.array([12345.0, 1.9, 1.0]))
    header, percent, absolute = text.splitlines()[1:]
    assert header.split() == ["mean", "median", "min", "max", "std"]
    cells = [row[20:].split() for row in (percent, absolute)]
    assert [len(c) for c in cells] == [5, 5]
    assert float(cells[0][3]) == pytest.approx(1234499900.0)
    assert float(cells[1][3]) == pytest.approx(12344.999)
    # right-aligned under their headers
    assert all(len(row) == len(header) for row in (percent, absolute))


def test_boxes_given_as_x_y_width_height_are_named() -> None:
    head = "sequence,observation,x1,y1,x2,y2,cam_x,cam_y,cam_z\n"
    # corners (100, 100)-(140, 150) written as x, y, w, h = 100, 100, 40, 50
    text = head + "".join(
        f"a,{i},{100 - i},{100 - i},{40 + 2 * i},{50 + 2 * i},0,0,{i / 10}\n" for i in range(1, 4)
    )
    problems = _problems(text).problems
    assert any(p.startswith("most boxes end before they start") and "x2 = x + width" in p for p in problems)
    # one box written the wrong way among corners is a mistake, not another convention
    text = head + "".join(
        f"a,{i},{100 - i},{100 - i},{140 + i},{150 + i},0,0,{i / 10}\n" for i in range(1, 4)
    )
    text += "a,4,150,96,140,154,0,0,0.4\n"
    problems = _problems(text).problems
    assert [p.split(" (")[0] for p in problems] == ["box with x2 <= x1"]
