"""Error against true depth: the binning (pure, no matplotlib) and ``odmd-bench plot``."""

from __future__ import annotations

import csv
import gzip
import io
import struct
import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

import odmd_bench
from odmd_bench.cli.main import cli
from odmd_bench.data.io import write_sets
from odmd_bench.data.registry import get_benchmark, set_file
from odmd_bench.errors import UsageError
from odmd_bench.evaluation.depth_bins import (
    CSV_COLUMNS,
    bin_edges,
    binned_errors,
    error_curves,
    format_curves_csv,
    parse_bins,
)
from odmd_bench.evaluation.predictions import write_predictions
from odmd_bench.evaluation.scoring import evaluate

SETS = ("normal", "perturb", "robot", "driving")
N = {"normal": 5, "perturb": 4, "robot": 3, "driving": 40}
BENCH = "odms-detection"


# --- binning: pure computation --------------------------------------------------------


def test_equal_width_edges_span_the_depth_range() -> None:
    z = np.random.default_rng(0).uniform(2.0, 60.0, 500)
    edges = bin_edges(z, 7)
    assert edges.shape == (8,)
    assert edges[0] == z.min() and edges[-1] == z.max()
    np.testing.assert_allclose(np.diff(edges), (z.max() - z.min()) / 7)


def test_one_depth_only_gets_a_metre_wide_bin() -> None:
    assert bin_edges([3.0, 3.0], 2).tolist() == [2.5, 3.0, 3.5]


def test_binned_errors_match_a_brute_force_count() -> None:
    rng = np.random.default_rng(1)
    z = rng.uniform(1.0, 11.0, 1000)
    e = rng.exponential(1.0, 1000) * z
    edges = bin_edges(z, 5)
    b = binned_errors(z, e, edges)
    assert b.counts.sum() == 1000 and b.outside == 0
    for i in range(5):
        last = i == 4
        sel = (z >= edges[i]) & ((z <= edges[i + 1]) if last else (z < edges[i + 1]))
        assert b.counts[i] == sel.sum()
        assert b.mean[i] == pytest.approx(e[sel].mean())
        assert b.median[i] == pytest.approx(np.median(e[sel]))
        assert b.q25[i] <= b.median[i] <= b.q75[i]
    np.testing.assert_allclose(b.centres, (edges[:-1] + edges[1:]) / 2)


def test_bins_are_closed_left_and_the_last_is_closed_right() -> None:
    b = binned_errors([0.0, 1.0, 2.0], [1.0, 2.0, 3.0], [0.0, 1.0, 2.0])
    assert b.counts.tolist() == [1, 2]
    assert b.mean.tolist() == [1.0, 2.5]


def test_empty_bins_are_nan_and_outside_examples_are_counted() -> None:
    b = binned_errors([0.5, 0.6, 5.0, 9.0], [1.0, 3.0, 2.0, 7.0], [0.0, 1.0, 2.0, 3.0])
    assert b.counts.tolist() == [2, 0, 0]
    assert b.mean[0] == 2.0 and np.isnan(b.mean[1:]).all() and np.isnan(b.q75[1:]).all()
    assert b.outside == 2


def test_binning_refuses_bad_input() -> None:
    with pytest.raises(UsageError, match="one error per depth"):
        binned_errors([1.0, 2.0], [1.0], [0.0, 3.0])
    with pytest.raises(UsageError, match="strictly increasing"):
        binned_errors([1.0], [1.0], [0.0, 2.0, 2.0])
    with pytest.raises(UsageError, match="finite"):
        binned_errors([np.nan], [1.0], [0.0, 2.0])
    with pytest.raises(UsageError, match="at least 1"):
        bin_edges([1.0, 2.0], 0)


def test_parse_bins() -> None:
    assert parse_bins(" 12 ") == 12
    assert parse_bins("0,5,20") == (0.0, 5.0, 20.0)
    for bad in ("0", "-3", "ten", "2.5", "5,1", "1,x", "1,inf", "1,"):
        with pytest.raises(UsageError, match="bins"):
            parse_bins(bad)


