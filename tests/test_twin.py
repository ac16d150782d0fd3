"""A file made for one ODMD benchmark, scored or added as the other's (odmd_bench.evaluation.scoring).

``odmd-v1`` and ``odmd-paper`` have the same sets and sizes, so only the depths can tell.
The ``odmd-paper`` here is a stand-in written by the test (other examples, the same
robot set as ``odmd-v1``), so that the real release is not needed.
"""

from __future__ import annotations

import dataclasses
import shutil
from pathlib import Path

import numpy as np
import pytest
from conftest import add_entry

import odmd_bench
import odmd_bench.leaderboard as lb
from odmd_bench import ValidationError
from odmd_bench.data.io import write_sets
from odmd_bench.data.registry import get_benchmark, set_file
from odmd_bench.evaluation.predictions import write_predictions
from odmd_bench.evaluation.scoring import FAR_BETTER, evaluate, twin_fit

PERTURB = {"normal": "normal", "camera": "camera", "object": "object"}


@pytest.fixture(scope="module")
def both(v1_data_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A data folder with odmd-v1 test and a stand-in odmd-paper test of the same sizes."""
    data = tmp_path_factory.mktemp("twin-data")
    target = set_file(get_benchmark("odmd-v1"), "test", data)
    target.parent.mkdir(parents=True)
    shutil.copy2(set_file(get_benchmark("odmd-v1"), "test", v1_data_dir), target)
    v1 = odmd_bench.load_split("test", "odmd-v1", data)
    paper = {
        s: odmd_bench.generate(len(v1[s]), perturbation=p, rng=90 + i)
        for i, (s, p) in enumerate(PERTURB.items())
    }
    robot = v1["robot"]  # the same arrays (and content hash), found as odmd-paper's
    paper["robot"] = dataclasses.replace(robot, attrs={**robot.attrs, "benchmark": "odmd-paper"})
    write_sets(
        set_file(get_benchmark("odmd-paper"), "test", data),
        paper,
        file_attrs={"benchmark": "odmd-paper", "split": "test"},
    )
    return data


def _truth(bench: str, data: Path, noise: float = 0.0) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(5)
    sets = odmd_bench.load_split("test", bench, data)
    return {s: ex.depth * (1 + rng.normal(0, noise, len(ex))) for s, ex in sets.items()}


def _twin_warnings(result: odmd_bench.EvaluationResult) -> list[str]:
    return [w for w in result.warnings if "far better" in w]


def test_a_file_for_odmd_paper_scored_by_default_against_odmd_v1_is_named(both: Path, tmp_path: Path) -> None:
    p = tmp_path / "paper.csv"
    write_predictions(p, "test", _truth("odmd-paper", both, 0.05))  # no benchmark column
    result = evaluate(p, data_dir=both)
    assert result.benchmark == "odmd-v1"  # scored as the contract says, and told
    (warning,) = _twin_warnings(result)
    assert "scored against odmd-v1, the default, as the file has no benchmark column" in warning
    assert "fit odmd-paper far better than odmd-v1" in warning and "on normal, camera, object)" in warning
    assert warning.endswith("score them with --benchmark odmd-paper")
    assert not _twin_warnings(evaluate(p, benchmark="odmd-paper", data_dir=both))
    # The same depths scored as asked are not changed by the check.
    again = evaluate(p, benchmark="odmd-v1", data_dir=both)
    assert again.all_percent_error_mean == result.all_percent_error_mean
    assert "as asked (--benchmark odmd-v1)" in _twin_warnings(again)[0]


def test_a_file_for_odmd_v1_asked_to_score_as_odmd_paper_is_named(both: Path, tmp_path: Path) -> None:
    p = tmp_path / "v1.csv"
    write_predictions(p, "test", _truth("odmd-v1", both, 0.2))
    (warning,) = _twin_warnings(evaluate(p, benchmark="odmd-paper", data_dir=both))
    assert "fit odmd-v1 far better than odmd-paper" in warning
    assert not _twin_warnings(evaluate(p, data_dir=both))


@pytest.mark.parametrize("noise", [0.0, 0.3, 1.0])
def test_depths_made_for_the_benchmark_scored_give_no_warning(
    both: Path, tmp_path: Path, noise: float
) -> None:
    p = tmp_path / "v1.csv"
    write_predictions(p, "test", _truth("odmd-v1", both, noise))
    result = evaluate(p, data_dir=both)
    assert not _twin_warnings(result)
    fit = twin_fit(result, both)
    assert fit is not None and fit.sets == ("normal", "camera", "object")  # robot is the same in both
    assert fit.other >= FAR_BETTER * fit.scored


def test_a_benchmark_column_is_taken_at_its_word(both: Path, tmp_path: Path) -> None:
    p = tmp_path / "paper-says-v1.csv"
    write_predictions(p, "test", _truth("odmd-paper", both), benchmark="odmd-v1")
    assert not _twin_warnings(evaluate(p, data_dir=both))


def test_no_twin_in_the_data_folder_means_no_check_and_nothing_built(
    v1_data_dir: Path, tmp_path: Path
) -> None:
    data = tmp_path / "data"
    target = set_file(get_benchmark("odmd-v1"), "test", data)
    target.parent.mkdir(parents=True)
    shutil.copy2(set_file(get_benchmark("odmd-v1"), "test", v1_data_dir), target)
    p = tmp_path / "v1.csv"
    write_predictions(p, "test", _truth("odmd-v1", data, 0.5))
    assert not _twin_warnings(evaluate(p, data_dir=data))
    assert not set_file(get_benchmark("odmd-paper"), "test", data).exists()


def _add(root: Path, data: Path, preds: Path, benchmark: str) -> lb.Entry:
    return add_entry(root, data, preds, "mine", name="Mine", command="my-method", benchmark=benchmark)


def test_leaderboard_add_refuses_a_file_that_fits_the_other_board(both: Path, tmp_path: Path) -> None:
    root = tmp_path / "leaderboard"
    (root / lb.ENTRIES).mkdir(parents=True)
    p = tmp_path / "paper.csv"
    write_predictions(p, "test", _truth("odmd-paper", both, 0.05))
    with pytest.raises(ValidationError) as info:
        _add(root, both, p, "odmd-v1")
    (problem,) = info.value.problems
    assert problem.startswith("its depths fit odmd-paper far better than odmd-v1 (mean percent error")
    assert "add them with --benchmark odmd-paper" in problem
    assert not list((root / lb.ENTRIES).iterdir())  # nothing written
    assert _add(root, both, p, "odmd-paper").meta.benchmark == "odmd-paper"
    # A benchmark column that says odmd-v1 is the user's word: the file is added there.
    said = tmp_path / "paper-says-v1.csv"
    write_predictions(said, "test", _truth("odmd-paper", both, 0.05), benchmark="odmd-v1")
    assert _add(root, both, said, "odmd-v1").meta.benchmark == "odmd-v1"
