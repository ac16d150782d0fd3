"""The site's figures (PNG and SVG bytes; need the ``plot`` extra, matplotlib).

Written without a date or software stamp, so that two builds give the same bytes.

The accuracy-against-speed figure is an SVG whose text stays text (the browser draws it,
and a test reads each label's box in Chromium). Its point labels are placed by
:func:`_place_labels`, written here: matplotlib places no annotation itself, and the one
library for it (adjustText) moves labels by repulsion until they overlap "little",
without a guarantee of no overlap or of staying inside the axes; with a handful of
labels per panel, trying a fixed list of positions in order and taking the first free
one is exact, deterministic and small.
"""

from __future__ import annotations

import io
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

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


def _svg(fig: Figure) -> bytes:
    """The figure as SVG, its text as ``<text>`` (DejaVu Sans, matplotlib's font), the same bytes each build."""
    import matplotlib

    out = io.BytesIO()
    with matplotlib.rc_context({"svg.fonttype": "none", "svg.hashsalt": "odmd-bench", "svg.id": "speed"}):
        fig.savefig(out, format="svg", dpi=DPI, metadata={"Date": None, "Creator": None})
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


#: Where a point's label may go, tried in this order: (dx, dy) offsets in points from the
#: point to the label's nearest corner or edge, then the same 2, 3, 4 and 5 times as far
#: (with a line to the point).
_OFFSETS: tuple[tuple[int, int], ...] = (
    (6, -6),
    (6, 4),
    (-6, -6),
    (-6, 4),
    (0, 8),
    (0, -10),
    (8, 0),
    (-8, 0),
)
_SCALES = (1, 2, 3, 4, 5)
_PAD = 3.0  # pixels kept free around each label


def _place_labels(ax: Any, points: Sequence[tuple[float, float, str]], avoid: Sequence[Any]) -> list[Any]:
    """Annotate each ``(x, y, text)`` where its label overlaps no other label, no point and nothing of ``avoid``.

    Each label takes the first offset of :data:`_OFFSETS` (then twice, then three times as
    far, joined to its point by a line) whose box, :data:`_PAD` pixels wider on each side,
    lies inside the axes and meets no placed label, no marker of ``points`` and no box of
    ``avoid`` (display boxes, e.g. the legend's). Where none is free the least
    overlapping one is kept (never on the board's panels nor on a crowded test panel:
    tests/test_site.py measures every label in Chromium).

    Returns:
        The annotations, in the order of ``points``.
    """
    from matplotlib.transforms import Bbox

    fig = ax.figure
    renderer = fig.canvas.get_renderer()
    inside = ax.get_window_extent(renderer)
    markers = [
        Bbox.from_bounds(px - 4, py - 4, 8, 8)
        for px, py in (ax.transData.transform((x, y)) for x, y, _ in points)
    ]
    taken: list[Any] = [*avoid, *markers]
    out = []
    for x, y, text in points:
        best: tuple[float, Any] | None = None
        for scale in _SCALES:
            for dx, dy in _OFFSETS:
                note = ax.annotate(
                    text,
                    (x, y),
                    xytext=(dx * scale, dy * scale),
                    textcoords="offset points",
                    fontsize=8,
                    ha="left" if dx > 0 else "right" if dx < 0 else "center",
                    va="top" if dy < 0 else "bottom" if dy > 0 else "center",
                    arrowprops=None if scale == 1 else {"arrowstyle": "-", "color": "#8795a3", "lw": 0.6},
                )
                box = note.get_window_extent(renderer).padded(_PAD)
                outside = not (
                    box.x0 >= inside.x0
                    and box.x1 <= inside.x1
                    and box.y0 >= inside.y0
                    and box.y1 <= inside.y1
                )
                overlap = sum(_area(box, other) for other in taken) + (1e9 if outside else 0.0)
                if best is None or overlap < best[0]:
                    if best is not None:
                        best[1].remove()
                    best = (overlap, note)
                else:
                    note.remove()
                if overlap == 0:
                    break
            if best is not None and best[0] == 0:
                break
        assert best is not None  # _OFFSETS is not empty
        taken.append(best[1].get_window_extent(renderer).padded(_PAD))
        out.append(best[1])
    return out


def _marker_boxes(ax: Any, xy: Sequence[tuple[float, float]], half: float = 4.0) -> list[Any]:
    """The display box of a marker at each data point (``half`` pixels each way)."""
    from matplotlib.transforms import Bbox

    return [
        Bbox.from_bounds(px - half, py - half, 2 * half, 2 * half)
        for px, py in (ax.transData.transform(p) for p in xy)
    ]


def _step_boxes(ax: Any, front: Sequence[tuple[float, float]], half: float = 1.5) -> list[Any]:
    """Thin display boxes along the Pareto front's steps (``where="post"``: across, then down)."""
    from matplotlib.transforms import Bbox

    out = []
    pixels = [ax.transData.transform(p) for p in front]
    for (x0, y0), (x1, y1) in zip(pixels, pixels[1:], strict=False):
        out.append(Bbox([[min(x0, x1) - half, y0 - half], [max(x0, x1) + half, y0 + half]]))
        out.append(Bbox([[x1 - half, min(y0, y1) - half], [x1 + half, max(y0, y1) + half]]))
    return out


def _area(a: Any, b: Any) -> float:
    """The area two display boxes share (0: they do not meet)."""
    w = min(a.x1, b.x1) - max(a.x0, b.x0)
    h = min(a.y1, b.y1) - max(a.y0, b.y0)
    return max(w, 0.0) * max(h, 0.0)


def speed_svg(points: Sequence[SpeedPoint], boards: Sequence[str]) -> bytes:
    """All against examples per second, one panel per board, the Pareto front marked and named.

    Only the front's points are named (by their name up to its first " ("), placed so
    that no two labels, no label and point, and no label and legend overlap, and no label
    leaves its panel (:func:`_place_labels`); every point is in the index's table.
    """
    shown = [b for b in boards if any(p.board == b for p in points)]
    n = len(shown)
    # margins in inches, the same for one panel or several: 0.6 below (the x label), 0.35
    # above (the title), 0.95 between two panels (a title and an x label)
    height = 3.3 * n
    panel = (height - 0.6 - 0.35 - 0.95 * (n - 1)) / n
    fig = _figure(6.4, height)
    axes = fig.subplots(n, 1, squeeze=False)[:, 0]
    fig.subplots_adjust(left=0.1, right=0.97, bottom=0.6 / height, top=1 - 0.35 / height, hspace=0.95 / panel)
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
        ax.set_xscale("log")
        # room for the labels: a decade beyond the fastest, a fifth of the range above and below
        ax.margins(x=0.25, y=0.2)
        ax.set_xlabel("examples per second (log scale)")
        ax.set_ylabel("All (mean % error)")
        ax.set_title(f"{board}: {len(mine)} entries", fontsize=10)
        ax.grid(alpha=0.3)
        legend = ax.legend(fontsize=8, loc="upper left")
        canvas: Any = fig.canvas  # FigureCanvasAgg (_figure), which has a renderer
        renderer = canvas.get_renderer()
        ax.get_xlim(), ax.get_ylim()  # the limits fixed (with the margins) before anything is measured
        _place_labels(
            ax,
            [(p.examples_per_second, p.all, p.name.split(" (")[0]) for p in front],
            [
                legend.get_window_extent(renderer).padded(_PAD),
                *_marker_boxes(ax, [(p.examples_per_second, p.all) for p in mine]),
                *_step_boxes(ax, [(p.examples_per_second, p.all) for p in front]),
            ],
        )
    return _svg(fig)
