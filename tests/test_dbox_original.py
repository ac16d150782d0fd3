"""A checkpoint from the original release gives, through odmd-bench, the original code's predictions.

The release's own checkpoint (``DBox_pretrained_paper.pt``) is scored against its
published numbers in ``test_dbox_release.py``. What is checked here is everything
between any such file and a score. The original evaluation recipe (sequence
input, f_Rel normalisation by the first camera offset, increments, the
missing-detection filter, float32 throughout), written out below, and the forward pass
as the release wrote it (:func:`reference_forward`, which ``test_dbox.py`` checks
against the equations) are applied to the original pickles; odmd-bench is run on the
imported ``odmd-paper`` sets with the same checkpoint file (the shipped ``p`` weights,
which are in the original key layout and give realistic depths). Every prediction must
agree to float32 rounding, so any checkpoint in that layout scores the same in
odmd-bench as in the original code.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from odmd_bench_baselines import dbox  # noqa: E402
from odmd_bench_baselines.dbox.model import DBox, reference_forward  # noqa: E402

import odmd_bench  # noqa: E402
from odmd_bench.data.importer import safe_unpickle  # noqa: E402

N_OBS = 10
FILES = {"normal": "normal", "camera": "perturb_motion", "object": "perturb_detection", "robot": "robot"}


def original_inputs(raw: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(inputs (N, 10, 7) float32, norm (N,) float32, depth (N,)) as the original recipe builds them."""
    bboxes = np.array(raw["bb"]["bboxes"], dtype=np.float64)  # (positions, 5, N)
    moves = raw["bb_3D"]["camera_movement"]  # (positions - 1, 3, N), relative to the last
    n_pos, _, n = bboxes.shape
    idx = np.linspace(0, n_pos - 1, N_OBS, dtype=int)
    cam_idx = np.linspace(0, n_pos - 2, N_OBS - 1, dtype=int)
    # Missing detection (width 0): the box of the closest valid observation, earlier on a tie.
    before = bboxes.copy()
    for k, e in np.argwhere(bboxes[idx, 2] == 0):
        valid = np.flatnonzero(before[:, 2, e] != 0)
        bboxes[k, :-1, e] = bboxes[valid[np.argmin(np.abs(valid - k))], :-1, e]
    flat = np.zeros((n, N_OBS * 7), dtype=np.float32)
    flat[:, : N_OBS * 4] = bboxes[idx, :-1].reshape(N_OBS * 4, n).T
    flat[:, -N_OBS * 3 : -3] = moves[cam_idx].reshape(N_OBS * 3 - 3, n).T
    norm = np.linalg.norm(flat[:, -N_OBS * 3 : -N_OBS * 3 + 3], axis=1)
    flat[:, -N_OBS * 3 :] = flat[:, -N_OBS * 3 :] * (1 / norm)[:, None]
    seq = np.zeros((n, N_OBS, 7), dtype=np.float32)
    seq[:, :, :4] = flat[:, : N_OBS * 4].reshape(n, N_OBS, 4)
    seq[:, :, -3:] = flat[:, -N_OBS * 3 :].reshape(n, N_OBS, 3)
    seq[:, 1:, -3:] = np.diff(seq[:, :, -3:], axis=1)
    seq[:, 0, -3:] = 0
    return seq, norm, bboxes[-1, -1]


@pytest.fixture(scope="module")
def checkpoint() -> tuple[Path, DBox]:
    """The checkpoint file, and the network holding its tensors as the original code would."""
    path = dbox.weights_path("p")
    state = torch.load(path, map_location="cpu", weights_only=True)
    assert list(state) == [
        "W",
        "U",
        "bias",
        "V",
        *(f"linears.{k}.{p}" for k in range(7) for p in ("weight", "bias")),
    ]
    assert all(t.dtype == torch.float32 for t in state.values())
    net = DBox()
    net.load_state_dict(state)
    return path, net


@pytest.mark.parametrize("split", ["val", "test"])
@pytest.mark.parametrize("set_name", list(FILES))
def test_the_original_recipe_and_odmd_bench_give_the_same_predictions(
    split: str,
    set_name: str,
    checkpoint: tuple[Path, DBox],
    original_release: Path,
    paper_data_dir: Path,
) -> None:
    torch.set_num_threads(1)
    path, net = checkpoint
    raw = safe_unpickle((original_release / "odmd" / split / f"{split}_{FILES[set_name]}.pk").read_bytes())
    seq, norm, depth = original_inputs(raw)
    with torch.no_grad():
        theirs = reference_forward(net, torch.from_numpy(seq)).numpy() * norm
    imported = odmd_bench.load(split, set_name, "odmd-paper", paper_data_dir)
    ours = dbox.predict(imported, weights=path)

    np.testing.assert_array_equal(imported.depth, depth)
    np.testing.assert_allclose(ours, theirs, rtol=2e-5, atol=0)
    error_theirs = np.mean(np.abs(theirs - depth) / depth)
    error_ours = np.mean(np.abs(ours - depth) / depth)
    assert abs(error_ours - error_theirs) < 1e-6
    if set_name == "robot":
        assert (raw["bb"]["bboxes"][:, 2] == 0).any()  # the missing-detection filter is exercised
