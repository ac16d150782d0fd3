"""The faults of issue 45's battery, each pinned: caps, claims, the site's folder, float options, exits."""

from __future__ import annotations

import gzip
import io
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from odmd_bench import UsageError, ValidationError
from odmd_bench.cli.main import cli
from odmd_bench.inputs.source import CHUNK_BYTES, LIMIT_ENV, read_source
from odmd_bench.leaderboard.site import MANIFEST, write_site

HEADER = b"sequence,observation,x1,y1,x2,y2,cam_x,cam_y,cam_z\n"
ONE_ROW = HEADER + b"a,0,1,1,2,2,0,0,0\n"  # refused for its content: one observation


# --- a cap bounds what is read, never what is allocated ---------------------------------

#: The largest legal cap (2**30 MiB, 1 PiB): no machine can allocate it.
LARGEST_CAP = str(2**30)


@pytest.mark.parametrize("how", ["path", "stdin", "gzip"])
def test_the_largest_legal_cap_reads_a_small_sequences_file(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path, how: str
) -> None:
    monkeypatch.setenv(LIMIT_ENV, LARGEST_CAP)
    path = tmp_path / "s.csv"
    path.write_bytes(gzip.compress(ONE_ROW) if how == "gzip" else ONE_ROW)
    source, stdin = ("-", ONE_ROW) if how == "stdin" else (str(path), None)
    args = ["predict", source, "--method", "box-ls", "--image-size", "640", "480", "-o", "-"]
    r = CliRunner().invoke(cli, args, input=stdin)
    assert r.exit_code == 2, r.output
    assert "internal error" not in r.stderr and "sequence with one observation" in r.stderr


