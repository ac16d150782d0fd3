"""``leaderboard build``, ``check``, ``add``, ``site`` and ``audit``."""

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
@click.option(
    "--audits",
    "audits",
    is_flag=True,
    help="Also re-run every recorded audit (leaderboard/audits/SEED.json) and fail where one differs "
    "(re-runs every audited method: about a minute).",
)
def check_command(root: Path | None, data_dir: Path | None, original: Path | None, audits: bool) -> None:
    """Re-score every entry and compare the committed table and JSON with what build writes now.

    A line per board on stderr while it runs; every difference is named (file, row,
    field, old and new). Each recorded audit file must be well formed and match the
    board; --audits also re-runs them.

    \b
    Exit status:
      0  the committed files are what build writes, every entry re-scored
      1  the gate failed: a committed file differs from a fresh build (with --audits:
         or a recorded audit differs from its re-run)
      2  bad input: an entry, reported.yaml or an audit file is invalid (every problem named)
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
    differences = list(report.differences)
    if audits and not report.differences:
        from odmd_bench.leaderboard.audit import rerun_audits

        differences = rerun_audits(
            folder, data_dir, original, progress=lambda line: click.echo(line, err=True)
        )
    if differences:
        n = len(differences)
        click.echo(
            f"fail: leaderboard check ({folder}): {n} {'difference' if n == 1 else 'differences'} from what "
            + ("the audits give now" if not report.differences else "build writes now")
            + "; run `odmd-bench leaderboard build` and commit LEADERBOARD.md, "
            "leaderboard.json and README.md" + ("" if report.differences else " (or record the audit again)"),
            err=True,
        )
        for line in differences:
            click.echo(f"  - {line}", err=True)
        click.get_current_context().exit(1)
    said = "; every recorded audit re-run" if audits else ""
    click.echo(f"leaderboard check passed: {folder} is what build writes, every entry re-scored{said}")


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


@leaderboard.command("site")
@click.option(
    "-o",
    "--output",
    required=True,
    type=click.Path(path_type=Path),
    help="The folder to write the site to (new, empty, or a site written before, which is replaced).",
)
@click.option("--no-plot", is_flag=True, help="Draw no figures (they need the [plot] extra, matplotlib).")
@click.option(
    "--source-url",
    default=None,
    help="Where repository paths link to, e.g. https://github.com/OWNER/odmd-bench/blob/main "
    "[default: shown as text].",
)
@_root_option
@_data_option
@_original_option
def site_command(
    output: Path,
    no_plot: bool,
    source_url: str | None,
    root: Path | None,
    data_dir: Path | None,
    original: Path | None,
) -> None:
    """Write the leaderboard as a static web site: index, a page per method, downloads.

    Built from the committed leaderboard.json, each entry re-scored beside it (a number
    that differs stops it: run `leaderboard build` first). Serve the folder with any web
    server, e.g. python -m http.server -d DIR.
    """
    from odmd_bench.leaderboard.site import build_site, write_site

    folder = _root(root)
    files, said = build_site(
        folder, data_dir, original, figures=False if no_plot else None, source_url=source_url
    )
    kept = write_site(files, output)
    for line in said:
        click.echo(line)
    if kept:
        shown = ", ".join(kept[:10]) + (f", ... ({len(kept) - 10} more)" if len(kept) > 10 else "")
        click.echo(f"kept {len(kept)} file(s) in {output} that odmd-bench did not write: {shown}")
    pages = sum(1 for name in files if name.endswith(".html"))
    click.echo(f"wrote {output}: {len(files)} files, {pages} pages (open {output / 'index.html'})")


@leaderboard.command("audit")
@click.option(
    "--seed",
    required=True,
    type=click.IntRange(0, 2**53),
    help="Seed of the fresh sets (and of the test's permutations); the same seed gives the same audit.",
)
@_root_option
@click.option(
    "--repeats",
    default=5,  # odmd_bench.leaderboard.audit.REPEATS (a test checks that they agree)
    show_default=True,
    type=click.IntRange(1, 100),
    help="Fresh draws per set, pooled (more draws: fewer chance flags, more power, longer).",
)
@click.option(
    "--size",
    default=None,
    type=click.IntRange(1, 1_000_000),
    help="Examples per fresh set [default: as many as the committed set].",
)
@click.option(
    "--format",
    "fmt",
    type=click.Choice(["table", "json"]),
    default="table",
    show_default=True,
    help="Output format.",
)
@click.option(
    "--record",
    is_flag=True,
    help="Write the audit to leaderboard/audits/SEED.json (then run leaderboard build).",
)
@_data_option
@_original_option
def audit_command(
    seed: int,
    root: Path | None,
    repeats: int,
    size: int | None,
    fmt: str,
    record: bool,
    data_dir: Path | None,
    original: Path | None,
) -> None:
    """Re-run every entry of the odmd-v1 test board on fresh draws of its generated sets.

    The Normal, Camera and Object test sets are drawn again (same generator and
    configuration, seeds derived from SEED; Robot is real and left out), every entry whose
    command is `odmd-bench baseline NAME ...` of an installed method is re-run on them with
    its recorded options, and its committed test means are compared with the fresh ones.
    An entry is flagged when its committed score is better than chance allows (one-sided
    permutation test, Holm-corrected; leaderboard/README.md). Exit status: 0 with nothing
    flagged, 1 when an entry is flagged, 2 on bad input.
    """
    from odmd_bench.leaderboard.audit import audit, audit_json, audit_table, flagged
    from odmd_bench.leaderboard.audit_files import record as write_record

    folder = _root(root)
    result = audit(
        folder,
        seed,
        repeats=repeats,
        size=size,
        data_dir=data_dir,
        original=original,
        progress=lambda line: click.echo(line, err=True),
    )
    if record:
        path = write_record(folder, result)
        click.echo(f"recorded {path}; now run `odmd-bench leaderboard build` and commit it", err=True)
    click.echo(audit_json(result) if fmt == "json" else audit_table(result), nl=False)
    if flagged(result):
        click.get_current_context().exit(1)


COMMANDS: list[click.Command] = [leaderboard]
