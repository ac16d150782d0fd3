"""``odmd-bench evaluate`` and ``odmd-bench compare`` through click's CliRunner."""

from __future__ import annotations

import csv
import io
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

import odmd_bench
from odmd_bench.cli.main import cli
from odmd_bench.data.io import write_sets
from odmd_bench.data.registry import get_benchmark, set_file
from odmd_bench.evaluation.predictions import write_predictions
from odmd_bench.evaluation.report import PER_EXAMPLE_COLUMNS
from odmd_bench.evaluation.scoring import evaluate

SETS = ("normal", "camera", "object", "robot")
N = {"normal": 6, "camera": 5, "object": 4, "robot": 3}
UNPINNED = (
    "odmd-paper test normal, camera, object, robot: not the pinned version of the benchmark (imported "
    "with --allow-unknown, or written by other means); these scores do not compare with the paper's or "
    "the leaderboard's"
)


@pytest.fixture()
def data(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    d = tmp_path / "data"
    sets = {s: odmd_bench.generate(N[s], perturbation="both", rng=i) for i, s in enumerate(SETS)}
    write_sets(set_file(get_benchmark("odmd-paper"), "test", d), sets)
    monkeypatch.setenv("ODMD_BENCH_DATA", str(d))
    return d


def preds(tmp_path: Path, name: str = "p.csv", scale: float = 0.1, seed: int = 0, **kw: object) -> Path:
    rng = np.random.default_rng(seed)
    truth = {s: ex.depth for s, ex in odmd_bench.load_split("test", "odmd-paper").items()}
    p = tmp_path / name
    write_predictions(p, "test", {s: z * (1 + rng.normal(0, scale, z.shape)) for s, z in truth.items()}, **kw)  # type: ignore[arg-type]
    return p


def run(*args: str, unpinned: bool = False) -> tuple[int, str, str]:
    """Exit status, stdout and stderr; stderr without the fixture's unpinned-sets warning unless asked."""
    r = CliRunner().invoke(cli, list(args))
    err = r.stderr if unpinned else "".join(ln for ln in r.stderr.splitlines(True) if UNPINNED not in ln)
    return r.exit_code, r.stdout, err


def test_table(data: Path, tmp_path: Path) -> None:
    code, out, err = run("evaluate", str(preds(tmp_path)), "--benchmark", "odmd-paper", unpinned=True)
    assert code == 0, err
    lines = out.splitlines()
    assert lines[0].startswith("odmd-paper test: p.csv (sha256 ")
    assert "percent error (%)" in out and "absolute error (m)" in out
    names = [ln.split()[0] for ln in lines if len(ln.split()) > 2 and ln.split()[1].isdigit()]
    assert names == [*SETS, "All"]
    row = next(ln for ln in lines if ln.startswith("robot")).split()
    assert row[1] == "3" and len(row) == 12  # name, n, 5 percent, 5 absolute
    # The fixture's sets are written, not imported from the release: not the pinned ones.
    assert err == f"warning: {UNPINNED}\n"


def test_json_has_the_contract_keys_and_matches_the_library(data: Path, tmp_path: Path) -> None:
    p = preds(tmp_path)
    code, out, _ = run("evaluate", str(p), "--benchmark", "odmd-paper", "--format", "json")
    assert code == 0
    d = json.loads(out)
    assert {"benchmark", "split", "sets", "all", "provenance"} <= set(d)
    assert list(d["sets"]) == list(SETS)
    stats = {"mean", "median", "min", "max", "std"}
    for s in SETS:
        assert d["sets"][s]["n"] == N[s]
        assert set(d["sets"][s]["percent_error"]) == stats == set(d["sets"][s]["absolute_error"])
    lib = evaluate(p, benchmark="odmd-paper")
    assert d["all"]["percent_error_mean"] == lib.all_percent_error_mean  # exact through JSON
    assert d["provenance"]["predictions_sha256"] == lib.provenance["predictions_sha256"]


def test_csv_and_markdown(data: Path, tmp_path: Path) -> None:
    p = preds(tmp_path)
    code, out, _ = run("evaluate", str(p), "--benchmark", "odmd-paper", "--format", "csv")
    assert code == 0
    table = list(csv.DictReader(io.StringIO(out)))
    assert [r["set"] for r in table] == [*SETS, "All"]
    lib = evaluate(p, benchmark="odmd-paper")
    assert float(table[2]["percent_error_max"]) == lib.sets["object"]["percent_error"]["max"]
    assert float(table[-1]["percent_error_mean"]) == lib.all_percent_error_mean
    code, out, _ = run("evaluate", str(p), "--benchmark", "odmd-paper", "--format", "markdown")
    assert code == 0
    rows = [ln for ln in out.splitlines() if ln.startswith("|")]
    assert len(rows) == 2 + 4 + 1 and rows[-1].startswith("| **All** |")


def test_benchmark_column_and_sets(data: Path, tmp_path: Path) -> None:
    p = preds(tmp_path, benchmark="odmd-paper")
    code, out, err = run("evaluate", str(p), "--sets", "robot,camera", "--format", "json")
    assert code == 0
    assert list(json.loads(out)["sets"]) == ["camera", "robot"]
    assert "warning: ignored rows of sets not asked for: normal (6 rows), object (4 rows)" in err


def test_per_example_file(data: Path, tmp_path: Path) -> None:
    out_file = tmp_path / "out" / "per_example.csv"
    code, _, err = run(
        "evaluate", str(preds(tmp_path)), "--benchmark", "odmd-paper", "--per-example", str(out_file)
    )
    assert code == 0
    assert f"wrote per-example errors to {out_file}" in err
    with out_file.open() as fh:
        table = list(csv.DictReader(fh))
    assert list(table[0]) == list(PER_EXAMPLE_COLUMNS)
    assert len(table) == sum(N.values())
    robot = odmd_bench.load("test", "robot", "odmd-paper")
    last = [r for r in table if r["set"] == "robot"][-1]
    assert int(last["index"]) == 2 and float(last["truth"]) == robot.depth[2]
    assert int(last["n_detected"]) == int(robot.detected[2].sum())
    assert float(last["camera_move"]) == pytest.approx(np.linalg.norm(robot.camera[2, 0]), rel=1e-15)
    pred, truth = float(last["prediction"]), float(last["truth"])
    assert float(last["percent_error"]) == abs(truth - pred) / truth * 100
    assert sorted(x.name for x in out_file.parent.iterdir()) == ["per_example.csv"]  # no temp file left


def test_bad_file_exits_2_with_every_problem(data: Path, tmp_path: Path) -> None:
    p = tmp_path / "bad.csv"
    p.write_text("split,set,index,depth\ntest,normal,0,nan\ntest,nromal,1,1\ntest,normal,x,1\n")
    code, out, err = run("evaluate", str(p), "--benchmark", "odmd-paper")
    assert code == 2 and out == ""
    assert err.startswith("error: ")
    for words in (
        "depth is NaN or infinite (1 row): line 2",
        "did you mean 'normal'",
        "index is not an integer",
        "has no rows",
    ):
        assert words in err
    assert "Traceback" not in err


def test_negative_depth_warns_on_stderr_and_stdout_stays_json(data: Path, tmp_path: Path) -> None:
    p = tmp_path / "neg.csv"
    truth = {s: ex.depth.copy() for s, ex in odmd_bench.load_split("test", "odmd-paper").items()}
    truth["object"][1] = -0.5
    write_predictions(p, "test", truth)
    code, out, err = run("evaluate", str(p), "--benchmark", "odmd-paper", "--format", "json")
    assert code == 0
    assert json.loads(out)["sets"]["object"]["percent_error"]["max"] > 100
    assert err.startswith("warning: 1 depth is zero or negative (scored as given)")


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (["--format", "yaml"], "Invalid value for '--format'"),
        (["--benchmark", "odmd-v9"], "unknown benchmark 'odmd-v9'"),
        (["--sets", "robt"], "did you mean 'robot'"),
    ],
)
def test_usage_errors_exit_2(data: Path, tmp_path: Path, args: list[str], words: str) -> None:
    base = ["--benchmark", "odmd-paper"] if "--benchmark" not in args else []
    code, _, err = run("evaluate", str(preds(tmp_path)), *base, *args)
    assert code == 2 and words in err


