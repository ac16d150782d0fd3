"""Every entry of this repository's own methods is what its ``command`` writes with the code and weights here.

``odmd-bench leaderboard check`` re-scores the committed predictions: it proves the table
is what the files say, not that the files are what the shipped methods and weights
produce. This test re-runs the command of each entry whose ``code`` is in ``baselines/``
and compares the predictions, so an entry left stale by new weights or a changed method
fails here instead of passing CI. Entries of methods whose code lives elsewhere are
re-scored by ``check`` only.
"""

from __future__ import annotations

import shlex
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from odmd_bench.cli.main import cli
from odmd_bench.leaderboard.files import discover, read_entry

BOARD = Path(__file__).resolve().parents[1] / "leaderboard"
#: how an entry's command names the user's copy of the original release (the release checkpoint's entries)
RELEASE_PLACEHOLDER = "ODMD/"

#: the entries of this repository's methods (their ``code`` is a path under ``baselines/``)
OWN_ENTRIES = [f for f in discover(BOARD) if read_entry(f).meta.code.startswith("baselines/")]

#: DBox's depths computed once per run for the same network and input (tests/conftest.py,
#: ``dbox_depths_shared``): the entries of odmd-paper and odmd-v1 share sets, and other
#: test files check the same shipped weights on the same sets against their recorded numbers
pytestmark = pytest.mark.usefixtures("dbox_depths_made_once")


def _argv(command: str, release: Path, out: Path, data_dir: Path) -> list[str]:
    """The command as arguments of ``odmd-bench``: output to ``out``, data from ``data_dir``.

    A command may end in a note in parentheses, and may name a file of the original release
    as ``ODMD/...``; both are resolved here.
    """
    words = shlex.split(command)
    if any(w.startswith("(") for w in words):
        words = words[: next(i for i, w in enumerate(words) if w.startswith("("))]
    assert words[:2] == ["odmd-bench", "baseline"], command
    assert words.count("-o") == 1, command
    words[words.index("-o") + 1] = str(out)
    words = [
        str(release / w[len(RELEASE_PLACEHOLDER) :]) if w.startswith(RELEASE_PLACEHOLDER) else w
        for w in words
    ]
    return [*words[1:], "--data-dir", str(data_dir)]


def _depths(path: Path) -> pd.Series:
    frame = pd.read_csv(path, comment="#")
    return frame.set_index(["split", "set", "index"])["depth"].sort_index()


def test_every_board_has_entries_to_re_run() -> None:
    assert {f.name for f in OWN_ENTRIES} == {
        "odmd-paper-test",
        "odmd-v1-test",
        "odms-detection-test",
        "kitti-tracking-test",
    }


@pytest.mark.parametrize("folder", OWN_ENTRIES, ids=lambda p: f"{p.parent.name}/{p.name}")
def test_each_entry_is_what_its_command_writes(
    folder: Path, original_release: Path, paper_data_dir: Path, v1_data_dir: Path, tmp_path: Path
) -> None:
    entry = read_entry(folder)
    if " dbox" in entry.meta.command:
        pytest.importorskip("torch")  # the [dbox] extra
    data_dir = v1_data_dir if entry.meta.benchmark == "odmd-v1" else paper_data_dir
    out = tmp_path / "predictions.csv"
    run = CliRunner().invoke(cli, _argv(entry.meta.command, original_release, out, data_dir))
    assert run.exit_code == 0, run.output
    committed, rerun = _depths(entry.predictions), _depths(out)
    assert committed.index.equals(rerun.index), entry.key
    # float32 products differ in the last bits between processors (and the oneDNN kernel some
    # entries were made with before issue 44 dropped it), so not compared exactly
    np.testing.assert_allclose(
        rerun.to_numpy(), committed.to_numpy(), rtol=1e-4, atol=1e-6, err_msg=entry.key
    )
