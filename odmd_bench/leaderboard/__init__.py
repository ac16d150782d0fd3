"""The leaderboard: entries re-scored by the evaluator, rank groups, tables, JSON, plot.

Only the entries are committed (``leaderboard/entries/``, with ``reported.yaml`` and
``audits/``); the tables, JSON and plot are derived by :func:`build` and written by
:func:`write` (by default into ``leaderboard/build/``, ignored by git), so that two entry
pull requests never touch the same file. Each entry records its predictions' SHA-256 and
its scores; :func:`check` re-scores every entry and compares them.

The package, by concern:

- :mod:`~odmd_bench.leaderboard.specs`: the boards, as data (:data:`BOARDS`).
- :mod:`~odmd_bench.leaderboard.entry`: an entry's metadata, :class:`EntryMeta`,
  validated on creation (:func:`~odmd_bench.leaderboard.entry.validate_meta`).
- :mod:`odmd_bench.documents`: bounded YAML/JSON reading (no aliases), shared with the
  generator configurations.
- :mod:`~odmd_bench.leaderboard.files`: the folder: discovery, reading entries (no
  symbolic links); :mod:`~odmd_bench.leaderboard.add` adds one.
- :mod:`~odmd_bench.leaderboard.board`: loading each board's sets once and scoring
  (:func:`~odmd_bench.leaderboard.board.score_csv` is the one call into the
  evaluator); :mod:`~odmd_bench.leaderboard.ranking`: rank groups, pure.
- :mod:`~odmd_bench.leaderboard.reported`: results printed in papers (``reported.yaml``).
- :mod:`~odmd_bench.leaderboard.render`: :func:`build` and the markdown and JSON
  texts; :mod:`~odmd_bench.leaderboard.plot`: the plot; :mod:`~odmd_bench.leaderboard.diff`:
  :func:`check` (:func:`check_report` tells invalid input from differences), naming
  each entry and field whose recorded value differs from its re-scoring;
  :mod:`~odmd_bench.leaderboard.output`: :func:`write`, the outputs written at once;
  :mod:`~odmd_bench.leaderboard.dataframe`: :func:`frame`, the leaderboard in pandas.

Nothing here prints.

Rank groups (the exact rule): on each board, rows are sorted by ``All`` (the mean of
the sets' mean percent errors; ties broken by method id). The first row leads group 1.
Walking down the sorted rows, each row is compared with the leader of the current group
by :func:`~odmd_bench.evaluation.compare.compare_errors` on per-example percent errors
(``RANK_RESAMPLES`` paired bootstrap resamples and sign flips, seed ``RANK_SEED``,
confidence ``RANK_CONFIDENCE``, stratified by set for ``All``). If the verdict on ``All``
is "not distinguishable" the row joins that group; otherwise it leads the next group. So
group numbers never decrease down the table, every member of a group is
indistinguishable from its group's best row (not necessarily from every other member),
and a row that starts a new group is distinguishably worse than the previous group's best.
"""

from odmd_bench.leaderboard.add import add_entry
from odmd_bench.leaderboard.board import Board, Row, collect, data_version, load_board_data, score_entry
from odmd_bench.leaderboard.dataframe import frame
from odmd_bench.leaderboard.diff import (
    CheckReport,
    check,
    check_report,
    diff_json,
    diff_markdown,
    entry_differences,
)
from odmd_bench.leaderboard.entry import (
    ENTRY_FILES,
    MAX_LENGTHS,
    OPTIONAL_FIELDS,
    REQUIRED_FIELDS,
    Entry,
    EntryMeta,
)
from odmd_bench.leaderboard.files import (
    BUILD,
    ENTRIES,
    JSON_FILE,
    MARKDOWN,
    MAX_PREDICTIONS_BYTES,
    PLOT,
    PLOT_SOURCE_KEY,
    board_digest,
    build_folder,
    discover,
    entry_file_problems,
    find_root,
    plot_source,
    read_entry,
    validate_entry,
)
from odmd_bench.leaderboard.output import write
from odmd_bench.leaderboard.ranking import RANK_CONFIDENCE, RANK_RESAMPLES, RANK_SEED, Ranked, rank_groups
from odmd_bench.leaderboard.render import (
    JSON_DECIMALS,
    Built,
    build,
    render_json,
    render_markdown,
)
from odmd_bench.leaderboard.reported import REPORTED, ReportedResult, read_reported
from odmd_bench.leaderboard.specs import BOARDS, BoardSpec

__all__ = [
    "BOARDS",
    "BUILD",
    "ENTRIES",
    "ENTRY_FILES",
    "JSON_DECIMALS",
    "JSON_FILE",
    "MARKDOWN",
    "MAX_LENGTHS",
    "MAX_PREDICTIONS_BYTES",
    "OPTIONAL_FIELDS",
    "PLOT",
    "PLOT_SOURCE_KEY",
    "RANK_CONFIDENCE",
    "RANK_RESAMPLES",
    "RANK_SEED",
    "REPORTED",
    "REQUIRED_FIELDS",
    "Board",
    "BoardSpec",
    "Built",
    "CheckReport",
    "Entry",
    "EntryMeta",
    "Ranked",
    "ReportedResult",
    "Row",
    "add_entry",
    "board_digest",
    "build",
    "build_folder",
    "check",
    "check_report",
    "collect",
    "data_version",
    "diff_json",
    "diff_markdown",
    "discover",
    "entry_differences",
    "entry_file_problems",
    "find_root",
    "frame",
    "load_board_data",
    "plot_source",
    "rank_groups",
    "read_entry",
    "read_reported",
    "render_json",
    "render_markdown",
    "score_entry",
    "validate_entry",
    "write",
]
