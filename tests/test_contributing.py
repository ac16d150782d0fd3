"""CONTRIBUTING.md walked as a contributor walks it, and two entry pull requests merged.

The contributor's test reads the commands from CONTRIBUTING.md itself (its ``bash``
blocks, and the plug-in package from its ``toml`` and ``python`` blocks), so the page is
what is tested: in a copy of this repository's tree (a git repository of its own), a
plug-in method in a package outside it, installed for the test (a ``.dist-info`` with its
entry point on ``sys.path``, as pip would write it), makes predictions for ``odmd-v1 test``
and ``odmd-paper test``, adds the entries, and commits; then, with the plug-in no longer
installed (CI does not have it), ``leaderboard check`` and the tests that read the
committed tree pass on that tree.
"""

from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import tomllib
import yaml
from click.testing import CliRunner
from conftest import boards_data, original_dir

from odmd_bench import leaderboard as lb
from odmd_bench.cli.main import cli
from odmd_bench.leaderboard.site import build_site
from odmd_bench.leaderboard.speed import THREAD_VARIABLES

#: The boards here hold the same files build after build: each parsed and resampled once (conftest).
pytestmark = pytest.mark.usefixtures("boards_ranked_once")

REPO = Path(__file__).resolve().parents[1]
GUIDE = REPO / "CONTRIBUTING.md"
#: The only words of the page a contributor replaces: where their copy of the release is.
ORIGINAL_PLACEHOLDER = "PATH/TO/odmd-original"
GIT_ENV = {
    "GIT_AUTHOR_NAME": "Contributor",
    "GIT_AUTHOR_EMAIL": "contributor@example.org",
    "GIT_COMMITTER_NAME": "Contributor",
    "GIT_COMMITTER_EMAIL": "contributor@example.org",
    "GIT_CONFIG_GLOBAL": os.devnull,
    "GIT_CONFIG_NOSYSTEM": "1",
}


def _blocks(text: str, language: str) -> list[str]:
    """The fenced code blocks of ``language`` in a markdown text, in order."""
    return re.findall(rf"^```{language}\n(.*?)^```$", text, flags=re.MULTILINE | re.DOTALL)


def _commands(block: str) -> list[str]:
    """A bash block's commands: continuation lines joined, comments dropped."""
    joined = block.replace("\\\n", " ")
    out = []
    for line in joined.splitlines():
        words = shlex.split(line, comments=True)
        if words:
            out.append(shlex.join(words))
    return out


def _git(tree: Path, *args: str) -> str:
    done = subprocess.run(
        ["git", *args], cwd=tree, env={**os.environ, **GIT_ENV}, capture_output=True, text=True, check=False
    )
    assert done.returncode == 0, (args, done.stdout, done.stderr)
    return done.stdout


def _copy_tree(dest: Path) -> Path:
    """This repository's tree (its tracked and new files; no checkpoints) as a git repository of its own, on main."""
    if not (REPO / ".git").exists():
        pytest.skip("not a git checkout")
    listed = _git(REPO, "ls-files", "--cached", "--others", "--exclude-standard", "-z").split("\0")
    for name in listed:
        src = REPO / name
        if not name or name.endswith(".pt") or not src.is_file():  # weights: not read by any gate here
            continue
        (dest / name).parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(src, dest / name)
    _git(dest, "init", "-q", "-b", "main")
    _git(dest, "add", "-A")
    _git(dest, "commit", "-q", "-m", "main")
    return dest


def _install_plugin(package: Path, site: Path) -> None:
    """Install the package as pip would for the test: its modules and a ``.dist-info`` on ``site``."""
    project = tomllib.loads((package / "pyproject.toml").read_text())["project"]
    name, version = project["name"], project["version"]
    shutil.copytree(package / name.replace("-", "_"), site / name.replace("-", "_"))
    info = site / f"{name.replace('-', '_')}-{version}.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {name}\nVersion: {version}\n")
    points = project["entry-points"]
    (info / "entry_points.txt").write_text(
        "".join(
            f"[{group}]\n" + "".join(f"{k} = {v}\n" for k, v in eps.items()) for group, eps in points.items()
        )
    )


