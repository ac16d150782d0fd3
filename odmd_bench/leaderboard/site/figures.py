"""The site's figures (PNG bytes; need the ``plot`` extra, matplotlib).

Written without a date or software stamp, so that two builds give the same bytes.
"""

from __future__ import annotations

import io
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from odmd_bench.leaderboard.specs import SET_TITLES

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from odmd_bench.evaluation.scoring import EvaluationResult

#: Depth bins of the error-against-depth figure (quantiles of each set's true depth).
DEPTH_BINS = 10
DPI = 80


def _figure(width: float, height: float) -> Figure:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    # fixed margins: a layout engine would measure every label of every figure (slow)
    fig = Figure(figsize=(width, height))
    FigureCanvasAgg(fig)
    return fig


def _png(fig: Figure) -> bytes:
    out = io.BytesIO()
    fig.savefig(out, format="png", dpi=DPI, metadata={"Software": None})
    return out.getvalue()


def error_depth_png(result: EvaluationResult, sets: Sequence[str], title: str) -> bytes:
    """Median percent error (with its quartiles for All) against true depth, per set.

    Each set's examples are binned by true depth (:data:`DEPTH_BINS` quantile bins); a
    point is a bin's median depth and median percent error.
    """
    errors = result.percent_errors()
    fig = _figure(6.4, 3.4)
    fig.subplots_adjust(left=0.1, right=0.98, bottom=0.15, top=0.9)
    ax = fig.subplots()
    for s in sets:
        depth = np.asarray(result.examples[s].depth, dtype=np.float64)
        err = np.asarray(errors[s], dtype=np.float64)
        edges = np.quantile(depth, np.linspace(0, 1, DEPTH_BINS + 1))
        which = np.clip(np.searchsorted(edges, depth, side="right") - 1, 0, DEPTH_BINS - 1)
        centres, medians = [], []
        for b in range(DEPTH_BINS):
            sel = which == b
            if sel.any():
                centres.append(float(np.median(depth[sel])))
                medians.append(float(np.median(err[sel])))
        ax.plot(centres, medians, marker="o", markersize=3, label=SET_TITLES.get(s, s))
    ax.set_xscale("log")  # the sets' depths differ by orders of magnitude (Driving: tens of metres)
    ax.set_xlabel("true depth Z (m, log scale)")
    ax.set_ylabel("median percent error (%)")
    ax.set_title(title, fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return _png(fig)


@dataclass(frozen=True)
class SpeedPoint:
    """One entry on the accuracy-against-speed figure."""

    board: str
    name: str
    examples_per_second: float
    all: float


def pareto(points: Sequence[SpeedPoint]) -> list[SpeedPoint]:
    """The points no other point beats on both speed (higher) and All (lower), fastest first.

    Examples:
        >>> p = [SpeedPoint("b", n, v, a) for n, v, a in [("x", 10, 5), ("y", 100, 9), ("z", 50, 12)]]
        >>> [q.name for q in pareto(p)]
        ['y', 'x']
    """
    front: list[SpeedPoint] = []
    for p in sorted(points, key=lambda q: (-q.examples_per_second, q.all, q.name)):
        if not front or p.all < front[-1].all:
            front.append(p)
    return front


def speed_png(points: Sequence[SpeedPoint], boards: Sequence[str]) -> bytes:
    """All against examples per second, one panel per board, the Pareto front marked and named.

    Only the front's points are named (by their name up to its first " ("), so that the
    labels stay readable; every point is in the index's table.
    """
    shown = [b for b in boards if any(p.board == b for p in points)]
    fig = _figure(6.4, 3.3 * len(shown))
    axes = fig.subplots(len(shown), 1, squeeze=False)[:, 0]
    fig.subplots_adjust(left=0.1, right=0.97, bottom=0.4 / len(shown), top=1 - 0.25 / len(shown), hspace=0.5)
    for ax, board in zip(axes, shown, strict=True):
        mine = [p for p in points if p.board == board]
        front = sorted(pareto(mine), key=lambda q: q.examples_per_second)
        ax.scatter([p.examples_per_second for p in mine], [p.all for p in mine], color="#8795a3", s=16)
        ax.step(
            [p.examples_per_second for p in front],
            [p.all for p in front],
            where="post",
            color="#c0392b",
            label="Pareto front",
        )
        ax.scatter(
            [p.examples_per_second for p in front], [p.all for p in front], color="#c0392b", s=30, zorder=3
        )
        for i, p in enumerate(front):
            last = i == len(front) - 1  # the fastest: named on its left, inside the panel
            ax.annotate(
                p.name.split(" (")[0],
                (p.examples_per_second, p.all),
                fontsize=8,
                xytext=(-6 if last else 4, -10),
                textcoords="offset points",
                ha="right" if last else "left",
            )
        ax.set_xscale("log")
        ax.margins(x=0.2, y=0.12)
        ax.set_xlabel("examples per second (log scale)")
        ax.set_ylabel("All (mean % error)")
        ax.set_title(f"{board}: {len(mine)} entries", fontsize=10)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="upper left")
    return _png(fig)
