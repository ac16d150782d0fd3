"""``leaderboard build``, ``check``, ``site``, ``export`` and ``audit``: the board and its views.

An entry's own commands, ``leaderboard add`` and ``speed``, are in
:mod:`~odmd_bench.cli.leaderboard_entry`; this group holds them too.
"""

from __future__ import annotations

from pathlib import Path

import click

from odmd_bench.cli.leaderboard_entry import add_command, speed_command
from odmd_bench.cli.options import data_dir_option as _data_option
from odmd_bench.cli.options import leaderboard_root as _root
from odmd_bench.cli.options import original_option as _original_option
from odmd_bench.cli.options import root_option as _root_option
from odmd_bench.errors import ValidationError


@click.group("leaderboard")
def leaderboard() -> None:
    """The verified leaderboard: every row re-scored from committed predictions.

    \b
    Add a method (CONTRIBUTING.md, step by step):
      1. odmd-bench baseline ... / your own code  ->  a predictions CSV
      2. odmd-bench leaderboard add PREDS.csv --method ID --name ... (see --help)
      3. odmd-bench leaderboard check, then a pull request with the entry folder only
    The tables, JSON and plot are derived: `leaderboard build` writes them (not committed).
    """


leaderboard.add_command(add_command)
leaderboard.add_command(speed_command)


@leaderboard.command("build")
@click.option(
    "-o",
    "--output",
    type=click.Path(file_okay=False, path_type=Path),
    default=None,
    help="The folder to write to [default: build/ in the leaderboard folder, ignored by git].",
)
@_root_option
@_data_option
@_original_option
@click.option("--no-plot", is_flag=True, help="Do not draw leaderboard.png (it needs the [plot] extra).")
def build_command(
    output: Path | None, root: Path | None, data_dir: Path | None, original: Path | None, no_plot: bool
) -> None:
    """Re-score every entry and write LEADERBOARD.md, leaderboard.json and leaderboard.png.

    They are derived from the entries and not committed; without matplotlib the plot is
    skipped (the rest is written, and the command succeeds).
    """
    from odmd_bench.leaderboard import build, build_folder, write

    folder = _root(root)
    built = build(folder, data_dir, original, progress=lambda line: click.echo(line, err=True))
    for line in write(output if output is not None else build_folder(folder), built, plot=not no_plot):
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
    """Re-score every entry and compare it with the predictions' SHA-256 and scores it records.

    A line per board on stderr while it runs; every difference is named (entry, field,
    recorded and re-scored value). The whole board is built as `build` builds it (rank
    groups, reported results); each recorded audit file must be well formed and match the
    board; --audits also re-runs them. Nothing is written.

    \b
    Exit status:
      0  every entry re-scored, and each records its predictions' SHA-256 and scores
      1  the gate failed: an entry's recorded SHA-256 or score differs from its re-scoring
         (with --audits: or a recorded audit differs from its re-run)
      2  bad input: an entry, reported.yaml or an audit file is invalid (every problem named)
    """
    from odmd_bench.leaderboard import check_report

    folder = _root(root)
    report = check_report(folder, data_dir, original, progress=lambda line: click.echo(line, err=True))
    if report.invalid:
        n = len(report.invalid)
        raise ValidationError(
            f"leaderboard check failed ({folder}): {n} {'problem' if n == 1 else 'problems'} with the "
            "entries; fix them (`odmd-bench leaderboard add --replace` rewrites an entry)",
            report.invalid,
        )
    differences = list(report.differences)
    if audits and not report.differences:
        from odmd_bench.leaderboard.audit_check import rerun_audits

        differences = rerun_audits(
            folder, data_dir, original, progress=lambda line: click.echo(line, err=True)
        )
    if differences:
        n = len(differences)
        click.echo(
            f"fail: leaderboard check ({folder}): {n} {'difference' if n == 1 else 'differences'} "
            + (
                "between the recorded audits and their re-runs; record the audit again"
                if not report.differences
                else "between what the entries record and their re-scoring: an entry's predictions "
                "or numbers were changed by hand; make it again with `odmd-bench leaderboard add --replace`"
            ),
            err=True,
        )
        for line in differences:
            click.echo(f"  - {line}", err=True)
        click.get_current_context().exit(1)
    said = "; every recorded audit re-run" if audits else ""
    click.echo(f"leaderboard check passed: {folder}: every entry re-scored, as it records{said}")


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
    "--no-croissant",
    is_flag=True,
    help="Write no Croissant descriptions into downloads/ (by default one per ranked benchmark, which "
    "loads its val and test sets).",
)
@click.option(
    "--source-url",
    default=None,
    help="Where repository paths link to, e.g. https://github.com/odmd-bench/odmd-bench/blob/main "
    "[default: shown as text].",
)
@_root_option
@_data_option
@_original_option
def site_command(
    output: Path,
    no_plot: bool,
    no_croissant: bool,
    source_url: str | None,
    root: Path | None,
    data_dir: Path | None,
    original: Path | None,
) -> None:
    """Write the leaderboard as a static web site: index, a page per method, downloads.

    Built from the entries, as `leaderboard build` builds the board (an entry whose
    recorded SHA-256 or scores differ from its re-scoring stops it, as `check` fails).
    Serve the folder with any web server, e.g. python -m http.server -d DIR.
    """
    from odmd_bench.extras import require
    from odmd_bench.leaderboard.site import build_site, check_site_folder, write_site

    require("jinja2", "site", "odmd-bench leaderboard site")  # before scoring: fail fast
    check_site_folder(output)  # a folder of other files too
    folder = _root(root)
    files, said = build_site(
        folder,
        data_dir,
        original,
        figures=False if no_plot else None,
        source_url=source_url,
        croissant=not no_croissant,
    )
    kept = write_site(files, output)
    for line in said:
        click.echo(line)
    if kept:
        shown = ", ".join(kept[:10]) + (f", ... ({len(kept) - 10} more)" if len(kept) > 10 else "")
        click.echo(f"kept {len(kept)} file(s) in {output} that odmd-bench did not write: {shown}")
    pages = sum(1 for name in files if name.endswith(".html"))
    click.echo(f"wrote {output}: {len(files)} files, {pages} pages (open {output / 'index.html'})")