@pytest.fixture
def contributor(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[dict[str, Path]]:
    """A copy of the tree, the contributor's package beside it (outside), a data folder; cwd is the tree."""
    original = original_dir()
    tree = _copy_tree(tmp_path / "odmd-bench")
    guide = (tree / "CONTRIBUTING.md").read_text()
    package_files = [
        b for lang in ("toml", "python") for b in _blocks(guide, lang) if b.startswith("# my-depth/")
    ]
    for block in package_files:
        path = tmp_path / block.splitlines()[0].removeprefix("# ")
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(block.split("\n", 1)[1] if path.suffix == ".toml" else block)
    assert (tmp_path / "my-depth" / "pyproject.toml").is_file() and (
        tmp_path / "my-depth" / "my_depth"
    ).is_dir()
    data = tmp_path / "data"
    monkeypatch.setenv("ODMD_BENCH_DATA", str(data))
    for v in THREAD_VARIABLES:  # as `leaderboard speed` runs itself (not again in a child: the
        monkeypatch.setenv(v, "1")  # plug-in is installed for this process only)
    monkeypatch.chdir(tree)
    yield {"tree": tree, "package": tmp_path / "my-depth", "site": tmp_path / "site", "original": original}
    for name in [m for m in sys.modules if m == "my_depth" or m.startswith("my_depth.")]:
        del sys.modules[name]


def _run(command: str, original: Path) -> Any:
    words = shlex.split(command.replace(ORIGINAL_PLACEHOLDER, str(original)))
    assert words[0] == "odmd-bench", command
    result = CliRunner().invoke(cli, words[1:])
    assert result.exit_code == 0, (command, result.output)
    return result


def test_contributing_walked_as_a_contributor_passes_the_gates_without_the_plugin(
    contributor: dict[str, Path], monkeypatch: pytest.MonkeyPatch
) -> None:
    tree, original = contributor["tree"], contributor["original"]
    guide = (tree / "CONTRIBUTING.md").read_text()
    steps = guide[guide.index("## Step by step") : guide.index("## What CI checks")]
    commands = [c for block in _blocks(steps, "bash") for c in _commands(block)]
    assert [c.split()[:3] for c in commands if c.startswith("odmd-bench leaderboard")] == [
        ["odmd-bench", "leaderboard", "speed"],
        ["odmd-bench", "leaderboard", "add"],
        ["odmd-bench", "leaderboard", "add"],
        ["odmd-bench", "leaderboard", "check"],
        ["odmd-bench", "leaderboard", "build"],
    ]
    site = contributor["site"]
    _install_plugin(contributor["package"], site)
    monkeypatch.syspath_prepend(str(site))
    said = []
    for command in commands:
        if command.startswith("pip "):
            continue  # odmd-bench is installed; the plug-in was installed above
        if command.startswith("git "):
            _git(tree, *shlex.split(command)[1:])
            continue
        said.append(_run(command, original).output)
    # The entry folders, as add wrote them: the honesty fields, the pinned plug-in, the records.
    for board in ("odmd-v1-test", "odmd-paper-test"):
        meta = yaml.safe_load(
            (tree / "leaderboard" / "entries" / "my-depth" / board / "entry.yaml").read_text()
        )
        assert meta["plugin"] == {"requirement": "my-depth==0.1.0"}
        assert (meta["uses_test_labels"], meta["selected_on"], meta["training_kind"]) == (
            False,
            "nothing",
            "none",
        )
        assert meta["command"].startswith("odmd-bench baseline my-depth --benchmark ")
        assert set(meta["scores"]) == {"normal", "camera", "object", "robot", "all"}
        assert meta["scores"]["all"] == pytest.approx(
            np.mean([meta["scores"][s] for s in meta["scores"] if s != "all"])
        )
    speed = yaml.safe_load(
        (tree / "leaderboard" / "entries" / "my-depth" / "odmd-v1-test" / "entry.yaml").read_text()
    )["speed"]
    assert speed["examples_per_second"] > 0 and speed["command"].startswith(
        "odmd-bench leaderboard speed my-depth"
    )
    # The pull request is the entry folder and nothing else; nothing is left to commit.
    changed = _git(tree, "diff", "--name-only", "main", "HEAD").split()
    assert changed and all(p.startswith("leaderboard/entries/my-depth/") for p in changed)
    assert _git(tree, "status", "--porcelain") == ""

    # CI: the plug-in is not installed.
    sys.path.remove(str(site))
    for name in [m for m in sys.modules if m == "my_depth" or m.startswith("my_depth.")]:
        del sys.modules[name]
    assert "my-depth" not in CliRunner().invoke(cli, ["baseline", "--list"]).output
    check = CliRunner().invoke(cli, ["leaderboard", "check", "--original", str(original)])
    assert check.exit_code == 0, check.output
    # The site shows the entry, and how to get its plug-in before its command.
    files, _ = build_site(tree / "leaderboard", figures=False, n_resamples=200)
    page = files["methods/my-depth.html"].decode()
    assert "pip install my-depth==0.1.0\nodmd-bench baseline my-depth --benchmark odmd-v1" in page
    assert "<dt>Selected on</dt><dd>nothing</dd>" in page and "<dt>Test labels used</dt><dd>no</dd>" in page
    data = os.environ["ODMD_BENCH_DATA"]
    tests = [
        "tests/test_leaderboard.py",
        "-k",
        "committed or audit_matches or downloads_are_the_board or every_number or honesty_fields",
        "tests/test_leaderboard_audit.py",
        "tests/test_site.py",
    ]
    env = {**os.environ, "ODMD_ORIGINAL": str(original), "ODMD_BENCH_DATA": data}
    done = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:randomly", "-p", "no:cacheprovider", *tests],
        cwd=tree,
        env=env,
        capture_output=True,
        text=True,
        check=False,
    )
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-2000:]
    assert " passed" in done.stdout and "skipped" not in done.stdout.splitlines()[-1]