def test_error_curves_share_bins_and_the_csv_reads_back_exactly(data: Path, tmp_path: Path) -> None:
    a = evaluate(preds(tmp_path, "a.csv", seed=1), sets=["driving"])
    b = evaluate(preds(tmp_path, "b.csv", seed=2, scale=0.3), sets=["driving"])
    curves = error_curves([a, b], ["A", "B"], "driving", error="percent", bins=4)
    assert [c.label for c in curves] == ["A", "B"]
    np.testing.assert_array_equal(curves[0].bins.edges, curves[1].bins.edges)
    truth = a.examples["driving"].depth
    pct = np.abs(truth - b.predictions["driving"]) / truth * 100
    assert curves[1].set_mean == pytest.approx(pct.mean())
    assert curves[1].bins.counts.sum() == N["driving"]
    text = format_curves_csv(curves, benchmark=BENCH, split="test", set_name="driving", error="percent")
    rows = list(csv.DictReader(io.StringIO(text)))
    assert tuple(rows[0]) == CSV_COLUMNS and len(rows) == 8
    for r in rows[4:]:
        i = int(r["bin"])
        assert r["unit"] == "%" and int(r["n"]) == curves[1].bins.counts[i]
        if r["mean"]:
            assert float(r["mean"]) == curves[1].bins.mean[i]  # repr precision: exact
    with pytest.raises(UsageError, match="labels"):
        error_curves([a, b], ["A"], "driving")
    with pytest.raises(UsageError, match="unknown error"):
        error_curves([a], ["A"], "driving", error="squared")


# --- odmd-bench plot -----------------------------------------------------------------


