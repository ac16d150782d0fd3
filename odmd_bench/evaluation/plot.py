"""Drawing error against true depth (``odmd-bench plot``; needs the ``plot`` extra).

The numbers come from :mod:`odmd_bench.evaluation.depth_bins`; this module only draws
them, with matplotlib's Agg canvas (no pyplot, no global backend), into a PNG of a fixed
size whose bytes depend only on the numbers and the matplotlib version (no timestamp,
no software tag).
"""

from __future__ import annotations

import os
from collections.abc import Sequence

import numpy as np

from odmd_bench.evaluation.depth_bins import ERRORS, ErrorCurve

#: Figure size in inches and resolution: the PNG is ``FIGSIZE * DPI`` pixels (800 x 640).
FIGSIZE: tuple[float, float] = (8.0, 6.4)
DPI = 100

_YLABEL = {
    "absolute": "absolute error |Z - Ẑ| (m)",
    "percent": "percent error |Z - Ẑ| / Z (%)",
}


def default_title(benchmark: str, split: str, set_name: str, error: str, n: int) -> str:
    """The figure's title: the error and the set, then a line naming the benchmark, split and size.

    Example:
        >>> default_title("odms-detection", "test", "driving", "absolute", 750).splitlines()[0]
        'Absolute error against true depth: Driving set'
    """
    return (
        f"{error.capitalize()} error against true depth: {set_name.capitalize()} set\n"
        f"{benchmark} {split}, {n} examples"
    )


def text_problems(texts: Sequence[tuple[str, str]]) -> list[str]:
    """Problems with texts that matplotlib would read as math (``$...$``) but cannot parse.

    Args:
        texts: ``(what, text)`` pairs, ``what`` naming the option in the message.

    Returns:
        One line per text that would fail to draw; empty when all draw.
    """
    from matplotlib import cbook
    from matplotlib.mathtext import MathTextParser

    parser = MathTextParser("path")
    problems = []
    for what, text in texts:
        if not cbook.is_math_text(text):
            continue
        try:
            parser.parse(text)
        except ValueError as e:
            cause = str(e).strip().splitlines()[-1] if str(e).strip() else type(e).__name__
            cause = cause if len(cause) <= 120 else cause[:117] + "..."
            problems.append(f"{what} {text!r} is not valid matplotlib math text ($...$): {cause}")
    return problems


def draw_error_curves(
    curves: Sequence[ErrorCurve],
    path: str | os.PathLike[str],
    *,
    error: str,
    title: str,
    band: bool = True,
) -> None:
    """Write a PNG: mean error per depth bin, one line per curve, and the bins' counts.

    Args:
        curves: from :func:`~odmd_bench.evaluation.depth_bins.error_curves` (same bins).
        path: the PNG to write (atomically: an existing file is replaced only on success).
        error: ``"absolute"`` or ``"percent"`` (the y axis).
        title: the figure's title (may hold a line break).
        band: shade each curve's interquartile range per bin.

    Raises:
        ModuleNotFoundError: matplotlib is missing (the caller checks the extra first).
        StorageError: the file cannot be written.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from odmd_bench.outputs import atomic_path

    unit = ERRORS[error][1]
    fig = Figure(figsize=FIGSIZE, dpi=DPI, layout="constrained")
    FigureCanvasAgg(fig)
    ax, ax_n = fig.subplots(2, 1, sharex=True, height_ratios=[3.2, 1.0])
    edges = curves[0].bins.edges
    centres = curves[0].bins.centres
    for curve in curves:
        b = curve.bins
        (line,) = ax.plot(
            centres,
            b.mean,
            marker="o",
            markersize=4.5,
            linewidth=1.8,
            label=f"{curve.label} (mean {curve.set_mean:.2f} {unit})",
        )
        if band:
            ax.fill_between(centres, b.q25, b.q75, color=line.get_color(), alpha=0.15, linewidth=0)
    ax.set_ylabel(f"mean {_YLABEL[error]}")
    ax.set_ylim(bottom=0)
    ax.grid(alpha=0.35)
    ax.legend(
        loc="best",
        fontsize=9,
        title="line: mean per bin" + ("; band: 25th-75th percentile" if band else ""),
    )
    ax.set_title(title, fontsize=11)

    counts = curves[0].bins.counts
    ax_n.bar(edges[:-1], counts, width=np.diff(edges), align="edge", color="0.7", edgecolor="0.4")
    ax_n.bar_label(ax_n.containers[0], fmt="%d", fontsize=7, padding=1)
    ax_n.set_ylabel("examples")
    ax_n.set_ylim(0, max(1, int(counts.max())) * 1.3)
    ax_n.set_xlabel("true depth Z (m)")
    ax_n.set_xticks(edges if edges.size <= 16 else np.linspace(edges[0], edges[-1], 9))
    ax_n.tick_params(axis="x", labelsize=8)
    ax_n.xaxis.set_major_formatter("{x:.3g}")
    ax_n.grid(axis="y", alpha=0.35)
    ax.set_xlim(edges[0], edges[-1])
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=DPI, metadata={"Software": None})


def draw_reliability(
    curves: Sequence[tuple[str, Sequence[float], Sequence[float], tuple[float, float] | None]],
    path: str | os.PathLike[str],
    *,
    title: str,
) -> None:
    """Write a PNG: a reliability diagram, observed coverage against the nominal level.

    Args:
        curves: ``(label, levels, coverages, interval)`` per file: the coverage of the
            normal's central interval at each level (empty without ``depth_std``), and
            the stated interval's ``(level, coverage)`` (None without one).
        path: the PNG to write (atomically).
        title: the figure's title.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from odmd_bench.outputs import atomic_path

    fig = Figure(figsize=(6.4, 6.4), dpi=DPI, layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.subplots()
    ax.plot([0, 1], [0, 1], color="0.5", linestyle="--", linewidth=1, label="calibrated (coverage = level)")
    for label, levels, coverages, interval in curves:
        color = None
        if len(levels):
            (line,) = ax.plot(
                levels, coverages, marker="o", markersize=4, linewidth=1.6, label=f"{label}: normal"
            )
            color = line.get_color()
        if interval is not None:
            ax.plot(
                [interval[0]],
                [interval[1]],
                marker="D",
                markersize=8,
                linestyle="none",
                color=color,
                label=f"{label}: stated interval ({100 * interval[1]:.1f}% at {interval[0]:g})",
            )
    ax.set_xlim(0, 1)
    ax.set_ylim(0, 1)
    ax.set_aspect("equal")
    ax.set_xlabel("nominal level of the central interval")
    ax.set_ylabel("observed coverage")
    ax.grid(alpha=0.35)
    ax.legend(loc="upper left", fontsize=8, title="below the line: too narrow; above: too wide")
    ax.set_title(title, fontsize=11)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=DPI, metadata={"Software": None})


__all__ = ["DPI", "FIGSIZE", "default_title", "draw_error_curves", "draw_reliability", "text_problems"]
