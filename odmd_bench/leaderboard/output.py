"""Writing a built leaderboard: ``LEADERBOARD.md``, ``leaderboard.json`` and the plot, into one folder.

Above :mod:`~odmd_bench.leaderboard.render` and :mod:`~odmd_bench.leaderboard.plot`, which
draw what it writes. The views are derived from the entries and never committed: by
default they go to ``leaderboard/build/`` (:func:`~odmd_bench.leaderboard.files.build_folder`,
ignored by git).
"""

from __future__ import annotations

import importlib.util
import os
from pathlib import Path

from odmd_bench.leaderboard.files import JSON_FILE, MARKDOWN, PLOT, board_digest, plot_source
from odmd_bench.leaderboard.render import Built
from odmd_bench.outputs import atomic_texts


def write(folder: str | os.PathLike[str], built: Built, *, plot: bool = True) -> list[str]:
    """Write ``LEADERBOARD.md``, ``leaderboard.json`` and (with matplotlib) ``leaderboard.png`` into ``folder``.

    The folder is made where missing. Without matplotlib the plot is skipped (and said):
    nothing checks it, so the core install builds the rest.

    Returns:
        One line per thing done or skipped.
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    said = []
    texts = [(folder / MARKDOWN, built.markdown), (folder / JSON_FILE, built.json_text)]
    if plot and importlib.util.find_spec("matplotlib") is None:
        plot = False
        said.append(
            f"skipped the plot {folder / PLOT}: matplotlib is not installed (pip install 'odmd-bench[plot]')"
        )
    stale = folder / PLOT
    if not plot and stale.is_file() and not stale.is_symlink():
        try:
            drawn_from = plot_source(stale)
        except OSError:
            drawn_from = None
        if drawn_from != board_digest(built.json_text):  # a plot of another board: not left beside it
            stale.unlink()
            said.append(f"removed {stale}: it was drawn from another board")
    # Every file, the plot included, is written before any replaces its old version: a
    # failure (a full disk, a file size limit, a file that cannot be replaced) leaves the
    # folder as it was, all of it.
    with atomic_texts(texts, also=[folder / PLOT] if plot else []) as figure:
        if plot:
            from odmd_bench.leaderboard.plot import plot_boards

            plot_boards(built.boards, figure[0], source=board_digest(built.json_text))
            said.append(f"wrote {folder / PLOT}")
    said[:0] = [f"wrote {folder / MARKDOWN}", f"wrote {folder / JSON_FILE}"]
    return said
