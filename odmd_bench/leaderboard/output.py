"""Writing a built leaderboard: ``LEADERBOARD.md``, ``leaderboard.json``, the README block, the plot.

Above :mod:`~odmd_bench.leaderboard.render` and :mod:`~odmd_bench.leaderboard.plot`, which
draw what it writes; the folder's layout is :mod:`~odmd_bench.leaderboard.files`'.
"""

from __future__ import annotations

import importlib.util
import os
from pathlib import Path

from odmd_bench.data.atomic import atomic_texts
from odmd_bench.leaderboard.files import JSON_FILE, MARKDOWN, PLOT, board_digest, plot_problem, stale_readme
from odmd_bench.leaderboard.render import Built


def write(root: str | os.PathLike[str], built: Built, *, plot: bool = True) -> list[str]:
    """Write ``LEADERBOARD.md``, ``leaderboard.json``, the README block and (with matplotlib) the plot.

    Returns:
        One line per thing done or skipped.
    """
    root = Path(root)
    said = []
    texts = [(root / MARKDOWN, built.markdown), (root / JSON_FILE, built.json_text)]
    stale = stale_readme(root, built.readme_block)
    if stale is not None:
        texts.append((stale[0], stale[2]))
    if plot and importlib.util.find_spec("matplotlib") is None:
        plot = False
        said.append(
            f"skipped the plot {root / PLOT}: matplotlib is not installed (pip install 'odmd-bench[plot]')"
        )
    if not plot:
        stale_plot = plot_problem(root, built.json_text)
        if stale_plot is not None:
            said.append(f"warning: {stale_plot}; `leaderboard check` fails until then")
    # Every file, the plot included, is written before any replaces its old version: a
    # failure (a full disk, a file size limit, a file that cannot be replaced) leaves the
    # board as it was, all of it.
    with atomic_texts(texts, also=[root / PLOT] if plot else []) as figure:
        if plot:
            from odmd_bench.leaderboard.plot import plot_boards

            plot_boards(built.boards, figure[0], source=board_digest(built.json_text))
            said.append(f"wrote {root / PLOT}")
    said[:0] = [f"wrote {root / MARKDOWN}", f"wrote {root / JSON_FILE}"] + (
        [f"updated the leaderboard summary in {stale[0]}"] if stale is not None else []
    )
    return said
