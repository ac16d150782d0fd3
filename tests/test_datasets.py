"""torch datasets: the generator stream seeded per worker and epoch, and a set by index."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from torch.utils.data import DataLoader  # noqa: E402

import odmd_bench  # noqa: E402
from odmd_bench import UsageError  # noqa: E402
from odmd_bench.datasets import ExamplesDataset, GeneratedBatches, batch_seed  # noqa: E402


def _epoch(dataset: GeneratedBatches, workers: int) -> list[dict[str, Any]]:
    return list(DataLoader(dataset, batch_size=None, num_workers=workers))


def _same(a: dict[str, Any], b: dict[str, Any]) -> bool:
    return a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)


def test_import_odmd_bench_does_not_import_the_datasets_or_torch() -> None:
    code = "import sys, odmd_bench; print('odmd_bench.datasets' in sys.modules, 'torch' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["False", "False"]


def test_two_workers_never_repeat_a_batch_and_a_rerun_repeats_all() -> None:
    dataset = GeneratedBatches(batch_size=16, batches_per_epoch=6, perturbation="both", seed=3)
    first = _epoch(dataset, workers=2)
    assert len(first) == 6
    boxes = [b["boxes"] for b in first]
    assert all(not torch.equal(boxes[i], boxes[j]) for i in range(6) for j in range(i))
    # The same seed again: every batch again, in the same order; and with no workers too.
    again = _epoch(dataset, workers=2)
    alone = _epoch(dataset, workers=0)
    assert all(_same(a, b) and _same(a, c) for a, b, c in zip(first, again, alone, strict=True))


def test_batch_k_of_epoch_e_is_the_generator_seeded_for_that_pair() -> None:
    dataset = GeneratedBatches(batch_size=8, batches_per_epoch=4, seed=5, dtype=torch.float64)
    dataset.set_epoch(2)
    batches = _epoch(dataset, workers=2)
    for k, batch in enumerate(batches):
        ex = odmd_bench.generate(8, "odmd", "both", rng=np.random.default_rng(batch_seed(5, 2, k)))
        np.testing.assert_array_equal(batch["boxes"].numpy(), ex.boxes)
        np.testing.assert_array_equal(batch["camera"].numpy(), ex.camera)
        np.testing.assert_array_equal(batch["depth"].numpy(), ex.depth)
        np.testing.assert_array_equal(batch["detected"].numpy(), ex.detected)
    # Another epoch gives other batches.
    dataset.set_epoch(3)
    assert not any(_same(a, b) for a, b in zip(batches, _epoch(dataset, workers=0), strict=True))


def test_ranks_share_an_epoch_without_overlap() -> None:
    ranks = [GeneratedBatches(4, 10, seed=1, rank=r, world_size=2) for r in range(2)]
    made = [set(ds.batch_indices(w, 3)) for ds in ranks for w in range(3)]
    assert sorted(k for m in made for k in m) == list(range(10))


def test_bad_arguments_are_named() -> None:
    with pytest.raises(UsageError) as info:
        GeneratedBatches(batch_size=0, batches_per_epoch=2, rank=2, world_size=2)
    assert "batch_size" in info.value.render()
    with pytest.raises(odmd_bench.ConfigError, match="wobbly"):
        GeneratedBatches(4, 2, perturbation="wobbly")


def test_a_set_by_index_through_two_workers(v1_data_dir: Path) -> None:
    dataset = ExamplesDataset.from_set("val", "camera", data_dir=v1_data_dir, dtype=torch.float64)
    ex = odmd_bench.load("val", "camera", data_dir=v1_data_dir)
    assert len(dataset) == len(ex)
    batches = list(DataLoader(dataset, batch_size=500, num_workers=2))
    index = torch.cat([b["index"] for b in batches]).numpy()
    np.testing.assert_array_equal(index, np.arange(len(ex)))
    np.testing.assert_array_equal(torch.cat([b["boxes"] for b in batches]).numpy(), ex.boxes)
    np.testing.assert_array_equal(torch.cat([b["depth"] for b in batches]).numpy(), ex.depth)
    item = dataset[-1]
    assert item["boxes"].shape == (10, 4) and int(item["index"]) == len(ex) - 1
    with pytest.raises(IndexError):
        dataset[len(ex)]