@leaderboard.command("export")
@click.option(
    "--format",
    "fmt",
    required=True,
    type=click.Choice(["hf-eval-results", "json"]),
    help="hf-eval-results: Hugging Face's .eval_results YAML, a folder per method; json: results.json, "
    "a record per entry with its provenance (re-scored here, or reported in a paper).",
)
@click.option(
    "-o",
    "--output",
    required=True,
    type=click.Path(path_type=Path),
    help="The folder to write into (files of the same names are replaced).",
)
@click.option(
    "--hf-dataset",
    default=None,
    help="hf-eval-results: the Hub dataset id the results name [default: odmd-bench/odmd].",
)
@_root_option
@_data_option
@_original_option
def export_command(
    fmt: str,
    output: Path,
    hf_dataset: str | None,
    root: Path | None,
    data_dir: Path | None,
    original: Path | None,
) -> None:
    """Write the board in an exchange format other leaderboards read (docs/format.md).

    Every entry is re-scored first, as by `leaderboard build` (a problem stops it); the
    numbers are leaderboard.json's.
    """
    from odmd_bench.leaderboard import build
    from odmd_bench.leaderboard.export import HF_DATASET, export_files, write_export

    built = build(_root(root), data_dir, original, progress=lambda line: click.echo(line, err=True))
    files = export_files(built, fmt, hf_dataset=hf_dataset or HF_DATASET)
    for path in write_export(files, output):
        click.echo(str(path))


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
    help="Write the audit to leaderboard/audits/SEED.json (then run leaderboard build); refused where "
    "an entry a record re-ran, or a shipped method's, cannot be re-run here.",
)
@click.option(
    "--only",
    "only",
    multiple=True,
    metavar="METHOD",
    help="Audit this entry (a method id of the odmd-v1 test board) alone; repeat for more "
    "[default: every entry].",
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
    only: tuple[str, ...],
    data_dir: Path | None,
    original: Path | None,
) -> None:
    """Re-run every entry of the odmd-v1 test board on fresh draws of its generated sets.

    The Normal, Camera and Object test sets are drawn again (same generator and
    configuration, seeds derived from SEED; Robot is real and left out), every entry whose
    method can be run here (shipped, an installed plug-in, or a plug-in kept in its entry
    folder) is re-run on them with its recorded options, and its committed test means are
    compared with the fresh ones. An entry is flagged when its committed score is better
    than chance allows (one-sided permutation test, Holm-corrected; leaderboard/README.md).
    An entry that cannot be re-run is shown "not audited: REASON"; a plug-in that fails,
    exits or prints is contained and shown "failed: REASON". Exit status: 0 with nothing
    flagged, 1 when an entry is flagged, 2 on bad input or a refused --record.
    """
    from odmd_bench.errors import UsageError
    from odmd_bench.leaderboard.audit import audit, audit_json, audit_table, flagged, record_problems
    from odmd_bench.leaderboard.audit_files import record as write_record

    folder = _root(root)
    result = audit(
        folder,
        seed,
        repeats=repeats,
        size=size,
        data_dir=data_dir,
        original=original,
        only=list(dict.fromkeys(only)) or None,
        progress=lambda line: click.echo(line, err=True),
    )
    click.echo(audit_json(result) if fmt == "json" else audit_table(result), nl=False)
    if record:
        refused = record_problems(folder, result)
        if refused:
            raise UsageError(
                "not recorded: this audit would replace re-run results with 'not re-run' (record it where "
                "every such entry runs: pip install -e '.[dbox]', --original PATH, the plug-in installed)",
                refused,
            )
        path = write_record(folder, result)
        click.echo(f"recorded {path}; now run `odmd-bench leaderboard build` and commit it", err=True)
    if flagged(result):
        click.get_current_context().exit(1)


COMMANDS: list[click.Command] = [leaderboard]
