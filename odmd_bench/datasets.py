"""PyTorch datasets over ODMD examples (needs torch: ``pip install 'odmd-bench[dbox]'``).

``import odmd_bench`` never imports this module (nor torch); import it yourself:

>>> from torch.utils.data import DataLoader
>>> from odmd_bench.datasets import GeneratedBatches
>>> batches = GeneratedBatches(batch_size=8, batches_per_epoch=4, seed=0)
>>> loader = DataLoader(batches, batch_size=None)  # the dataset yields whole batches
>>> next(iter(loader))["boxes"].shape
torch.Size([8, 10, 4])

Every item is a dict of tensors: ``boxes`` (..., n_obs, 4), ``detected`` (..., n_obs)
bool, ``camera`` (..., n_obs, 3), ``depth`` (...,), and for a map-style dataset the
example's ``index`` in its set.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np

from odmd_bench.data.config import GeneratorConfig
from odmd_bench.data.examples import Examples
from odmd_bench.data.generator import generate
from odmd_bench.errors import UsageError
from odmd_bench.extras import require

torch = require("torch", "dbox", "odmd_bench.datasets")
from torch.utils.data import Dataset, IterableDataset, get_worker_info  # noqa: E402

#: The arrays each item holds, besides ``index``.
FIELDS: tuple[str, ...] = ("boxes", "detected", "camera", "depth")


def to_tensors(examples: Examples, dtype: Any = None) -> dict[str, Any]:
    """``boxes``, ``detected``, ``camera`` and ``depth`` of ``examples`` as tensors.

    Args:
        examples: N examples.
        dtype: floating dtype of the float arrays (default ``torch.float32``; give
            ``torch.float64`` to keep the stored numbers exactly).

    Returns:
        ``{name: tensor}`` with the shapes of :class:`~odmd_bench.Examples`.
    """
    dtype = torch.float32 if dtype is None else dtype
    out = {name: torch.from_numpy(np.ascontiguousarray(getattr(examples, name))) for name in FIELDS}
    for name in ("boxes", "camera", "depth"):
        out[name] = out[name].to(dtype)
    return out


def batch_seed(seed: int, epoch: int, batch: int) -> np.random.SeedSequence:
    """The seed of batch ``batch`` of epoch ``epoch``: one child of ``seed`` per pair."""
    return np.random.SeedSequence(seed, spawn_key=(epoch, batch))


class GeneratedBatches(IterableDataset):
    """Fresh training batches from the generator, reproducible and never repeated.

    Batch ``k`` of epoch ``e`` is ``odmd_bench.generate(batch_size, preset,
    perturbation, rng=SeedSequence(seed, spawn_key=(e, k)))``: the first batch of
    :func:`odmd_bench.stream` seeded for that pair. Of the ``batches_per_epoch`` batches
    of an epoch, DataLoader worker ``w`` of ``W`` (and process ``rank`` of
    ``world_size`` in distributed training) makes those with ``k % (W * world_size) ==
    rank * W + w``. So two workers never make the same batch, an epoch is the same set
    of batches (in the same order, as DataLoader takes one batch from each worker in
    turn) for any number of workers, and a rerun with the same seed repeats everything.

    Call :meth:`set_epoch` before each epoch (as with ``DistributedSampler``); it has
    no effect on workers kept alive with ``persistent_workers=True``, so do not use it
    with them. Use ``DataLoader(dataset, batch_size=None)``: items are whole batches.

    Args:
        batch_size: examples per batch.
        batches_per_epoch: batches in an epoch (``len(dataset)``).
        preset: generator preset name or config (``"odmd"``, ``"odms"``).
        perturbation: ``"normal"``, ``"camera"``, ``"object"`` or ``"both"``.
        seed: the one seed everything derives from.
        dtype: float dtype of the tensors (default ``torch.float32``).
        rank, world_size: this process's share in distributed training.
    """

    def __init__(
        self,
        batch_size: int,
        batches_per_epoch: int,
        preset: str | GeneratorConfig = "odmd",
        perturbation: str = "both",
        seed: int = 0,
        dtype: Any = None,
        rank: int = 0,
        world_size: int = 1,
    ) -> None:
        super().__init__()
        problems = []
        for name, value, low in (
            ("batch_size", batch_size, 1),
            ("batches_per_epoch", batches_per_epoch, 1),
            ("seed", seed, 0),
            ("world_size", world_size, 1),
            ("rank", rank, 0),
        ):
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
                problems.append(f"{name} must be an integer >= {low}, got {value!r}")
        if not problems and rank >= world_size:
            problems.append(f"rank must be < world_size ({world_size}), got {rank}")
        if problems:
            raise UsageError("bad GeneratedBatches arguments", problems)
        self.batch_size = int(batch_size)
        self.batches_per_epoch = int(batches_per_epoch)
        self.preset = preset
        self.perturbation = perturbation
        self.seed = int(seed)
        self.dtype = dtype
        self.rank = int(rank)
        self.world_size = int(world_size)
        self.epoch = 0
        generate(1, preset, perturbation, rng=0)  # unknown presets and perturbations fail here

    def set_epoch(self, epoch: int) -> None:
        """Make the next iteration epoch ``epoch``."""
        self.epoch = int(epoch)

    def __len__(self) -> int:
        return self.batches_per_epoch

    def batch_indices(self, worker: int = 0, workers: int = 1) -> range:
        """The batches of an epoch that ``worker`` of ``workers`` makes on this rank."""
        step = workers * self.world_size
        return range(self.rank * workers + worker, self.batches_per_epoch, step)

    def batch(self, k: int, epoch: int | None = None) -> dict[str, Any]:
        """Batch ``k`` of ``epoch`` (default: the current one), as tensors."""
        e = self.epoch if epoch is None else int(epoch)
        rng = np.random.default_rng(batch_seed(self.seed, e, k))
        return to_tensors(generate(self.batch_size, self.preset, self.perturbation, rng=rng), self.dtype)

    def __iter__(self) -> Iterator[dict[str, Any]]:
        info = get_worker_info()
        worker, workers = (0, 1) if info is None else (info.id, info.num_workers)
        for k in self.batch_indices(worker, workers):
            yield self.batch(k)


class ExamplesDataset(Dataset):
    """The examples of one set, one item each (map-style): for val and test sets.

    Items are ``{"boxes": (n_obs, 4), "detected": (n_obs,), "camera": (n_obs, 3),
    "depth": (), "index": ()}``; a DataLoader with ``batch_size=B`` stacks them. The
    tensors are made once, so workers only index them.

    Args:
        examples: the set.
        dtype: float dtype of the tensors (default ``torch.float32``).
    """

    def __init__(self, examples: Examples, dtype: Any = None) -> None:
        super().__init__()
        self.examples = examples
        self.tensors = to_tensors(examples, dtype)

    @classmethod
    def from_set(
        cls,
        split: str,
        set_name: str,
        benchmark: str = "odmd-v1",
        data_dir: Any = None,
        dtype: Any = None,
    ) -> ExamplesDataset:
        """A set of a benchmark, loaded (and verified) by :func:`odmd_bench.load`."""
        from odmd_bench.data.store import load

        return cls(load(split, set_name, benchmark, data_dir), dtype)

    def __len__(self) -> int:
        return len(self.examples)

    def __getitem__(self, index: int) -> dict[str, Any]:
        i = int(index)
        if not -len(self) <= i < len(self):
            raise IndexError(f"index {index} out of range for {len(self)} examples")
        i %= len(self)
        item = {name: t[i] for name, t in self.tensors.items()}
        item["index"] = torch.tensor(i)
        return item


__all__ = ["FIELDS", "ExamplesDataset", "GeneratedBatches", "batch_seed", "to_tensors"]
