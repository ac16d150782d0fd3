"""The original release's own DBox_p checkpoint, scored through the CLI, gives the published numbers.

``DBox_pretrained_paper.pt`` (the paper's 10M-iteration DBox_p) is the release's file,
under its non-commercial terms: it is read from the original release's folder and never
copied into the repository. The test fails in CI (``CI`` set) when the file is missing,
and skips elsewhere, like every test of the original release (``tests/conftest.py``).
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Callable
from pathlib import Path

import pytest

pytest.importorskip("torch")


CHECKPOINT = "results/model/DBox_pretrained/DBox_pretrained_paper.pt"
#: The paper's Table 1 row of DBox_p, and the release's stated val results.
PUBLISHED = {
    "test": {"normal": 1.73, "camera": 2.45, "object": 2.54, "robot": 11.17, "all": 4.47},
    "val": {"normal": 1.65, "camera": 2.44, "object": 2.62, "robot": 11.18},
}
TOLERANCE = 0.006  # the published numbers are rounded to two decimals


@pytest.fixture(scope="module")
def release_checkpoint(original_release: Path) -> Path:
    """The release's checkpoint, checked against the release's ``SHA256SUMS``."""
    path = original_release / CHECKPOINT
    if not path.is_file():
        message = f"the release's checkpoint is not at {path}"
        if os.environ.get("CI"):
            pytest.fail(message + "; CI must have it", pytrace=False)
        pytest.skip(message)
    sums = dict(
        reversed(line.split(None, 1)) for line in (original_release / "SHA256SUMS").read_text().splitlines()
    )
    assert hashlib.sha256(path.read_bytes()).hexdigest() == sums[CHECKPOINT]
    return path


@pytest.mark.parametrize("split", ["test", "val"])
def test_the_release_checkpoint_gives_the_published_numbers(
    split: str,
    release_checkpoint: Path,
    paper_data_dir: Path,
    tmp_path: Path,
    dbox_scores: Callable[..., dict[str, float]],
) -> None:
    got = dbox_scores(paper_data_dir, tmp_path, "odmd-paper", split, "--weights", str(release_checkpoint))
    far = {k: (round(got[k], 4), v) for k, v in PUBLISHED[split].items() if abs(got[k] - v) > TOLERANCE}
    assert not far, f"{split}: (measured, published) beyond {TOLERANCE}: {far}"


def test_a_damaged_copy_of_the_release_checkpoint_is_refused(
    release_checkpoint: Path, paper_data_dir: Path, tmp_path: Path
) -> None:
    from click.testing import CliRunner

    from odmd_bench.cli.main import cli

    data = bytearray(release_checkpoint.read_bytes())
    data[-3000] ^= 1  # one bit inside a tensor: torch would load it
    copy = tmp_path / release_checkpoint.name
    copy.write_bytes(bytes(data))
    args = [
        "baseline",
        "dbox",
        "--benchmark",
        "odmd-paper",
        "--data-dir",
        str(paper_data_dir),
        "-o",
        str(tmp_path / "p.csv"),
    ]
    r = CliRunner().invoke(cli, [*args, "--weights", str(copy)])  # known by its name: its pinned hash
    assert r.exit_code == 2 and "do not match the release's hash in splits/odmd-original.json" in r.stderr
    renamed = tmp_path / "mine.pt"
    renamed.write_bytes(bytes(data))
    good = hashlib.sha256(release_checkpoint.read_bytes()).hexdigest()
    r = CliRunner().invoke(cli, [*args, "--weights", str(renamed), "--weights-sha256", good])
    assert r.exit_code == 2 and "do not match the given weights_sha256" in r.stderr
    assert not (tmp_path / "p.csv").exists()