@pytest.fixture()
def data(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    d = tmp_path / "data"
    sets = {
        s: odmd_bench.generate(N[s], preset="odms", perturbation="both", rng=i) for i, s in enumerate(SETS)
    }
    write_sets(set_file(get_benchmark(BENCH), "test", d), sets)
    monkeypatch.setenv("ODMD_BENCH_DATA", str(d))
    return d


def preds(
    tmp_path: Path,
    name: str,
    *,
    seed: int = 0,
    scale: float = 0.1,
    split: str = "test",
    benchmark: str = BENCH,
) -> Path:
    rng = np.random.default_rng(seed)
    truth = {s: odmd_bench.load("test", s, BENCH).depth for s in SETS}
    p = tmp_path / name
    write_predictions(
        p, split, {s: z * (1 + rng.normal(0, scale, z.shape)) for s, z in truth.items()}, benchmark=benchmark
    )
    return p


def run(*args: str, stdin: bytes | None = None) -> tuple[int, str]:
    r = CliRunner().invoke(cli, list(args), input=stdin)
    return r.exit_code, r.stderr


def png_size(path: Path) -> tuple[int, int]:
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and data[12:16] == b"IHDR"
    width, height = struct.unpack(">II", data[16:24])
    return width, height


def test_plot_writes_a_png_of_the_expected_size_and_the_same_bytes_twice(data: Path, tmp_path: Path) -> None:
    pytest.importorskip("matplotlib")
    a, b = preds(tmp_path, "a.csv", seed=1), preds(tmp_path, "b.csv", seed=2, scale=0.3)
    out1, out2, table = tmp_path / "one.png", tmp_path / "two.png", tmp_path / "bins.csv"
    args = [str(a), str(b), "--set", "driving", "--benchmark", BENCH, "--split", "test", "--bins", "5"]
    code, err = run("plot", *args, "-o", str(out1), "--csv", str(table), "--label", "A", "--label", "B")
    assert code == 0, err
    assert "wrote the figure to" in err and "ignored rows" not in err
    assert png_size(out1) == (800, 640)
    code, err = run("plot", *args, "-o", str(out2), "--label", "A", "--label", "B")
    assert code == 0, err
    assert out1.read_bytes() == out2.read_bytes()
    rows = list(csv.DictReader(io.StringIO(table.read_text())))
    assert [r["label"] for r in rows] == ["A"] * 5 + ["B"] * 5
    assert sum(int(r["n"]) for r in rows[:5]) == N["driving"]
    # The numbers are those of the evaluator's per-example absolute errors.
    res = evaluate(b, sets=["driving"])
    errs = np.abs(res.examples["driving"].depth - res.predictions["driving"])
    means = [float(r["mean"]) * int(r["n"]) for r in rows[5:] if r["mean"]]
    assert sum(means) == pytest.approx(errs.sum())


def test_plot_reads_gzip_and_stdin_and_names_lines_by_file(data: Path, tmp_path: Path) -> None:
    pytest.importorskip("matplotlib")
    a = preds(tmp_path, "a.csv", seed=1)
    gz = tmp_path / "b.csv.gz"
    gz.write_bytes(gzip.compress(preds(tmp_path, "b.csv", seed=2).read_bytes()))
    out, table = tmp_path / "fig.png", tmp_path / "bins.csv"
    code, err = run(
        "plot", str(gz), "-", "--set", "robot", "--error", "percent", "-o", str(out), "--csv", str(table),
        stdin=a.read_bytes(),
    )  # fmt: skip
    assert code == 0, err
    rows = list(csv.DictReader(io.StringIO(table.read_text())))
    assert {r["label"] for r in rows} == {"b.csv.gz", "stdin"}
    assert {r["unit"] for r in rows} == {"%"} and {r["set"] for r in rows} == {"robot"}
    assert png_size(out) == (800, 640)


@pytest.mark.parametrize(
    ("extra", "expected"),
    [
        (["--set", "camera"], "unknown set 'camera'"),
        (["--set", "driving", "--label", "only-one"], "1 --label for 2 predictions files"),
        (["--set", "driving", "--bins", "3,1"], "strictly increasing"),
        (["--set", "driving", "--error", "squared"], "Invalid value for '--error'"),
        (["--set", "driving", "--label", "a", "--label", "$\\nosuch$"], "not valid matplotlib math text"),
    ],
)
def test_plot_refuses_bad_usage(data: Path, tmp_path: Path, extra: list[str], expected: str) -> None:
    if "math text" in expected:
        pytest.importorskip("matplotlib")
    a, b = preds(tmp_path, "a.csv"), preds(tmp_path, "b.csv")
    out = tmp_path / "fig.png"
    code, err = run("plot", str(a), str(b), "--benchmark", BENCH, *extra, "-o", str(out))
    assert code == 2 and expected in err
    assert "Traceback" not in err and not out.exists()


def test_plot_refuses_files_of_another_split_or_benchmark_naming_each(data: Path, tmp_path: Path) -> None:
    pytest.importorskip("matplotlib")
    good = preds(tmp_path, "good.csv")
    val = preds(tmp_path, "val.csv", split="val")
    other = tmp_path / "paper.csv"  # an odmd-paper file: its sets are not odms-detection's
    write_predictions(other, "test", {s: np.ones(3) for s in ("normal", "camera", "object", "robot")})
    out = tmp_path / "fig.png"
    code, err = run(
        "plot", str(good), str(val), str(other), "--benchmark", BENCH, "--split", "test", "--set", "driving",
        "-o", str(out),
    )  # fmt: skip
    assert code == 2, err
    assert "val.csv is for split 'val', not --split 'test'" in err
    assert "paper.csv" in err and "unknown set" in err and "'camera'" in err
    assert not out.exists()
    # Without --split, files of two splits cannot share one figure either.
    code, err = run("plot", str(good), str(val), "--set", "driving", "-o", str(out))
    assert code == 2 and "val.csv is for odms-detection val" in err


def test_plot_refuses_to_overwrite_its_input_or_write_a_non_png(data: Path, tmp_path: Path) -> None:
    a = preds(tmp_path, "a.csv")
    before = a.read_bytes()
    code, err = run("plot", str(a), "--set", "driving", "-o", str(tmp_path / "fig.pdf"), "--csv", str(a))
    assert code == 2
    assert "name it *.png" in err and "is the predictions file" in err
    assert a.read_bytes() == before


def test_plot_without_matplotlib_names_the_extra(
    data: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # makes `import matplotlib` fail
    out = tmp_path / "fig.png"
    code, err = run("plot", str(preds(tmp_path, "a.csv")), "--set", "driving", "-o", str(out))
    assert code == 2
    assert "odmd-bench plot needs matplotlib" in err and "odmd-bench[plot]" in err
    assert not out.exists()


def test_the_readme_figure_numbers_are_what_the_command_writes(paper_data_dir: Path, tmp_path: Path) -> None:
    """docs/driving-error.csv is reproduced by the README's command on the committed entries."""
    pytest.importorskip("matplotlib")  # the [plot] extra
    repo = Path(__file__).resolve().parents[1]
    entries = repo / "leaderboard" / "entries"
    args = [
        "plot",
        str(entries / "dbox-p-z-per-set" / "odms-detection-test" / "predictions.csv.gz"),
        str(entries / "dbox-abs-z-per-set" / "odms-detection-test" / "predictions.csv.gz"),
        *("--benchmark", "odms-detection", "--split", "test", "--set", "driving"),
        *("--label", "DBox$_p^z$", "--label", "DBox$_{Abs}^z$"),
        *(
            "-o",
            str(tmp_path / "fig.png"),
            "--csv",
            str(tmp_path / "fig.csv"),
            "--data-dir",
            str(paper_data_dir),
        ),
    ]
    r = CliRunner().invoke(cli, args)
    assert r.exit_code == 0, r.output
    assert (tmp_path / "fig.csv").read_bytes() == (repo / "docs" / "driving-error.csv").read_bytes()


def test_a_file_name_that_is_not_utf8_is_drawn_with_a_replacement_character() -> None:
    import os

    from odmd_bench.cli.plot import _labels

    name = os.fsdecode(b"bad\xff$x.csv")  # as Python gets it from the command line
    assert _labels((Path(name),), ()) == ["bad\ufffd\\$x.csv"]
