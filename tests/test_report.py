from __future__ import annotations

import numpy as np

import odmd_bench
from odmd_bench.evaluation.report import format_table
from odmd_bench.evaluation.scoring import Predictions, score


def test_table_columns_never_run_together_for_huge_errors() -> None:
    ex = odmd_bench.generate(4, rng=0)
    ex.attrs.update(benchmark="odmd-v1", split="test", set="normal", content_sha256="0" * 64)
    pred = ex.depth.copy()
    pred[0] *= 1000.0  # 99,900 % error
    p = Predictions(
        path="x.csv", sha256="1" * 64, benchmark="odmd-v1", split="test", depths={"normal": pred}, n_rows=4
    )
    table = format_table(score(p, {"normal": ex}))
    row = next(line for line in table.splitlines() if line.startswith("normal"))
    cells = row.split()
    assert len(cells) == 12, row  # set, n, 5 percent and 5 absolute statistics
    assert float(cells[5]) == np.round(abs(pred[0] - ex.depth[0]) / ex.depth[0] * 100, 2)


def test_a_set_with_an_unusable_true_depth_is_refused_by_name() -> None:
    """Written by other means than odmd-bench (the importer and generator never make one)."""
    import pytest

    ex = odmd_bench.generate(6, rng=0)
    ex.attrs.update(benchmark="odmd-v1", split="test", set="normal", content_sha256="0" * 64)
    pred = ex.depth.copy()
    ex.depth[[1, 4]] = [0.0, -2.0]
    p = Predictions(
        path="x.csv", sha256="1" * 64, benchmark="odmd-v1", split="test", depths={"normal": pred}, n_rows=6
    )
    with pytest.raises(odmd_bench.DataError) as info:
        score(p, {"normal": ex})
    assert info.value.message.startswith("odmd-v1 test normal cannot be scored against")
    assert info.value.problems == [
        "2 example(s) with a true depth that is not finite and > 0 (first: [1, 4])"
    ]
