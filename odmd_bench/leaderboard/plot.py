"""The leaderboard's plot (``leaderboard.png``; needs the ``plot`` extra, matplotlib)."""

from __future__ import annotations

import os
from collections.abc import Sequence

import numpy as np

from odmd_bench.leaderboard.board import Board
from odmd_bench.leaderboard.files import PLOT_SOURCE_KEY
from odmd_bench.leaderboard.specs import SET_TITLES


def plot_boards(
    boards: Sequence[Board], path: str | os.PathLike[str], *, top: int = 3, source: str | None = None
) -> None:
    """Write the boards' figure to ``path`` (PNG).

    Per board with entries: mean percent error per set per method (bars) and median
    percent error against true depth (binned) for the ``top`` best methods. ``source``,
    the SHA-256 of the ``leaderboard.json`` the boards are written to, is recorded in the
    PNG (text key :data:`odmd_bench.leaderboard.files.PLOT_SOURCE_KEY`), so that
    ``leaderboard check`` can tell a plot left from an earlier board.

    Raises:
        ModuleNotFoundError: When matplotlib is missing (it is an optional extra).
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from odmd_bench.outputs import atomic_path

    boards = [bd for bd in boards if bd.rows]
    n = max(1, len(boards))
    fig = Figure(figsize=(14, 4.6 * n), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(n, 2, squeeze=False)
    for (ax_bar, ax_depth), bd in zip(axes, boards, strict=False):
        labels = [*(SET_TITLES.get(s, s) for s in bd.sets), "All"]
        x = np.arange(len(labels))
        width = 0.8 / max(1, len(bd.rows))
        for i, row in enumerate(bd.rows):
            res = row.result
            vals = [res.sets[s]["percent_error"]["mean"] for s in bd.sets] + [res.all_percent_error_mean]
            bars = ax_bar.bar(
                x + (i - (len(bd.rows) - 1) / 2) * width,
                vals,
                width,
                label=f"{row.entry.meta.name} (group {row.group})",
            )
            ax_bar.bar_label(bars, fmt="%.1f", fontsize=7, padding=1)
        ax_bar.set_xticks(x, labels)
        ax_bar.set_ylabel("mean percent error (%)")
        ax_bar.set_title(f"{bd.spec.key} ({bd.spec.title}): mean percent error per set")
        ax_bar.legend(fontsize=8)
        ax_bar.grid(axis="y", alpha=0.3)

        for row in bd.rows[:top]:
            res = row.result
            errs = res.percent_errors()
            depth = np.concatenate([res.examples[s].depth for s in bd.sets])
            err = np.concatenate([errs[s] for s in bd.sets])
            edges = np.quantile(depth, np.linspace(0, 1, 13))
            which = np.clip(np.searchsorted(edges, depth, side="right") - 1, 0, len(edges) - 2)
            centres, medians = [], []
            for b in range(len(edges) - 1):
                sel = which == b
                if sel.any():
                    centres.append(float(np.median(depth[sel])))
                    medians.append(float(np.median(err[sel])))
            ax_depth.plot(
                centres,
                medians,
                marker="o",
                label=f"{row.entry.meta.name} (All {res.all_percent_error_mean:.2f})",
            )
        ax_depth.set_xlabel("true depth Z (m)")
        ax_depth.set_ylabel("median percent error (%) per depth bin")
        ax_depth.set_title(
            f"{bd.benchmark} {bd.split}: error against true depth, top {min(top, len(bd.rows))} (all sets)"
        )
        ax_depth.legend(fontsize=8)
        ax_depth.grid(alpha=0.3)
    with atomic_path(path) as tmp:
        metadata: dict[str, str | None] = {"Software": None}
        if source is not None:
            metadata[PLOT_SOURCE_KEY] = source
        fig.savefig(tmp, format="png", dpi=110, metadata=metadata)