def test_missing_imported_data_exits_2(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("ODMD_BENCH_DATA", str(tmp_path / "empty"))
    p = tmp_path / "p.csv"
    p.write_text("split,set,index,depth\ntest,normal,0,1.0\n")
    code, _, err = run("evaluate", str(p), "--benchmark", "odmd-paper")
    assert code == 2 and "odmd-bench import" in err


def test_data_dir_option(data: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    p = preds(tmp_path)
    monkeypatch.setenv("ODMD_BENCH_DATA", str(tmp_path / "elsewhere"))
    code, _, _ = run("evaluate", str(p), "--benchmark", "odmd-paper")
    assert code == 2
    code, _, err = run("evaluate", str(p), "--benchmark", "odmd-paper", "--data-dir", str(data))
    assert code == 0, err


def test_compare(data: Path, tmp_path: Path) -> None:
    a = preds(tmp_path, "a.csv", scale=0.01, seed=1)
    b = preds(tmp_path, "b.csv", scale=0.5, seed=2)
    code, out, err = run("compare", str(a), str(b), "--benchmark", "odmd-paper")
    assert code == 0, err
    assert "A = a.csv, B = b.csv" in out
    lines = out.splitlines()
    names = [ln.split()[0] for ln in lines if len(ln.split()) > 2 and ln.split()[1].isdigit()]
    assert names == [*SETS, "All"]
    all_row = next(ln for ln in lines if ln.startswith("All"))
    assert all_row.endswith(("A better", "not distinguishable"))
    code, out, _ = run(
        "compare", str(a), str(b), "--benchmark", "odmd-paper", "--format", "json", "--seed", "3"
    )
    d = json.loads(out)
    assert d["method"]["seed"] == 3 and set(d["sets"]) == set(SETS)
    assert d["all"]["difference"] < 0
    code2, out2, _ = run(
        "compare", str(a), str(b), "--benchmark", "odmd-paper", "--format", "json", "--seed", "3"
    )
    assert out2 == out  # reproducible
    for fmt in ("csv", "markdown"):
        code, out, _ = run("compare", str(a), str(b), "--benchmark", "odmd-paper", "--format", fmt)
        assert code == 0 and "All" in out


def test_compare_bad_file_exits_2(data: Path, tmp_path: Path) -> None:
    a = preds(tmp_path, "a.csv")
    b = tmp_path / "b.csv"
    b.write_text("nothing useful\n")
    code, out, err = run("compare", str(a), str(b), "--benchmark", "odmd-paper")
    assert code == 2 and out == "" and "B (" in err and "missing column" in err


def test_evaluate_never_imports_torch_or_pandas(data: Path, tmp_path: Path) -> None:
    p = preds(tmp_path)
    script = (
        "import sys\n"
        "from click.testing import CliRunner\n"
        "from odmd_bench.cli.main import cli\n"
        f"r = CliRunner().invoke(cli, ['evaluate', {str(p)!r}, '--benchmark', 'odmd-paper', '--format', 'json'])\n"
        "assert r.exit_code == 0, r.output\n"
        f"r = CliRunner().invoke(cli, ['compare', {str(p)!r}, {str(p)!r}, '--benchmark', 'odmd-paper'])\n"
        "assert r.exit_code == 0, r.output\n"
        "print(sorted(m for m in sys.modules if m.split('.')[0] in ('torch', 'scipy', 'matplotlib', 'pandas')))\n"
    )
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[]"


def test_missing_generated_benchmark_is_generated_first(tmp_path: Path) -> None:
    from odmd_bench.data.manifests import manifest
    from odmd_bench.data.registry import get_benchmark

    sizes = {s: manifest(get_benchmark("odmd-v1"))["splits"]["val"][s]["n"] for s in SETS}
    p = tmp_path / "ones.csv"
    write_predictions(p, "val", {s: np.ones(n) for s, n in sizes.items()})
    env = {**os.environ, "ODMD_BENCH_DATA": str(tmp_path / "fresh")}
    done = subprocess.run(
        [
            sys.executable,
            "-c",
            "from odmd_bench.cli.main import main; main()",
            "evaluate",
            str(p),
            "--format",
            "json",
        ],
        capture_output=True,
        text=True,
        env=env,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    assert "generating odmd-v1 val first" in done.stderr
    assert json.loads(done.stdout)["benchmark"] == "odmd-v1"
    assert (tmp_path / "fresh" / "odmd-v1" / "val.h5").exists()


# --- stdin, gzip, -o, refusing to overwrite the input, CI gates ------------------------


def invoke(args: list[str], stdin: bytes | None = None) -> tuple[int, str, str]:
    r = CliRunner().invoke(cli, args, input=stdin)
    return r.exit_code, r.stdout, r.stderr


def test_stdin_and_gzip_score_like_the_file(data: Path, tmp_path: Path) -> None:
    import gzip

    p = preds(tmp_path)
    base = ["--benchmark", "odmd-paper", "--format", "json"]
    plain = json.loads(run("evaluate", str(p), *base)[1])
    packed = tmp_path / "p.csv.gz"
    packed.write_bytes(gzip.compress(p.read_bytes()))
    for args, stdin in (
        (["evaluate", str(packed), *base], None),
        (["evaluate", "-", *base], p.read_bytes()),
        (["evaluate", "-", *base], packed.read_bytes()),
    ):
        code, out, err = invoke(args, stdin)
        assert code == 0, err
        got = json.loads(out)
        assert got["sets"] == plain["sets"] and got["all"] == plain["all"]
        assert got["provenance"]["predictions_sha256"] == plain["provenance"]["predictions_sha256"]
    assert json.loads(invoke(["evaluate", "-", *base], p.read_bytes())[1])["provenance"][
        "predictions_file"
    ] == ("<stdin>")
    code, out, _ = invoke(["compare", "-", str(packed), "--benchmark", "odmd-paper"], p.read_bytes())
    assert code == 0 and "A = <stdin>, B = p.csv.gz" in out
    code, _, err = invoke(["compare", "-", "-", "--benchmark", "odmd-paper"], b"")
    assert code == 2 and "both be read from stdin" in err


def test_output_file_and_dash(data: Path, tmp_path: Path) -> None:
    p = preds(tmp_path)
    report = tmp_path / "out" / "report.json"
    code, out, err = run(
        "evaluate", str(p), "--benchmark", "odmd-paper", "--format", "json", "-o", str(report)
    )
    assert code == 0 and out == "" and f"wrote the report to {report}" in err
    assert (
        json.loads(report.read_text())["all"]["percent_error_mean"]
        == evaluate(p, benchmark="odmd-paper").all_percent_error_mean
    )
    code, out, _ = run("evaluate", str(p), "--benchmark", "odmd-paper", "--format", "json", "-o", "-")
    assert code == 0 and json.loads(out) == json.loads(report.read_text())
    assert not Path("-").exists()
    code, out, _ = run(
        "evaluate", str(p), "--benchmark", "odmd-paper", "--per-example", "-", "-o", str(tmp_path / "r.txt")
    )
    assert code == 0 and out.splitlines()[0] == ",".join(PER_EXAMPLE_COLUMNS)
    assert len(out.splitlines()) == 1 + sum(N.values())
    code, _, err = run("evaluate", str(p), "--benchmark", "odmd-paper", "--per-example", "-")
    assert code == 2 and "cannot both write to stdout" in err
    cmp_out = tmp_path / "cmp.csv"
    code, out, _ = run(
        "compare", str(p), str(p), "--benchmark", "odmd-paper", "--format", "csv", "-o", str(cmp_out)
    )
    assert code == 0 and out == "" and cmp_out.read_text().startswith("benchmark,split,set,n,")


def test_outputs_never_replace_the_scored_file(data: Path, tmp_path: Path) -> None:
    p = preds(tmp_path)
    before = p.read_bytes()
    sym = tmp_path / "sym.csv"
    sym.symlink_to(p)
    hard = tmp_path / "hard.csv"
    os.link(p, hard)
    for args in (
        ["evaluate", str(p), "--per-example", str(p)],
        ["evaluate", str(p), "--per-example", str(sym)],
        ["evaluate", str(hard), "--per-example", str(p)],
        ["evaluate", str(p), "-o", str(tmp_path / "." / "p.csv")],
        ["evaluate", str(sym), "-o", str(hard)],
        ["compare", str(p), str(preds(tmp_path, "b.csv")), "-o", str(hard)],
    ):
        code, out, err = run(*args, "--benchmark", "odmd-paper")
        assert code == 2 and out == "", args
        assert "being scored" in err and "Traceback" not in err
        assert p.read_bytes() == before
    code, _, err = run(
        "evaluate",
        str(p),
        "--benchmark",
        "odmd-paper",
        "-o",
        str(tmp_path / "x"),
        "--per-example",
        str(tmp_path / "x"),
    )
    assert code == 2 and "name the same file" in err


def test_max_all_gate(data: Path, tmp_path: Path) -> None:
    p = preds(tmp_path, scale=0.1)
    all_mean = evaluate(p, benchmark="odmd-paper").all_percent_error_mean
    code, out, err = run("evaluate", str(p), "--benchmark", "odmd-paper", "--max-all", f"{all_mean + 0.01}")
    assert code == 0 and "All" in out and err.startswith("ok: All")
    code, out, err = run("evaluate", str(p), "--benchmark", "odmd-paper", "--max-all", f"{all_mean - 0.01}")
    assert code == 1 and "All" in out  # the report is still printed
    assert f"fail: All {all_mean:.2f} is above --max-all {all_mean - 0.01:g}" in err
    for bad, said in (("nan", "nan is not a finite number"), ("-1", "--max-all must be a finite number")):
        code, out, err = run("evaluate", str(p), "--benchmark", "odmd-paper", "--max-all", bad)
        assert code == 2 and out == "" and said in err


def test_compare_fail_if_worse(data: Path, tmp_path: Path) -> None:
    truth = {s: ex.depth for s, ex in odmd_bench.load_split("test", "odmd-paper").items()}
    good = preds(tmp_path, "good.csv", scale=0.01, seed=1)
    bad = tmp_path / "bad.csv"
    write_predictions(bad, "test", {s: z * 1.5 for s, z in truth.items()})
    base = ["--benchmark", "odmd-paper", "--fail-if-worse"]
    code, out, err = run("compare", str(good), str(bad), *base)
    assert code == 1 and "All" in out
    # The gate line says A - B, as the table above it does: the same number, the same sign.
    (all_row,) = [line.split() for line in out.splitlines() if line.startswith("All ")]
    assert err.splitlines()[0].startswith(
        f"fail: the candidate is significantly worse on All: A - B (baseline - candidate) = {all_row[4]} points"
    )
    assert all_row[4].startswith("-")
    code, out, err = run("compare", str(bad), str(good), *base)
    assert code == 0 and err.startswith("ok: the candidate is significantly better on All")
    code, out, err = run("compare", str(good), str(good), *base, "--sets", "normal,robot")
    assert code == 0
    # A file compared with itself: every difference and bound is +0.00, never -0.00.
    assert "-0.00" not in out + err and "[+0.00, +0.00]" in out and "= +0.00 points" in err
    assert [ln.split(":")[0] + ":" + ln.split(":")[1] for ln in err.splitlines() if ln.startswith("ok")] == [
        "ok: not significantly worse on All",
        "ok: not significantly worse on normal",
        "ok: not significantly worse on robot",
    ]
    # without the flag, a worse candidate is reported but does not fail
    code, _, _ = run("compare", str(good), str(bad), "--benchmark", "odmd-paper")
    assert code == 0


def test_huge_depths_are_refused_by_evaluate_and_compare(data: Path, tmp_path: Path) -> None:
    good = preds(tmp_path)
    huge = tmp_path / "huge.csv"
    lines = good.read_text().splitlines()
    lines[3] = lines[3].rsplit(",", 1)[0] + ",1e308"
    huge.write_text("\n".join(lines) + "\n")
    for args in (["evaluate", str(huge)], ["compare", str(good), str(huge)]):
        code, out, err = run(*args, "--benchmark", "odmd-paper", "--format", "json")
        assert code == 2 and out == ""
        assert "depth is out of range" in err and "line 4 ('1e308')" in err


def test_outputs_follow_links_and_write_into_pipes(data: Path, tmp_path: Path) -> None:
    p = preds(tmp_path, benchmark="odmd-paper")
    real = tmp_path / "real.txt"
    real.write_text("old\n")
    link = tmp_path / "link.csv"
    link.symlink_to(real)
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    reader = os.open(fifo, os.O_RDONLY | os.O_NONBLOCK)  # a reader, so that the writer never waits
    try:
        code, out, err = run("evaluate", str(p), "--per-example", str(link), "-o", str(fifo))
        got = b""
        while chunk := os.read(reader, 1 << 16):
            got += chunk
    finally:
        os.close(reader)
    assert code == 0, err
    assert link.is_symlink() and os.readlink(link) == str(real)  # the link stays, its target is new
    assert real.read_text().startswith(",".join(PER_EXAMPLE_COLUMNS[:3]))
    assert fifo.is_fifo() and got.decode().startswith("odmd-paper test: p.csv")  # written into, not replaced
    assert [x.name for x in tmp_path.iterdir() if x.name.endswith(".tmp")] == []


def test_a_failed_command_replaces_no_earlier_output(data: Path, tmp_path: Path) -> None:
    p = preds(tmp_path, benchmark="odmd-paper")
    old = tmp_path / "pe.csv"
    old.write_text("OLD\n")
    blocker = tmp_path / "a-file"
    blocker.write_text("")
    code, _, err = run("evaluate", str(p), "--per-example", str(old), "-o", str(blocker / "report.txt"))
    assert code == 2 and f"cannot use {blocker} as a folder: it is a file" in err
    assert old.read_text() == "OLD\n"  # the per-example file is replaced only when the report is written too
    code, _, err = run("evaluate", str(p), "-o", str(data / "odmd-paper" / "test.h5"))
    assert code == 2 and "is inside the data folder" in err
    assert odmd_bench.load_split("test", "odmd-paper")["robot"].depth.size == N["robot"]


def test_a_misspelt_benchmark_column_is_refused(data: Path, tmp_path: Path) -> None:
    p = preds(tmp_path, benchmark="odmd-paper")
    for name in ("Benchmark", "bench_mark", "benchmrk"):
        bad = tmp_path / f"{name}.csv"
        bad.write_text(p.read_text().replace("benchmark", name, 1))
        code, _, err = run("evaluate", str(bad))
        assert code == 2 and f"column '{name}' looks like the optional column 'benchmark' misspelt" in err
    fine = tmp_path / "notes.csv"
    fine.write_text(p.read_text().replace("benchmark", "benchmark_notes", 1))
    assert run("evaluate", str(fine), "--benchmark", "odmd-paper")[0] == 0  # merely alike: ignored


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (["compare", "A", "A", "--seed", "-1"], "--seed"),
        (["compare", "A", "A", "--resamples", "1000000000000"], "--resamples"),
        (["plot", "A", "--set", "robot", "--bins", "1000000000000", "-o", "x.png"], "at most 200 bins"),
        (
            ["plot", "A", "--set", "robot", "--bins", ",".join(map(str, range(300))), "-o", "x.png"],
            "at most 201",
        ),
    ],
)
def test_out_of_range_options_exit_2(data: Path, tmp_path: Path, args: list[str], words: str) -> None:
    if args[0] == "plot":
        pytest.importorskip("matplotlib")
    p = str(preds(tmp_path, benchmark="odmd-paper"))
    code, _, err = run(*(p if a == "A" else str(tmp_path / a) if a.endswith(".png") else a for a in args))
    assert code == 2 and words in err and "Traceback" not in err


@pytest.mark.parametrize(
    "command", [["evaluate", "-"], ["compare", "P", "-"], ["plot", "-", "--set", "robot"]]
)
def test_a_closed_stdin_is_a_usage_error(data: Path, tmp_path: Path, command: list[str]) -> None:
    if "plot" in command:
        pytest.importorskip("matplotlib")  # the [plot] extra
    p = preds(tmp_path, benchmark="odmd-paper")
    args = [str(p) if a == "P" else a for a in command] + (
        ["-o", str(tmp_path / "f.png")] if "plot" in command else []
    )
    line = " ".join([sys.executable, "-m", "odmd_bench", *args]) + " <&-"
    done = subprocess.run(["bash", "-c", line], capture_output=True, text=True, check=False)
    assert done.returncode == 2, done.stderr
    assert "standard input is closed" in done.stderr and "Traceback" not in done.stderr


def test_spreadsheet_trailing_commas_and_utf16_without_a_mark(data: Path, tmp_path: Path) -> None:
    p = preds(tmp_path, benchmark="odmd-paper")
    lines = p.read_text().splitlines()
    trail = tmp_path / "trail.csv"
    trail.write_text("".join(line + ",,\n" for line in lines))  # empty columns, as spreadsheets save them
    assert run("evaluate", str(trail))[0] == 0
    u16 = tmp_path / "u16.csv"
    u16.write_bytes(p.read_text().encode("utf-16-le"))
    code, _, err = run("evaluate", str(u16))
    assert (
        code == 2 and "looks like UTF-16 text without a byte-order mark" in err and "save it as UTF-8" in err
    )


def test_the_readmes_evaluate_output_is_what_the_commands_print(
    v1_data_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """README.md's quick start: `baseline box-ls -o box-ls.csv` then `evaluate box-ls.csv`."""
    readme = (Path(__file__).resolve().parents[1] / "README.md").read_text(encoding="utf-8")
    intro = "`evaluate` prints (Box_LS on `odmd-v1` test; the warning goes to standard error):\n\n```\n"
    start = readme.index(intro) + len(intro)
    shown = readme[start : readme.index("```", start)]
    monkeypatch.chdir(tmp_path)
    runner = CliRunner()
    made = runner.invoke(cli, ["baseline", "box-ls", "-o", "box-ls.csv", "--data-dir", str(v1_data_dir)])
    assert made.exit_code == 0, made.output
    r = runner.invoke(cli, ["evaluate", "box-ls.csv", "--data-dir", str(v1_data_dir)])
    assert r.exit_code == 0, r.output
    assert r.stdout + r.stderr == shown


def test_the_expected_input_format_is_stated_in_help_and_docstring() -> None:
    """OGB-style: the file's and the arrays' format, with every benchmark's sets, where a user looks."""
    from odmd_bench.data.registry import BENCHMARKS

    result = CliRunner().invoke(cli, ["evaluate", "--help"])
    assert result.exit_code == 0
    help_text = " ".join(result.output.split())
    doc = " ".join((odmd_bench.score.__doc__ or "").split())
    assert (
        "Expected input format (what `odmd-bench baseline NAME -o PREDS` writes): split,set,index,depth"
        in help_text
    )
    assert "Expected input format" in doc and "in index order" in doc
    for name, bench in BENCHMARKS.items():
        listed = f"{', '.join(bench.sets[:-1])}, {bench.sets[-1]}"
        assert listed in help_text and listed in doc, (name, listed)


@pytest.mark.parametrize(("resamples", "confidence"), [("10", "0.95"), ("2000", "0.9999"), ("1", "0.5")])
def test_a_gate_that_could_never_fail_is_refused(
    data: Path, tmp_path: Path, resamples: str, confidence: str
) -> None:
    truth = {s: ex.depth for s, ex in odmd_bench.load_split("test", "odmd-paper").items()}
    good = preds(tmp_path, "good.csv", scale=0.01, seed=1)
    bad = tmp_path / "bad.csv"
    write_predictions(bad, "test", {s: z * 1.5 for s, z in truth.items()})
    for gate in ([], ["--fail-if-worse"]):
        code, out, err = run(
            "compare", str(good), str(bad), "--benchmark", "odmd-paper", "--resamples", resamples,
            "--confidence", confidence, *gate,
        )  # fmt: skip
        assert code == 2 and out == "" and "Traceback" not in err
        assert f"--resamples and --confidence: {resamples} resamples at confidence {confidence} " in err
        assert "can never find a difference" in err and "use at least" in err


def test_a_pass_beside_an_interval_on_the_worse_side_says_why() -> None:
    from odmd_bench.evaluation.compare import compare_errors
    from odmd_bench.evaluation.gates import fail_if_worse

    # Five examples all worse for B: the interval lies above 0, the exact p is 0.0625.
    a = {"normal": np.array([1.0, 2.0, 3.0, 4.0, 5.0])}
    b = {"normal": a["normal"] + np.array([0.9, 1.0, 1.1, 1.0, 0.95])}
    passed, lines = fail_if_worse(compare_errors(a, b, n_resamples=4000))
    assert passed
    assert lines[0].startswith("ok: not significantly worse on All")
    assert "(the interval lies above 0, but the test's p = 0." in lines[0]
    assert lines[0].endswith("is not below 0.05: worse needs both)")