def _nudged_predictions(source: Path, out: Path, factor: float) -> Path:
    """The predictions of a committed entry with every depth times ``factor`` (a new, made-up result)."""
    import gzip

    lines = gzip.decompress(source.read_bytes()).decode().splitlines()
    col = lines[0].split(",").index("depth")
    rows = [lines[0]]
    for line in lines[1:]:
        cells = line.split(",")
        cells[col] = repr(float(cells[col]) * factor)
        rows.append(",".join(cells))
    out.write_text("\n".join(rows) + "\n")
    return out


def test_two_entry_pull_requests_from_one_main_merge_without_conflict_and_pass_the_gates(
    tmp_path: Path, paper_data_dir: Path, v1_data_dir: Path
) -> None:
    data = boards_data(tmp_path / "data", paper_data_dir, v1_data_dir)
    tree = _copy_tree(tmp_path / "odmd-bench")
    root = tree / "leaderboard"
    box_ls = root / "entries" / "box-ls" / "odmd-v1-test" / "predictions.csv.gz"
    for branch, factor in (("add-a", 1.01), ("add-b", 1.02)):
        _git(tree, "checkout", "-q", "-b", branch, "main")
        preds = _nudged_predictions(box_ls, tmp_path / f"{branch}.csv", factor)
        lb.add_entry(
            root,
            preds,
            method=f"method-{branch}",
            name=f"Method {branch}",
            description="Box_LS scaled (a test entry).",
            paper="none",
            code="https://example.org/code",
            training_data="none",
            training_kind="none",
            selected_on="nothing",
            uses_test_labels=False,
            command="python make.py",
            benchmark="odmd-v1",
            split="test",
            calibrated=False,
            data_dir=data,
        )
        lb.write(lb.build_folder(root), lb.build(root, data, n_resamples=200), plot=False)  # ignored by git
        _git(tree, "add", "-A")
        assert _git(tree, "status", "--porcelain").split() == [
            "A",
            f"leaderboard/entries/method-{branch}/odmd-v1-test/entry.yaml",
            "A",
            f"leaderboard/entries/method-{branch}/odmd-v1-test/predictions.csv.gz",
        ]
        _git(tree, "commit", "-q", "-m", f"leaderboard: add method-{branch}")
    _git(tree, "checkout", "-q", "main")
    _git(tree, "merge", "-q", "--no-edit", "add-a")
    _git(tree, "merge", "-q", "--no-edit", "add-b")  # a real merge: add-b was cut from the old main
    assert len(_git(tree, "log", "--merges", "--oneline").splitlines()) == 1
    report = lb.check_report(root, data)
    assert report == lb.CheckReport([], [])
    built = lb.build(root, data, n_resamples=200)
    (v1,) = [b for b in built.boards if b.benchmark == "odmd-v1"]
    assert {"method-add-a", "method-add-b"} <= {r.entry.method for r in v1.rows}
