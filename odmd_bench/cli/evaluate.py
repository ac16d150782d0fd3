"""``evaluate`` and ``compare``: score a predictions file, compare two, gate a CI job."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import click

from odmd_bench.cli.options import (
    FINITE_FLOAT,
    FiniteFloatRange,
    data_dir_option,
    data_folder_problems,
    same_file,
)
from odmd_bench.errors import UsageError
from odmd_bench.evaluation.compare import MAX_RESAMPLES
from odmd_bench.evaluation.report import FORMATS
from odmd_bench.inputs.source import stdin_bytes

_BENCHMARK_HELP = "Benchmark the file is for [default: the file's benchmark column, else odmd-v1]."
_SETS_HELP = (
    "Score only these sets (comma-separated, e.g. normal,robot); other sets' rows are checked but not scored."
)
_OUTPUT_HELP = "Write the report to FILE instead of stdout ('-': stdout)."
_PREDS = click.Path(path_type=Path, allow_dash=True)
_OUT = click.Path(path_type=Path, dir_okay=False, allow_dash=True)


def _sets(value: str | None) -> list[str] | None:
    return None if value is None else [s.strip() for s in value.split(",")]


def _warn(warnings: tuple[str, ...] | list[str]) -> None:
    for w in warnings:
        click.echo(f"warning: {w}", err=True)


def _source(path: Path) -> tuple[Any, str | None]:
    """What to read (a path, or stdin's bytes) and the name to report it by."""
    if str(path) == "-":
        return stdin_bytes(), "<stdin>"
    return path, None


def _refuse_overwrite(outputs: dict[str, Path | None], inputs: list[Path], data_dir: Path | None) -> None:
    """A report must never replace a file being scored, another report, or a data file.

    ``outputs``: option -> file, ``None`` or ``-`` for stdout. Paths are compared by
    what they resolve to, so a symbolic or hard link to an input is refused too.
    """
    files = {opt: p for opt, p in outputs.items() if p is not None and str(p) != "-"}
    problems = [
        f"{opt} {p} is the predictions file {src} being scored; write it elsewhere"
        for opt, p in files.items()
        for src in inputs
        if str(src) != "-" and same_file(p, src)
    ]
    named = list(files.items())
    problems += [
        f"{o1} and {o2} name the same file {p1}"
        for i, (o1, p1) in enumerate(named)
        for o2, p2 in named[i + 1 :]
        if same_file(p1, p2)
    ]
    problems += data_folder_problems(files, data_dir)
    if len(outputs) - len(files) > 1:
        problems.append(f"{' and '.join(outputs)} cannot both write to stdout; give one of them a file")
    if problems:
        raise UsageError("refusing to write the output", problems)


def _emit(*reports: tuple[str, Path | None, str]) -> None:
    """Write each ``(text, output, what)``: to stdout when ``output`` is None or ``-``.

    Every file is written before any replaces what was there, so a failure (a full
    disk, a folder that cannot be written) leaves them all as they were.
    """
    from odmd_bench.outputs import atomic_texts

    with atomic_texts([(out, text) for text, out, _ in reports if out is not None and str(out) != "-"]):
        pass
    for text, out, what in reports:
        if out is None or str(out) == "-":
            click.echo(text, nl=False)
        else:
            click.echo(f"wrote {what} to {out}", err=True)


@click.command("evaluate")
@click.argument("preds", type=_PREDS)
@click.option("--benchmark", default=None, help=_BENCHMARK_HELP)
@data_dir_option
@click.option("--format", "fmt", type=click.Choice(FORMATS), default="table", show_default=True)
@click.option("-o", "--output", type=_OUT, default=None, help=_OUTPUT_HELP)
@click.option(
    "--per-example",
    type=_OUT,
    default=None,
    help="Also write a CSV with each example's prediction, truth, percent and absolute error, "
    "number of detected boxes, camera move length and box size ('-': stdout).",
)
@click.option("--sets", default=None, help=_SETS_HELP)
@click.option(
    "--max-all",
    type=FINITE_FLOAT,
    default=None,
    metavar="X",
    help="Exit with status 1 when All (the mean of the sets' mean percent errors) is above X.",
)
def evaluate_command(
    preds: Path,
    benchmark: str | None,
    data_dir: Path | None,
    fmt: str,
    output: Path | None,
    per_example: Path | None,
    sets: str | None,
    max_all: float | None,
) -> None:
    """Validate the predictions CSV PREDS and score it.

    PREDS is a CSV file (or .csv.gz, or - for stdin) with a header and one row per
    example: split, set, index (0-based), depth (metres), and optionally benchmark;
    other columns are ignored, rows may come in any order. A file with any problem is
    refused as a whole, with every problem named (exit status 2). Zero or negative
    depths are scored as given, with a warning.

    \b
    Expected input format (what `odmd-bench baseline NAME -o PREDS` writes):
      split,set,index,depth
      test,normal,0,1.3371905452053497
      test,normal,1,0.6032816400207187
      ...
    \b
      split      val or test; one split per file
      set        each set of the benchmark (odmd-v1, odmd-paper: normal, camera,
                 object, robot; odms-detection: normal, perturb, robot, driving;
                 kitti-tracking: vehicle, person)
      index      0-based, the example's place in its set: each index of each set
                 exactly once
      depth      the estimated depth Z_n at the last observation, in metres: a
                 finite number (|depth| <= 1e12)
      benchmark  optional; else --benchmark, else odmd-v1

    Every rule: docs/format.md#validation.
    """
    from odmd_bench.evaluation.gates import check_ceiling, max_all_gate
    from odmd_bench.evaluation.report import format_per_example, format_result
    from odmd_bench.evaluation.scoring import evaluate

    outputs = {"--output": output} | ({"--per-example": per_example} if per_example is not None else {})
    _refuse_overwrite(outputs, [preds], data_dir)
    if max_all is not None:
        check_ceiling(max_all)  # before scoring, so that a bad X fails fast
    source, name = _source(preds)
    result = evaluate(source, benchmark=benchmark, data_dir=data_dir, sets=_sets(sets), name=name)
    _warn(result.warnings)
    reports = (
        [(format_per_example(result), per_example, "per-example errors")] if per_example is not None else []
    )
    _emit(*reports, (format_result(result, fmt), output, "the report"))
    if max_all is not None:
        passed, line = max_all_gate(result, max_all)
        click.echo(line, err=True)
        if not passed:
            click.get_current_context().exit(1)


@click.command("compare")
@click.argument("a", type=_PREDS)
@click.argument("b", type=_PREDS)
@click.option("--benchmark", default=None, help=_BENCHMARK_HELP)
@data_dir_option
@click.option("--format", "fmt", type=click.Choice(FORMATS), default="table", show_default=True)
@click.option("-o", "--output", type=_OUT, default=None, help=_OUTPUT_HELP)
@click.option("--sets", default=None, help=_SETS_HELP + " With --fail-if-worse, each is also a gate.")
@click.option(
    "--seed",
    type=click.IntRange(min=0),
    default=0,
    show_default=True,
    help="Seed of the bootstrap and the test.",
)
@click.option(
    "--resamples",
    type=click.IntRange(1, MAX_RESAMPLES),
    default=2000,
    show_default=True,
    help="Bootstrap resamples and sign flips.",
)
@click.option(
    "--confidence",
    type=FiniteFloatRange(0, 1, min_open=True, max_open=True),
    default=0.95,
    show_default=True,
    help="Level of the interval; the test's threshold is 1 - confidence.",
)
@click.option(
    "--metric",
    type=click.Choice(["percent_error", "interval_score"]),
    default="percent_error",
    show_default=True,
    help="What to compare: the percent error, or the interval score (both files need an interval).",
)
@click.option(
    "--fail-if-worse",
    is_flag=True,
    help="Exit with status 1 when B (the candidate) is significantly worse than A (the baseline) "
    "on All, or on any set of --sets.",
)
def compare_command(
    a: Path,
    b: Path,
    benchmark: str | None,
    data_dir: Path | None,
    fmt: str,
    output: Path | None,
    sets: str | None,
    seed: int,
    resamples: int,
    confidence: float,
    metric: str,
    fail_if_worse: bool,
) -> None:
    """Compare two predictions files A and B on the same benchmark and split.

    Per set and for All: the difference in mean percent error A - B with a paired
    bootstrap interval, a paired sign-flip test, and a verdict (A better, B better,
    not distinguishable). Both files are validated as by `evaluate`; either may be -
    (stdin). In CI, A is the committed baseline and B the candidate: --fail-if-worse.
    """
    from odmd_bench.evaluation.compare import compare_files, resolution_problem
    from odmd_bench.evaluation.report import format_comparison

    if str(a) == "-" and str(b) == "-":
        raise UsageError("A and B cannot both be read from stdin (-)")
    unable = resolution_problem(resamples, confidence)  # before scoring, so that it fails fast
    if unable is not None:
        raise UsageError(f"--resamples and --confidence: {unable}")
    _refuse_overwrite({"--output": output}, [a, b], data_dir)
    (src_a, name_a), (src_b, name_b) = _source(a), _source(b)
    c, ra, rb = compare_files(
        src_a,
        src_b,
        benchmark=benchmark,
        data_dir=data_dir,
        sets=_sets(sets),
        n_resamples=resamples,
        seed=seed,
        confidence=confidence,
        names=(name_a, name_b),
        metric=metric,
    )
    _warn([f"A: {w}" for w in ra.warnings] + [f"B: {w}" for w in rb.warnings])
    _emit((format_comparison(c, fmt), output, "the comparison"))
    if fail_if_worse:
        from odmd_bench.evaluation.gates import fail_if_worse as worse_gate

        passed, lines = worse_gate(c, list(c.sets) if sets is not None else [])
        for line in lines:
            click.echo(line, err=True)
        if not passed:
            click.get_current_context().exit(1)


COMMANDS: list[click.Command] = [evaluate_command, compare_command]
