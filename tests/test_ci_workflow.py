"""docs/ci-workflow.yml: its steps run as written, pass on the baseline, fail on a regression.

The steps that set up the machine (check-out, Python, ``pip install``, the artifact
upload) are skipped; every other ``run:`` is given to ``bash -e`` as GitHub does, in a
temporary folder, with the installed ``odmd-bench`` on the PATH and the job's
``ODMD_BENCH_DATA`` pointed at a temporary data folder.
"""

from __future__ import annotations

import csv
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
import yaml

import odmd_bench

WORKFLOW = Path(__file__).resolve().parents[1] / "docs" / "ci-workflow.yml"


def _job() -> dict[str, Any]:
    workflow = yaml.safe_load(WORKFLOW.read_text(encoding="utf-8"))
    triggers = workflow.get("on", workflow.get(True))  # YAML 1.1 reads the key `on` as True
    assert set(triggers) == {"push", "pull_request"}
    (job,) = workflow["jobs"].values()
    return job


def _set_up(step: dict[str, Any]) -> bool:
    return "uses" in step or "pip install" in step.get("run", "")


def _steps() -> dict[str, str]:
    """The steps that are run here, by name, in order."""
    return {s["name"]: s["run"] for s in _job()["steps"] if not _set_up(s)}


@pytest.fixture
def repo(tmp_path: Path) -> tuple[Path, dict[str, str]]:
    """A folder standing for the method's repository checkout, and the steps' environment."""
    env = dict(os.environ)
    job_env = _job()["env"]
    assert set(job_env) == {"ODMD_BENCH_DATA", "ODMD_BENCH_SOURCE"}
    env["ODMD_BENCH_DATA"] = str(tmp_path / "data")
    env["PATH"] = os.path.dirname(sys.executable) + os.pathsep + env["PATH"]
    work = tmp_path / "repo"
    work.mkdir()
    return work, env


def _run(script: str, cwd: Path, env: dict[str, str]) -> subprocess.CompletedProcess[str]:
    return subprocess.run(["bash", "-e", "-c", script], cwd=cwd, env=env, capture_output=True, text=True)


def test_the_workflow_has_the_documented_steps() -> None:
    names = [s["name"] for s in _job()["steps"]]
    skipped = [s["name"] for s in _job()["steps"] if _set_up(s)]
    assert skipped == ["Check out", "Set up Python", "Install", "Keep the predictions"]
    install = _job()["steps"][names.index("Install")]["run"]
    assert 'pip install "$ODMD_BENCH_SOURCE"' in install  # odmd-bench is not on PyPI
    source = _job()["env"]["ODMD_BENCH_SOURCE"]
    assert source.startswith("odmd-bench @ git+") and "@v" + odmd_bench.__version__ in source
    steps = _steps()
    assert list(steps) == [
        "Generate the benchmark",
        "Run the method",
        "Evaluate",
        "Compare with the committed baseline",
    ]
    assert "--max-all" in steps["Evaluate"]
    assert "ci/baseline-preds.csv preds.csv --fail-if-worse" in steps["Compare with the committed baseline"]


def test_the_steps_pass_on_the_committed_baseline(repo: tuple[Path, dict[str, str]]) -> None:
    work, env = repo
    steps = _steps()
    # What the method's author commits once: the method's own predictions.
    setup = _run(steps["Generate the benchmark"] + "\n" + steps["Run the method"], work, env)
    assert setup.returncode == 0, setup.stderr
    (work / "ci").mkdir()
    shutil.move(work / "preds.csv", work / "ci" / "baseline-preds.csv")
    for name, script in steps.items():
        done = _run(script, work, env)
        assert done.returncode == 0, f"{name}: {done.stdout}\n{done.stderr}"
    assert (work / "per-example.csv").is_file()


def test_the_job_fails_when_the_method_gets_worse(repo: tuple[Path, dict[str, str]]) -> None:
    work, env = repo
    steps = _steps()
    for name in ("Generate the benchmark", "Run the method"):
        assert _run(steps[name], work, env).returncode == 0
    (work / "ci").mkdir()
    shutil.copy(work / "preds.csv", work / "ci" / "baseline-preds.csv")
    # A regression: every depth 5% too far.
    with open(work / "preds.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    with open(work / "preds.csv", "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(rows[0]))
        writer.writeheader()
        for row in rows:
            writer.writerow({**row, "depth": repr(float(row["depth"]) * 1.05)})
    evaluate = _run(steps["Evaluate"], work, env)
    assert evaluate.returncode == 1, evaluate.stdout + evaluate.stderr
    compare = _run(steps["Compare with the committed baseline"], work, env)
    assert compare.returncode == 1, compare.stdout + compare.stderr
    assert "significantly worse" in compare.stdout + compare.stderr


def test_what_the_comment_says_of_sets_is_what_compare_does(repo: tuple[Path, dict[str, str]]) -> None:
    """With --sets, All covers those sets alone (not all four) and each set is a gate too."""
    comment = WORKFLOW.read_text(encoding="utf-8").split("\nname:")[0]
    assert (
        "With --sets\n# normal,robot, compare scores those two sets only: All is then their mean alone"
        in comment
    )
    work, env = repo
    steps = _steps()
    for name in ("Generate the benchmark", "Run the method"):
        assert _run(steps[name], work, env).returncode == 0
    command = steps["Compare with the committed baseline"].replace("ci/baseline-preds.csv", "preds.csv")
    done = _run(command + " --sets normal,robot --format json", work, env)
    assert done.returncode == 0, done.stderr
    result = json.loads(done.stdout)
    assert list(result["sets"]) == ["normal", "robot"]
    assert result["all"]["n"] == result["sets"]["normal"]["n"] + result["sets"]["robot"]["n"]
    gates = [
        line.split(":")[0] + ":" + line.split(":")[1]
        for line in done.stderr.splitlines()
        if line.startswith("ok")
    ]
    assert gates == [
        "ok: not significantly worse on All",
        "ok: not significantly worse on normal",
        "ok: not significantly worse on robot",
    ]
