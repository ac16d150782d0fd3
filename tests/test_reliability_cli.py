"""The command line's conventions and failure modes (issue 16 item 11, issue 17 item 5)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import click
import pytest
from click.testing import CliRunner

from odmd_bench.cli.main import EXIT_BROKEN_PIPE, cli
from odmd_bench.cli.options import DATA_DIR_HELP


def _commands(group: click.Group, prefix: tuple[str, ...] = ()) -> list[tuple[str, ...]]:
    out = []
    for name, cmd in group.commands.items():
        out.append((*prefix, name))
        if isinstance(cmd, click.Group):
            out.extend(_commands(cmd, (*prefix, name)))
    return out


def test_every_command_takes_dash_h() -> None:
    runner = CliRunner()
    names = _commands(cli)
    assert ("generate",) in names and ("import",) in names
    for path in [(), *names]:
        short = runner.invoke(cli, [*path, "-h"])
        long = runner.invoke(cli, [*path, "--help"])
        assert short.exit_code == 0 and short.stdout.startswith("Usage: "), (path, short.output)
        assert short.stdout == long.stdout


def test_python_dash_m() -> None:
    done = subprocess.run(
        [sys.executable, "-m", "odmd_bench", "--version"], capture_output=True, text=True, check=False
    )
    assert done.returncode == 0 and done.stdout.startswith("odmd-bench, version ")
    done = subprocess.run(
        [sys.executable, "-m", "odmd_bench", "-h"], capture_output=True, text=True, check=False
    )
    assert done.returncode == 0 and done.stdout.startswith("Usage: odmd-bench ")


@pytest.mark.parametrize("args", [["info", "FILE"], ["info", "--json", "FILE"], ["data-dir"]])
def test_a_closed_pipe_ends_quietly(tmp_path: Path, args: list[str]) -> None:
    from odmd_bench.data.generator import generate
    from odmd_bench.data.io import write_sets

    f = tmp_path / "x.h5"
    write_sets(f, {s: generate(3, rng=i) for i, s in enumerate(("normal", "camera", "object", "robot"))})
    cmd = [sys.executable, "-m", "odmd_bench", *(str(f) if a == "FILE" else a for a in args)]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    assert proc.stdout is not None and proc.stderr is not None
    proc.stdout.close()  # as `| head -0` does: the reader is gone before the output
    err = proc.stderr.read().decode()
    proc.stderr.close()
    code = proc.wait()
    assert "Traceback" not in err and "Exception ignored" not in err, err
    assert code in (0, EXIT_BROKEN_PIPE)
    shell = subprocess.run(
        f"{' '.join(cmd)} | head -1", shell=True, capture_output=True, text=True, check=False
    )
    assert "Traceback" not in shell.stderr and "Error" not in shell.stderr, shell.stderr
    assert len(shell.stdout.splitlines()) == 1


def test_json_errors_with_format_json(tmp_path: Path) -> None:
    runner = CliRunner()
    r = runner.invoke(cli, ["evaluate", str(tmp_path / "none.csv"), "--format", "json"])
    assert r.exit_code == 2
    body = json.loads(r.stderr)
    assert set(body) == {"error", "problems"} and body["problems"], body
    r = runner.invoke(cli, ["evaluate", "--format=json", str(tmp_path / "none.csv"), "--bogus"])
    assert r.exit_code == 2 and "--bogus" in json.loads(r.stderr)["error"]
    r = runner.invoke(cli, ["evaluate", str(tmp_path / "none.csv")])
    assert r.exit_code == 2 and r.stderr.startswith("error: ")


def test_an_os_error_is_one_clear_line(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import odmd_bench.data.io as io_mod

    def denied(path: object) -> None:
        raise PermissionError(13, "Permission denied", str(path))

    monkeypatch.setattr(io_mod, "file_summary", denied)
    r = CliRunner().invoke(cli, ["info", str(tmp_path / "x.h5")])
    assert r.exit_code == 2
    assert r.stderr == f"error: {tmp_path / 'x.h5'}: Permission denied\n"


def test_a_corrupt_file_in_info_is_a_clear_error(tmp_path: Path) -> None:
    from odmd_bench.data.generator import generate
    from odmd_bench.data.io import write_sets

    f = tmp_path / "x.h5"
    write_sets(f, {"normal": generate(3)})
    data = bytearray(f.read_bytes())
    data[499] ^= 0x80
    f.write_bytes(bytes(data))
    r = CliRunner().invoke(cli, ["info", str(f)])
    assert r.exit_code in (0, 2) and "Traceback" not in r.output


def test_data_dir_option_is_declared_once() -> None:
    for name in ("generate", "import"):
        opts = {o.name: o for o in cli.commands[name].params}
        assert opts["data_dir"].help == DATA_DIR_HELP
    generate_opts = {o.name: o for o in cli.commands["generate"].params}
    assert "--out" in generate_opts["data_dir"].opts


def test_data_folder_follows_the_os_convention(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from odmd_bench.data.registry import default_data_dir

    monkeypatch.delenv("ODMD_BENCH_DATA", raising=False)
    import platformdirs

    assert default_data_dir() == Path(platformdirs.user_data_dir("odmd-bench", appauthor=False))
    if sys.platform.startswith("linux"):  # platformdirs follows XDG there
        monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "xdg"))
        assert default_data_dir() == tmp_path / "xdg" / "odmd-bench"
    monkeypatch.setenv("ODMD_BENCH_DATA", str(tmp_path / "env"))
    assert default_data_dir() == tmp_path / "env"
    r = CliRunner().invoke(cli, ["data-dir"], env={"ODMD_BENCH_DATA": str(tmp_path / "env")})
    assert r.stdout.strip() == str(tmp_path / "env")


def test_help_names_the_data_folder_rule() -> None:
    r = CliRunner().invoke(cli, ["import", "-h"])
    text = " ".join(r.stdout.split())
    assert "$ODMD_BENCH_DATA" in text and "user data folder" in text


def test_a_removed_current_folder_is_named_as_such(tmp_path: Path) -> None:
    gone = tmp_path / "gone"
    gone.mkdir()
    code = (
        "import os, sys\n"
        f"os.chdir({str(gone)!r}); os.rmdir({str(gone)!r})\n"
        "sys.argv = ['odmd-bench', 'baseline', 'box-ls']\n"
        "from odmd_bench.cli.main import main\n"
        "main()\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == 2, done.stderr
    assert "error: the current folder no longer exists (it was removed)" in done.stderr
    assert "Traceback" not in done.stderr


def test_a_closed_pipe_is_141_however_large_the_output(tmp_path: Path) -> None:
    """Python's buffered stdout takes a partial write without an error: the rest was dropped, status 0."""
    import os

    from odmd_bench.data.generator import generate
    from odmd_bench.data.io import write_sets
    from odmd_bench.data.registry import get_benchmark, set_file

    data = tmp_path / "data"
    sets = {s: generate(1500, rng=i) for i, s in enumerate(("normal", "camera", "object", "robot"))}
    write_sets(set_file(get_benchmark("odmd-paper"), "test", data), sets)
    env = {**os.environ, "ODMD_BENCH_DATA": str(data)}
    preds = tmp_path / "p.csv"
    run = [sys.executable, "-m", "odmd_bench"]
    subprocess.run(
        [*run, "baseline", "box-ls", "--benchmark", "odmd-paper", "-o", str(preds)],
        env=env,
        check=True,
        capture_output=True,
    )
    for args in (
        ["baseline", "box-ls", "--benchmark", "odmd-paper", "-o", "-"],
        [
            "evaluate",
            str(preds),
            "--benchmark",
            "odmd-paper",
            "-o",
            str(tmp_path / "r.txt"),
            "--per-example",
            "-",
        ],
    ):
        whole = subprocess.run([*run, *args], env=env, capture_output=True, check=False)
        assert whole.returncode == 0 and len(whole.stdout) > 200_000  # more than a pipe holds
        proc = subprocess.Popen([*run, *args], env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        assert proc.stdout is not None and proc.stderr is not None
        assert proc.stdout.read(10) == whole.stdout[:10]
        proc.stdout.close()  # as `| head -c 10` does: the reader leaves mid-output
        err = proc.stderr.read().decode()
        proc.stderr.close()
        assert proc.wait() == EXIT_BROKEN_PIPE, (args, err)
        assert "Traceback" not in err and "Exception ignored" not in err