def test_the_largest_legal_cap_reads_a_small_original_file(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    monkeypatch.setenv(LIMIT_ENV, LARGEST_CAP)
    (tmp_path / "test_normal.pk").write_bytes(b"\x80\x04N.")
    r = CliRunner().invoke(
        cli, ["import", str(tmp_path / "test_normal.pk"), "--data-dir", str(tmp_path / "d")]
    )
    assert r.exit_code == 2 and "internal error" not in r.stderr and "unknown file" in r.stderr


class _Spy(io.RawIOBase):
    """A binary stream of ``size`` bytes that gives at most ``most`` per read and records what is asked."""

    def __init__(self, size: int, most: int) -> None:
        self.left, self.most, self.asked = size, most, []

    def readable(self) -> bool:
        return True

    def read(self, n: int = -1) -> bytes:
        self.asked.append(n)
        got = min(self.left, self.most, n if n >= 0 else self.left)
        self.left -= got
        return b"x" * got


def test_no_read_asks_for_more_than_a_chunk_or_what_is_left_below_the_cap() -> None:
    spy = _Spy(3 * CHUNK_BYTES + 5, most=CHUNK_BYTES // 3)  # short reads, as a pipe gives
    data, _ = read_source(spy, limit=2**50)
    assert len(data) == 3 * CHUNK_BYTES + 5 and max(spy.asked) == CHUNK_BYTES and min(spy.asked) > 0
    spy = _Spy(10 * CHUNK_BYTES, most=CHUNK_BYTES)
    with pytest.raises(ValidationError, match="larger than"):
        read_source(spy, limit=CHUNK_BYTES + 10)
    assert spy.asked == [CHUNK_BYTES, 11]  # the cap plus one byte, and no more


def test_a_regular_file_is_read_whole_in_one_read(tmp_path: Path) -> None:
    path = tmp_path / "big.csv"
    path.write_bytes(b"y" * (2 * CHUNK_BYTES + 3))
    data, _ = read_source(path, limit=2**50)
    assert data == path.read_bytes()
    data, _ = read_source(path, limit=2 * CHUNK_BYTES + 3)  # exactly at the cap: read
    assert len(data) == 2 * CHUNK_BYTES + 3
    with pytest.raises(ValidationError, match="larger than"):
        read_source(path, limit=2 * CHUNK_BYTES + 2)


# --- train-dbox claims its --out folder ---------------------------------------------------

WORKER = Path(__file__).parent / "dbox_worker.py"


def _train(out: Path, steps: int, *more: str) -> subprocess.Popen[str]:
    pytest.importorskip("torch")
    args = ["train-dbox", "--config", "p", "--steps", str(steps), "--val-every", str(steps), "--seed", "3"]
    args += ["--device", "cpu", "--threads", "1", "--out", str(out), *more]
    env = {**os.environ, "OMP_NUM_THREADS": "1", "PYTHONWARNINGS": "error"}
    return subprocess.Popen(
        [sys.executable, str(WORKER), *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )


def test_two_runs_started_together_into_one_folder_one_trains_and_the_other_is_refused(
    tmp_path: Path,
) -> None:
    out = tmp_path / "run"
    runs = [_train(out, 10**9), _train(out, 10**9)]  # neither ends by itself
    try:
        deadline = time.monotonic() + 600  # a hang guard, not a speed check: one run must be refused
        while all(r.poll() is None for r in runs):
            assert time.monotonic() < deadline, "both runs train into one folder"
            time.sleep(0.05)
        loser = next(r for r in runs if r.returncode is not None)
        winner = next(r for r in runs if r is not loser)
        _, err = loser.communicate(timeout=60)
        assert loser.returncode == 2 and "Traceback" not in err, err
        assert f"{out} is in use by another train-dbox run: process {winner.pid} on " in err
        assert winner.poll() is None  # the first run trains on
        claim = json.loads((out / "claim.json").read_text())
        assert claim["pid"] == winner.pid and "--steps 1000000000" in claim["command"]
    finally:
        for r in runs:
            if r.poll() is None:
                r.kill()
            r.communicate(timeout=60)


def test_a_folder_claimed_by_a_run_that_ended_is_refused_and_a_finished_run_resumes(tmp_path: Path) -> None:
    out = tmp_path / "run"
    out.mkdir()
    (out / "claim.json").write_text(json.dumps({"pid": 4242, "host": "h", "started": "T", "command": "c"}))
    _, err = _train(out, 2).communicate(timeout=300)
    assert "is claimed by an earlier train-dbox run (process 4242 on h, started T (c))" in err
    assert "which is not running now and left no training state to resume" in err
    assert f"delete {out / 'claim.json'} to start over" in err and "Traceback" not in err
    (out / "claim.json").unlink()
    first = _train(out, 2)
    assert first.communicate(timeout=300) and first.returncode == 0
    claim = json.loads((out / "claim.json").read_text())
    assert claim["pid"] == first.pid and "resumed" not in claim
    again = _train(out, 2)  # a new run into a finished run's folder: refused, as before
    _, err = again.communicate(timeout=300)
    assert again.returncode == 2 and "already holds a training run (last.pt)" in err
    resumed = _train(out, 2, "--resume")  # done already: it only loads the state
    assert resumed.communicate(timeout=300) and resumed.returncode == 0
    claim = json.loads((out / "claim.json").read_text())
    assert claim["pid"] == resumed.pid and claim["started"] != "" and "resumed" in claim


# --- leaderboard site -o DIR removes only what it wrote -----------------------------------

SITE = {
    "index.html": b'<html><head><meta name="generator" content="odmd-bench leaderboard site"></head></html>',
    "methods/a.html": b"a",
    "methods/b.html": b"b",
}


def test_a_rebuilt_site_keeps_the_users_files_and_removes_only_its_own(tmp_path: Path) -> None:
    out = tmp_path / "site"
    assert write_site(SITE, out) == []
    assert json.loads((out / MANIFEST).read_text())["files"] == sorted(SITE)
    (out / "CNAME").write_text("bench.example.org\n")
    (out / "notes").mkdir()
    (out / "notes" / "todo.txt").write_text("mine")
    (out / "methods" / "extra.html").write_text("mine too")
    (out / "empty").mkdir()
    (out / "link").symlink_to("CNAME")
    (out / "methods" / "a.html").write_text("edited")  # a file the site wrote: the site's again
    smaller = {k: v for k, v in SITE.items() if k != "methods/b.html"}  # an entry removed
    kept = write_site(smaller, out)
    assert kept == ["CNAME", "link", "methods/extra.html", "notes/todo.txt"]
    assert (out / "CNAME").read_text() == "bench.example.org\n" and (
        out / "notes" / "todo.txt"
    ).read_text() == "mine"
    assert (out / "methods" / "extra.html").read_text() == "mine too" and (out / "empty").is_dir()
    assert os.readlink(out / "link") == "CNAME"
    assert (out / "methods" / "a.html").read_bytes() == b"a" and not (out / "methods" / "b.html").exists()
    assert json.loads((out / MANIFEST).read_text())["files"] == sorted(smaller)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["site"]  # no staging folder left


def test_a_site_built_before_the_manifest_keeps_what_is_not_under_its_names(tmp_path: Path) -> None:
    out = tmp_path / "site"
    write_site(SITE, out)
    (out / MANIFEST).unlink()  # as an earlier version wrote it
    (out / "CNAME").write_text("x")
    (out / "methods" / "old.html").write_text("a page of an earlier build")
    assert write_site(SITE, out) == ["CNAME"]
    assert not (out / "methods" / "old.html").exists() and (out / MANIFEST).is_file()


def test_a_users_file_where_the_site_writes_is_refused_named_and_nothing_changes(tmp_path: Path) -> None:
    out = tmp_path / "site"
    write_site({"index.html": SITE["index.html"]}, out)
    (out / "methods").write_text("a file where the site puts a folder")
    (out / "CNAME").write_text("x")
    with pytest.raises(UsageError, match="did not write where the site writes its own") as info:
        write_site(SITE, out)
    assert info.value.problems == ["methods"]
    assert (out / "methods").read_text().startswith("a file") and not (out / "methods" / "a.html").exists()
    (out / MANIFEST).write_text("{not json")
    with pytest.raises(UsageError, match="is not a site manifest written by odmd-bench"):
        write_site(SITE, out)


def test_the_site_command_says_which_files_it_kept(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import odmd_bench.leaderboard.site as site_package

    monkeypatch.setattr(site_package, "build_site", lambda *a, **k: (SITE, []))
    out = tmp_path / "site"
    args = ["leaderboard", "site", "-o", str(out), "--root", str(tmp_path), "--no-plot"]
    assert CliRunner().invoke(cli, args).exit_code == 0
    (out / "CNAME").write_text("bench.example.org\n")
    again = CliRunner().invoke(cli, args)
    assert again.exit_code == 0, again.output
    assert f"kept 1 file(s) in {out} that odmd-bench did not write: CNAME" in again.output
    assert (out / "CNAME").read_text() == "bench.example.org\n"


# --- every float option refuses NaN and infinities -----------------------------------------


def _float_options() -> list[tuple[tuple[str, ...], str, int]]:
    """(command path, option, nargs) of every option of every command that takes a float."""
    import click

    def takes_float(kind: click.ParamType) -> bool:
        if isinstance(kind, click.Tuple):
            return any(takes_float(t) for t in kind.types)
        return isinstance(kind, click.types.FloatParamType)

    found = []

    def walk(command: click.Command, path: tuple[str, ...]) -> None:
        for param in command.params:
            if takes_float(param.type):
                assert isinstance(param, click.Option), f"{path}: a float argument {param.name}: test it here"
                found.append((path, param.opts[0], param.nargs))
        if isinstance(command, click.Group):
            ctx = click.Context(command)
            for name in command.list_commands(ctx):
                sub = command.get_command(ctx, name)
                assert sub is not None
                walk(sub, (*path, name))

    walk(cli, ())
    return found


FLOAT_OPTIONS = _float_options()


def test_the_float_options_are_found() -> None:
    named = {(" ".join(path), opt) for path, opt, _ in FLOAT_OPTIONS}
    assert {("compare", "--confidence"), ("evaluate", "--max-all"), ("predict", "--image-size")} <= named
    assert {("predict", "--intrinsics"), ("train-dbox", "--lr"), ("train-dbox", "--dist-timeout")} <= named


@pytest.mark.parametrize(("path", "option", "nargs"), FLOAT_OPTIONS, ids=lambda v: str(v))
@pytest.mark.parametrize("bad", ["nan", "NaN", "inf", "-inf", "Infinity", "1e400"])
def test_every_float_option_refuses_nan_and_infinities(
    path: tuple[str, ...], option: str, nargs: int, bad: str
) -> None:
    for at in range(nargs):  # each place of an option taking several numbers
        values = ["1"] * nargs
        values[at] = bad
        r = CliRunner().invoke(cli, [*path, option, *values])
        assert r.exit_code == 2, (r.exit_code, r.output)
        assert f"Invalid value for '{option}'" in r.output and "is not a finite number" in r.output, r.output
        assert "Traceback" not in r.output


def test_compare_confidence_nan_is_a_usage_error_not_an_internal_one(tmp_path: Path) -> None:
    (tmp_path / "a.csv").write_text("x\n")
    r = CliRunner().invoke(
        cli, ["compare", str(tmp_path / "a.csv"), str(tmp_path / "a.csv"), "--confidence", "nan"]
    )
    assert r.exit_code == 2 and "internal error" not in r.output and "is not a finite number" in r.output


# --- a closed standard output and an early Ctrl-C end quietly ----------------------------


def _entry(how: str) -> list[str]:
    if how == "-m":
        return [sys.executable, "-m", "odmd_bench"]
    script = Path(sys.executable).parent / "odmd-bench"
    if not script.is_file():
        pytest.skip(f"no odmd-bench script beside {sys.executable}")
    return [str(script)]


@pytest.mark.parametrize("how", ["script", "-m"])
@pytest.mark.parametrize("args", [["--version"], ["data-dir"], ["baseline", "--list"], ["info", "FILE"]])
def test_a_closed_standard_output_ends_quietly_with_141(tmp_path: Path, how: str, args: list[str]) -> None:
    from odmd_bench.cli.main import EXIT_BROKEN_PIPE
    from odmd_bench.data.generator import generate
    from odmd_bench.data.io import write_sets

    f = tmp_path / "x.h5"
    write_sets(f, {s: generate(3, rng=i) for i, s in enumerate(("normal", "camera", "object", "robot"))})
    cmd = [*_entry(how), *(str(f) if a == "FILE" else a for a in args)]
    done = subprocess.run(
        ["bash", "-c", 'exec "$@" >&-', "-", *cmd], capture_output=True, text=True, check=False
    )
    assert done.returncode == EXIT_BROKEN_PIPE and done.stderr == "", done.stderr


def test_a_command_with_standard_output_closed_still_does_its_work(tmp_path: Path) -> None:
    out = tmp_path / "preds.csv"
    cmd = [*_entry("-m"), "baseline", "box-ls", "--split", "val", "-o", str(out)]
    cmd += ["--data-dir", str(tmp_path / "data")]
    done = subprocess.run(
        ["bash", "-c", 'exec "$@" >&-', "-", *cmd], capture_output=True, text=True, check=False
    )
    assert "Traceback" not in done.stderr, done.stderr
    assert done.returncode in (0, 141) and out.is_file()  # 141 where it printed to standard output
    closed_err = subprocess.run(
        ["bash", "-c", 'exec "$@" 2>&-', "-", *_entry("-m"), "data-dir"], capture_output=True, text=True
    )
    assert closed_err.returncode == 0 and closed_err.stdout.strip()


#: Imports at which a test process sends itself SIGINT (the sitecustomize below), so that
#: each moment is hit every time: while the package imports (numpy, its modules), while the
#: command line imports (click, its commands), and once the command runs (gates: evaluate's
#: first import, before it reads its input). A Ctrl-C before that, while Python itself
#: starts (its site module), is Python's: it may print "Fatal Python error".
KICKS = [
    "numpy",
    "odmd_bench.data",
    "odmd_bench.predict",
    "click",
    "odmd_bench.cli.evaluate",
    "odmd_bench.evaluation.gates",
]

SITECUSTOMIZE = """
import os, signal, sys
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:  # started by a background job: Ctrl-C as in a terminal
    signal.signal(signal.SIGINT, signal.default_int_handler)
class _Kick:
    def find_spec(self, name, path=None, target=None):
        if name == os.environ.get("ODMD_TEST_SIGINT_ON"):
            sys.meta_path.remove(self)
            open(os.environ["ODMD_TEST_SIGINT_SENT"], "w").close()
            os.kill(os.getpid(), signal.SIGINT)
        return None
sys.meta_path.insert(0, _Kick())
"""


def _interrupted(cmd: list[str], env: dict[str, str]) -> tuple[int, str]:
    """Run ``cmd``, which waits on its standard input (kept open: it never ends by itself)."""
    proc = subprocess.Popen(
        cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env
    )
    try:
        _, err = proc.communicate(timeout=300)  # a hang guard: a swallowed interrupt waits forever
    finally:
        proc.kill()
    return proc.returncode, err


@pytest.mark.parametrize("how", ["script", "-m"])
@pytest.mark.parametrize("at", KICKS)
def test_a_ctrl_c_while_the_command_starts_ends_quietly_with_130(tmp_path: Path, how: str, at: str) -> None:
    (tmp_path / "sitecustomize.py").write_text(SITECUSTOMIZE)
    sent = tmp_path / "sent"
    env = {
        **os.environ,
        "PYTHONPATH": str(tmp_path),
        "ODMD_TEST_SIGINT_ON": at,
        "ODMD_TEST_SIGINT_SENT": str(sent),
    }
    code, err = _interrupted([*_entry(how), "evaluate", "-"], env)
    assert sent.exists()  # the signal came at that import
    assert code == 130 and "Traceback" not in err and "Exception ignored" not in err, (code, err)
    assert err.strip() in ("interrupted", "interrupted; no partial file was left behind"), err


def test_an_interrupt_that_something_swallows_still_ends_the_command_with_130(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    import odmd_bench.cli.main as cli_main

    def swallowing(**kwargs: object) -> None:
        try:
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(5)  # the handler runs here
        except BaseException:  # as a careless cleanup does  # noqa: BLE001, S110
            pass

    monkeypatch.setattr(cli_main, "_interrupted", False)
    monkeypatch.setattr(cli_main.cli, "main", swallowing)
    try:
        with pytest.raises(SystemExit) as done:
            cli_main.main()
    finally:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    assert done.value.code == 130 and capsys.readouterr().err == "interrupted\n"


# --- compare's gate lines say what the verdict is, once per gated set --------------------


@pytest.fixture()
def paper_like(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    import odmd_bench
    from odmd_bench.data.io import write_sets
    from odmd_bench.data.registry import get_benchmark, set_file

    d = tmp_path / "data"
    for k, split in enumerate(("val", "test")):
        sets = {
            s: odmd_bench.generate(40, rng=10 * k + i)
            for i, s in enumerate(("normal", "camera", "object", "robot"))
        }
        write_sets(set_file(get_benchmark("odmd-paper"), split, d), sets)
    monkeypatch.setenv("ODMD_BENCH_DATA", str(d))
    return d


def _scaled(tmp_path: Path, name: str, factor: float) -> Path:
    import odmd_bench
    from odmd_bench.evaluation.predictions import write_predictions

    truth = {s: ex.depth for s, ex in odmd_bench.load_split("test", "odmd-paper").items()}
    rng = np.random.default_rng(len(name))
    path = tmp_path / name
    write_predictions(
        path, "test", {s: z * factor * (1 + rng.normal(0, 0.01, z.shape)) for s, z in truth.items()}
    )
    return path


def _gate(a: Path, b: Path, *more: str) -> tuple[int, list[str]]:
    r = CliRunner().invoke(
        cli, ["compare", str(a), str(b), "--benchmark", "odmd-paper", "--fail-if-worse", *more]
    )
    return r.exit_code, [ln for ln in r.stderr.splitlines() if ln.startswith(("ok", "fail"))]  # not warnings


def test_a_significantly_better_candidate_is_called_better(paper_like: Path, tmp_path: Path) -> None:
    good, bad = _scaled(tmp_path, "good.csv", 1.0), _scaled(tmp_path, "bad.csv", 1.5)
    code, lines = _gate(bad, good, "--sets", "normal,robot")
    assert code == 0 and [ln.split(":")[0] + ":" + ln.split(":")[1] for ln in lines] == [
        "ok: the candidate is significantly better on All",
        "ok: the candidate is significantly better on normal",
        "ok: the candidate is significantly better on robot",
    ]
    assert not any("not significantly worse" in ln for ln in lines)
    code, lines = _gate(good, good)  # indistinguishable: not worse, and not called better
    assert code == 0 and lines[0].startswith("ok: not significantly worse on All: A - B")


@pytest.mark.parametrize(
    ("a", "b", "code", "start"),
    [
        ("good", "bad", 1, "fail: the candidate is significantly worse"),
        ("bad", "good", 0, "ok: the candidate is significantly better"),
    ],
)
def test_one_gated_set_gives_one_line(
    paper_like: Path, tmp_path: Path, a: str, b: str, code: int, start: str
) -> None:
    files = {"good": _scaled(tmp_path, "good.csv", 1.0), "bad": _scaled(tmp_path, "bad.csv", 1.5)}
    got, lines = _gate(files[a], files[b], "--sets", "camera")
    assert got == code and len(lines) == 1, lines
    assert lines[0].startswith(f"{start} on camera (= All, the only set compared): A - B")


def test_the_gate_line_gives_the_confidence_as_given(paper_like: Path, tmp_path: Path) -> None:
    good = _scaled(tmp_path, "good.csv", 1.0)
    _, lines = _gate(good, good, "--confidence", "0.999", "--resamples", "4000")
    assert "99.9% interval" in lines[0]
