"""``leaderboard build``, ``leaderboard check`` and ``leaderboard add``."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import click

from odmd_bench.cli.options import data_dir_option
from odmd_bench.data.registry import BENCHMARKS, SPLITS
from odmd_bench.errors import ValidationError

_root_option = click.option(
    "--root",
    type=click.Path(file_okay=False, path_type=Path),
    default=None,
    help="The leaderboard folder [default: leaderboard/ in the current folder or a parent].",
)
_data_option = data_dir_option
_original_option = click.option(
    "--original",
    type=click.Path(exists=True, file_okay=False, path_type=Path),
    envvar="ODMD_ORIGINAL",
    default=None,
    help="The original ODMD release's data folder (e.g. ../shared/odmd-original), imported into the "
    "data folder when odmd-paper is missing there [env: ODMD_ORIGINAL].",
)


def _root(root: Path | None) -> Path:
    from odmd_bench.leaderboard import find_root

    return root if root is not None else find_root()


@click.group("leaderboard")
def leaderboard() -> None:
    """The verified leaderboard: every row re-scored from committed predictions.

    \b
    Add a method in three steps:
      1. odmd-bench baseline ... / your own code  ->  a predictions CSV
      2. odmd-bench leaderboard add PREDS.csv --method ID --name ... (see --help)
      3. odmd-bench leaderboard build && odmd-bench leaderboard check
    """


@leaderboard.command("build")
@_root_option
@_data_option
@_original_option
@click.option("--no-plot", is_flag=True, help="Do not draw leaderboard.png.")
def build_command(root: Path | None, data_dir: Path | None, original: Path | None, no_plot: bool) -> None:
    """Re-score every entry and write LEADERBOARD.md, leaderboard.json and leaderboard.png."""
    from odmd_bench.leaderboard import build, write

    folder = _root(root)
    built = build(folder, data_dir, original, progress=lambda line: click.echo(line, err=True))
    for line in write(folder, built, plot=not no_plot):
        click.echo(line)
    n = sum(len(b.rows) for b in built.boards)
    click.echo(f"{n} entries on {len(built.boards)} boards; {len(built.reported)} reported results")


@leaderboard.command("check")
@_root_option
@_data_option
@_original_option
def check_command(root: Path | None, data_dir: Path | None, original: Path | None) -> None:
    """Re-score every entry and compare the committed table and JSON with what build writes now.

    A line per board on stderr while it runs; every difference is named (file, row,
    field, old and new).

    \b
    Exit status:
      0  the committed files are what build writes, every entry re-scored
      1  the gate failed: a committed file differs from a fresh build
      2  bad input: an entry or reported.yaml is invalid (every problem named)
    """
    from odmd_bench.leaderboard import check_report

    folder = _root(root)
    report = check_report(folder, data_dir, original, progress=lambda line: click.echo(line, err=True))
    if report.invalid:
        n = len(report.invalid)
        raise ValidationError(
            f"leaderboard check failed ({folder}): {n} {'problem' if n == 1 else 'problems'} with the "
            "entries; fix them, then run `odmd-bench leaderboard build`",
            report.invalid,
        )
    if report.differences:
        n = len(report.differences)
        click.echo(
            f"fail: leaderboard check ({folder}): {n} {'difference' if n == 1 else 'differences'} from what "
            "build writes now; run `odmd-bench leaderboard build` and commit LEADERBOARD.md, "
            "leaderboard.json and README.md",
            err=True,
        )
        for line in report.differences:
            click.echo(f"  - {line}", err=True)
        click.get_current_context().exit(1)
    click.echo(f"leaderboard check passed: {folder} is what build writes, every entry re-scored")


@leaderboard.command("add")
@click.argument("predictions", type=click.Path(exists=True, dir_okay=False, path_type=Path))
@click.option("--method", required=True, help="Method id, lowercase (the entry folder's name), e.g. dbox.")
@click.option(
    "--name", required=True, help="Name shown in the table, e.g. DBox_p (one line, at most 80 characters)."
)
@click.option("--description", required=True, help="One or two sentences (at most 500 characters).")
@click.option("--paper", required=True, help="Link to the paper, or 'none'.")
@click.option("--code", required=True, help="Link to the code, or a path in this repository.")
@click.option("--training-data", required=True, help="What it trained on ('none' for analytical methods).")
@click.option("--command", "command_", required=True, help="The exact command that produced the predictions.")
@click.option("--benchmark", required=True, type=click.Choice(list(BENCHMARKS)))
@click.option(
    "--split",
    default="test",
    show_default=True,
    type=click.Choice(SPLITS),
    help="The split; there must be a board for it (today: test).",
)
@click.option(
    "--calibrated/--uncalibrated", required=True, help="Whether the method uses the camera intrinsics."
)
@click.option("--date", default=None, help="YYYY-MM-DD, not in the future [default: today].")
@click.option("--notes", default=None, help="Anything else a reader should know (at most 1000 characters).")
@click.option("--replace", is_flag=True, help="Overwrite an existing entry.")
@_root_option
@_data_option
@_original_option
def add_command(predictions: Path, root: Path | None, command_: str, **fields: Any) -> None:
    """Add the predictions CSV PREDICTIONS as an entry (validated, hashed, compressed)."""
    from odmd_bench.leaderboard import add_entry

    # The other options are add_entry's keywords, under the same names.
    entry = add_entry(_root(root), predictions, command=command_, **fields)
    click.echo(f"added {entry.folder}; now run `odmd-bench leaderboard build` and commit the folder")


COMMANDS: list[click.Command] = [leaderboard]
