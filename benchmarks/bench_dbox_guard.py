r"""Inference speed of dbox-guard against the DBox_p^z per-set predictions it guards.

Run (one thread; the original release must be at ``../shared/odmd-original`` or
``$ODMD_ORIGINAL``):

    OMP_NUM_THREADS=1 .venv/bin/pytest benchmarks/bench_dbox_guard.py --benchmark-only \
        -p no:randomly --benchmark-columns=min,median,ops -s

Data: the four ODMS-detection val sets (6,260 examples), each predicted as
``odmd-bench baseline`` does (one call per set, the set's checkpoint loaded and
hash-checked in each call, as in both methods). ``test_dbox_per_set``: ``dbox.predict``
with ``config="p-z", selection="per-set"``; ``test_dbox_guard``: ``dbox_guard.predict``
(the same network on repaired boxes, plus Box_LS where the set's ``alpha`` is not 0, and
the cap); ``test_guard_steps``: the guard's numpy steps alone (flag, repair, Box_LS,
blend, cap), no network. Examples per second in ``extra_info``.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

import odmd_bench

torch = pytest.importorskip("torch")

from odmd_bench_baselines import box_ls, dbox, dbox_guard  # noqa: E402
from odmd_bench_baselines.dbox_guard.method import choose_parameters  # noqa: E402

ORIGINAL = Path(__file__).resolve().parents[2] / "shared" / "odmd-original"


@pytest.fixture(scope="module")
def val_sets(tmp_path_factory: pytest.TempPathFactory) -> dict[str, odmd_bench.Examples]:
    src = Path(os.environ.get("ODMD_ORIGINAL", ORIGINAL))
    if not (src / "odms_detection").is_dir():
        pytest.skip(f"the original release is not at {src}")
    from odmd_bench.data.importer import import_release

    data = tmp_path_factory.mktemp("data")
    import_release(src, data)
    torch.set_num_threads(1)
    return {s: ex.without_truth() for s, ex in odmd_bench.load_split("val", "odms-detection", data).items()}


def _n(sets: dict[str, odmd_bench.Examples]) -> int:
    return sum(len(ex) for ex in sets.values())


def test_dbox_per_set(benchmark, val_sets) -> None:  # type: ignore[no-untyped-def]
    def run() -> None:
        for ex in val_sets.values():
            dbox.predict(ex, config="p-z", selection="per-set")

    benchmark.pedantic(run, rounds=10, warmup_rounds=1)
    benchmark.extra_info["examples_per_s"] = _n(val_sets) / benchmark.stats.stats.min


def test_dbox_guard(benchmark, val_sets) -> None:  # type: ignore[no-untyped-def]
    def run() -> None:
        for ex in val_sets.values():
            dbox_guard.predict(ex)

    benchmark.pedantic(run, rounds=10, warmup_rounds=1)
    benchmark.extra_info["examples_per_s"] = _n(val_sets) / benchmark.stats.stats.min


def test_guard_steps(benchmark, val_sets) -> None:  # type: ignore[no-untyped-def]
    chosen = {s: choose_parameters(ex)[0] for s, ex in val_sets.items()}

    def run() -> None:
        for s, ex in val_sets.items():
            p = chosen[s]
            fixed = dbox_guard.repair(ex, dbox_guard.flag_wrong_starts(ex.boxes, ex.detected, p.tau))
            z = dbox_guard.travel(ex)  # a stand-in for the network's depth: same shape and scale
            if p.alpha:
                z = dbox_guard.blend(z, box_ls.predict(fixed), p.alpha)
            dbox_guard.cap(z, dbox_guard.travel(ex), p.cap)

    benchmark.pedantic(run, rounds=10, warmup_rounds=1)
    benchmark.extra_info["examples_per_s"] = _n(val_sets) / benchmark.stats.stats.min
