"""A predictions file scored against the wrong one of the two ODMD benchmarks.

``odmd-v1`` and ``odmd-paper`` have the same sets of the same sizes, so a file made for
one passes every check of the other, and a file without a ``benchmark`` column is
scored against ``odmd-v1`` by default. Its numbers are then those of depths for other
examples: meaningless, yet plausible enough to be copied into a paper. When the other
benchmark is in the data folder, :func:`twin_fit` scores the same depths against it; on
the sets whose content differs, depths made for the other benchmark fit it several
times better, which no method's depths do by chance over thousands of examples.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from odmd_bench.data.loading import read_split
from odmd_bench.data.registry import BENCHMARKS, Benchmark
from odmd_bench.errors import OdmdError
from odmd_bench.evaluation.metrics import percent_error
from odmd_bench.evaluation.result import EvaluationResult

#: The benchmark whose sets have the same names and sizes, for each that has one.
TWINS: dict[str, Benchmark] = {"odmd-v1": BENCHMARKS["odmd-paper"], "odmd-paper": BENCHMARKS["odmd-v1"]}
#: The other benchmark fits "far better" when its mean percent error is below this
#: fraction of the scored one's.
FAR_BETTER = 0.5


@dataclass(frozen=True)
class TwinFit:
    """The same depths' mean percent error on the scored benchmark and on its twin.

    Attributes:
        benchmark: the benchmark scored.
        twin: the other one.
        sets: the sets compared (those whose content differs between the two).
        scored: mean over ``sets`` of each set's mean percent error on ``benchmark``.
        other: the same on ``twin``.
    """

    benchmark: str
    twin: str
    sets: tuple[str, ...]
    scored: float
    other: float

    @property
    def far_better(self) -> bool:
        """Whether the depths fit the twin far better than the benchmark scored."""
        return self.other < FAR_BETTER * self.scored

    def describe(self) -> str:
        """``fit odmd-paper far better (... on normal, camera, object)``."""
        return (
            f"fit {self.twin} far better than {self.benchmark} (mean percent error "
            f"{self.other:.2f} against {self.scored:.2f} on {', '.join(self.sets)})"
        )


def twin_fit(result: EvaluationResult, data_dir: str | os.PathLike[str] | None = None) -> TwinFit | None:
    """How the depths of ``result`` fit the twin of the benchmark they were scored against.

    None where there is nothing to compare: no twin, the twin's split is not in the data
    folder (it is never generated or imported for this), it cannot be loaded or scored
    against, or no set scored differs between the two (the robot sets are the same).
    """
    other_bench = TWINS.get(result.benchmark)
    if other_bench is None:
        return None
    depths, examples = result.predictions, result.examples
    try:  # a missing split raises MissingDataError, as any other that cannot be loaded
        other = read_split(other_bench, result.split, data_dir, sets=list(depths))
        names = tuple(
            s
            for s in other
            if len(other[s]) == len(examples[s])
            and other[s].attrs.get("content_sha256") != examples[s].attrs.get("content_sha256")
        )
        there = [float(np.mean(percent_error(other[s].depth, depths[s]))) for s in names]
    except OdmdError:
        return None
    if not names:
        return None
    here = [result.sets[s]["percent_error"]["mean"] for s in names]
    return TwinFit(result.benchmark, other_bench.name, names, float(np.mean(here)), float(np.mean(there)))
