"""The read-only scoring trip: ``score_file`` writes nothing; ``evaluate`` generates a missing split first.

Scoring a parsed file (:func:`~odmd_bench.evaluation.scoring.score_file`) reads and
verifies the sets and never writes: not the split it lacks, not the twin benchmark's,
not a lock. Generating a missing split of a generated benchmark is the step of the
entry point (``evaluate``, ``odmd-bench evaluate``).
"""

from __future__ import annotations

import hashlib
import os
import shutil
import stat
from pathlib import Path

import numpy as np
import pytest

import odmd_bench
from odmd_bench.data.registry import get_benchmark, set_file
from odmd_bench.errors import MissingDataError
from odmd_bench.evaluation.parse import parse_predictions
from odmd_bench.evaluation.scoring import evaluate, score_file

V1 = get_benchmark("odmd-v1")


def _snapshot(folder: Path) -> dict[str, tuple[int, int, str]]:
    """Every entry under ``folder``: its mode, modification time and (for a file) content hash."""
    out = {}
    for p in sorted(folder.rglob("*")):
        st = p.lstat()
        digest = hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else ""
        out[p.relative_to(folder).as_posix()] = (st.st_mode, st.st_mtime_ns, digest)
    return out


def _read_only(folder: Path) -> dict[Path, int]:
    """Take the write bits off everything under ``folder``; return the modes to restore."""
    modes = {p: p.stat().st_mode for p in [folder, *folder.rglob("*")]}
    for p, mode in modes.items():
        os.chmod(p, mode & ~(stat.S_IWUSR | stat.S_IWGRP | stat.S_IWOTH))
    return modes


@pytest.fixture()
def preds(tmp_path: Path, v1_data_dir: Path) -> Path:
    """Predictions for ``odmd-v1`` val, 10 % too deep, without a benchmark column."""
    sets = odmd_bench.load_split("val", "odmd-v1", data_dir=v1_data_dir)
    path = tmp_path / "preds.csv"
    lines = [f"val,{s},{i},{1.1 * z!r}" for s, ex in sets.items() for i, z in enumerate(ex.depth.tolist())]
    path.write_text("split,set,index,depth\n" + "\n".join(lines) + "\n", encoding="utf-8")
    return path


def test_score_file_reads_a_read_only_data_folder_and_writes_nothing(
    tmp_path: Path, v1_data_dir: Path, preds: Path
) -> None:
    data = tmp_path / "data"
    (data / "odmd-v1").mkdir(parents=True)
    shutil.copy2(set_file(V1, "val", v1_data_dir), set_file(V1, "val", data))
    before = _snapshot(data)
    modes = _read_only(data)  # refuses writes where the tests do not run as root
    try:
        result = score_file(parse_predictions(preds, strict=False), data)
        narrowed = score_file(parse_predictions(preds, strict=False), data, sets=["robot", "normal"])
    finally:
        for p, mode in modes.items():
            os.chmod(p, mode)
    # Nothing made (no lock, no temporary file, not the twin odmd-paper's split), nothing changed.
    assert _snapshot(data) == before
    assert sorted(before) == ["odmd-v1", "odmd-v1/val.h5"]
    assert list(result.sets) == list(V1.sets)
    assert result.all_percent_error_mean == pytest.approx(10.0, rel=1e-12)
    assert list(narrowed.sets) == ["normal", "robot"]  # the benchmark's order, as evaluate gives
    # The same scores as the entry point, which had nothing to generate here.
    same = evaluate(preds, data_dir=data)
    assert same.sets == result.sets and same.warnings == result.warnings
    assert same.provenance == result.provenance
    for s in result.sets:
        np.testing.assert_array_equal(same.predictions[s], result.predictions[s])


def test_score_file_refuses_a_missing_split_with_the_command_and_creates_nothing(
    tmp_path: Path, preds: Path
) -> None:
    data = tmp_path / "empty"
    data.mkdir()
    parsed = parse_predictions(preds, strict=False)
    with pytest.raises(MissingDataError) as info:
        score_file(parsed, data)
    assert f"run `odmd-bench generate --data-dir {data}` first" in info.value.message
    assert info.value.message.startswith("odmd-v1 val is not in the data folder")
    assert list(data.iterdir()) == []


def test_evaluate_still_generates_the_missing_split_then_scores_it_read_only(
    tmp_path: Path, preds: Path
) -> None:
    data = tmp_path / "fresh"
    result = evaluate(preds, data_dir=data)
    assert set_file(V1, "val", data).is_file()
    assert not set_file(V1, "test", data).exists()  # only the split of the file
    assert result.all_percent_error_mean == pytest.approx(10.0, rel=1e-12)
    again = score_file(parse_predictions(preds, strict=False), data)
    assert again.sets == result.sets and again.provenance == result.provenance
