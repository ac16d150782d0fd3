"""``evaluate`` and ``compare``: score a predictions file, compare two."""

from __future__ import annotations

from pathlib import Path

import click

from odmd_bench.evaluation.report import FORMATS

_BENCHMARK_HELP = "Benchmark the file is for [default: the file's benchmark column, else odmd-v1]."
_DATA_HELP = "Data folder [default: $ODMD_BENCH_DATA, else ~/.local/share/odmd-bench]."
_SETS_HELP = "Score only these sets (comma-separated, e.g. normal,robot); other sets' rows are ignored."


def _sets(value: str | None) -> list[str] | None:
    return None if value is None else [s.strip() for s in value.split(",")]


def _warn(warnings: tuple[str, ...] | list[str]) -> None:
    for w in warnings:
        click.echo(f"warning: {w}", err=True)


@click.command("evaluate")
@click.argument("preds", type=click.Path(path_type=Path, dir_okay=True))
@click.option("--benchmark", default=None, help=_BENCHMARK_HELP)
@click.option("--data-dir", type=click.Path(path_type=Path, file_okay=False), default=None, help=_DATA_HELP)
@click.option("--format", "fmt", type=click.Choice(FORMATS), default="table", show_default=True)
@click.option(
    "--per-example",
    type=click.Path(path_type=Path, dir_okay=False),
    default=None,
    help="Also write a CSV with each example's prediction, truth, percent and absolute error, "
    "number of detected boxes, camera move length and box size.",
)
@click.option("--sets", default=None, help=_SETS_HELP)
def evaluate_command(
    preds: Path,
    benchmark: str | None,
    data_dir: Path | None,
    fmt: str,
    per_example: Path | None,
    sets: str | None,
) -> None:
    """Validate the predictions CSV PREDS and score it.

    PREDS is a CSV file with a header and one row per example: split, set, index
    (0-based), depth (metres), and optionally benchmark; other columns are ignored,
    rows may come in any order. A file with any problem is refused as a whole, with
    every problem named (exit status 2). Zero or negative depths are scored as given,
    with a warning.
    """
    from odmd_bench.evaluation.report import format_result, write_per_example
    from odmd_bench.evaluation.scoring import evaluate

    result = evaluate(preds, benchmark=benchmark, data_dir=data_dir, sets=_sets(sets))
    _warn(result.warnings)
    if per_example is not None:
        write_per_example(per_example, result)
        click.echo(f"wrote per-example errors to {per_example}", err=True)
    click.echo(format_result(result, fmt), nl=False)


@click.command("compare")
@click.argument("a", type=click.Path(path_type=Path))
@click.argument("b", type=click.Path(path_type=Path))
@click.option("--benchmark", default=None, help=_BENCHMARK_HELP)
@click.option("--data-dir", type=click.Path(path_type=Path, file_okay=False), default=None, help=_DATA_HELP)
@click.option("--format", "fmt", type=click.Choice(FORMATS), default="table", show_default=True)
@click.option("--sets", default=None, help=_SETS_HELP)
@click.option("--seed", type=int, default=0, show_default=True, help="Seed of the bootstrap and the test.")
@click.option(
    "--resamples",
    type=click.IntRange(min=1),
    default=2000,
    show_default=True,
    help="Bootstrap resamples and sign flips.",
)
def compare_command(
    a: Path,
    b: Path,
    benchmark: str | None,
    data_dir: Path | None,
    fmt: str,
    sets: str | None,
    seed: int,
    resamples: int,
) -> None:
    """Compare two predictions files A and B on the same benchmark and split.

    Per set and for All: the difference in mean percent error A - B with a paired
    bootstrap 95% interval, a paired sign-flip test, and a verdict (A better, B better,
    not distinguishable). Both files are validated as by `evaluate`.
    """
    from odmd_bench.evaluation.compare import compare_files
    from odmd_bench.evaluation.report import format_comparison

    c, ra, rb = compare_files(
        a, b, benchmark=benchmark, data_dir=data_dir, sets=_sets(sets), n_resamples=resamples, seed=seed
    )
    _warn([f"A: {w}" for w in ra.warnings] + [f"B: {w}" for w in rb.warnings])
    click.echo(format_comparison(c, fmt), nl=False)


COMMANDS: list[click.Command] = [evaluate_command, compare_command]
