"""``plot``: error against true depth, binned, one line per predictions file."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import click

from odmd_bench.cli.options import data_dir_option, data_folder_problems, same_file
from odmd_bench.errors import UsageError, ValidationError
from odmd_bench.evaluation.depth_bins import DEFAULT_BINS, ERRORS
from odmd_bench.inputs.source import stdin_bytes

_PREDS = click.Path(path_type=Path, allow_dash=True)
_OUT = click.Path(path_type=Path, dir_okay=False)

#: The warning every file of a whole split gets when one set is plotted: expected, not shown.
_IGNORED_SETS = "ignored rows of sets not asked for"


def _labels(preds: tuple[Path, ...], given: tuple[str, ...]) -> list[str]:
    """``--label`` values, or each file's name (its path as given where names repeat).

    A ``$`` in a file name is escaped, so that a name is never read as math text, and
    bytes of a name that are not UTF-8 are drawn as U+FFFD (a font has no glyph for them).
    """
    if given:
        return list(given)
    names = ["stdin" if str(p) == "-" else p.name for p in preds]
    chosen = [n if names.count(n) == 1 else str(p) for n, p in zip(names, preds, strict=True)]
    drawable = [n.encode("utf-8", "surrogateescape").decode("utf-8", "replace") for n in chosen]
    return [n.replace("$", r"\$") for n in drawable]


def _check_usage(
    preds: tuple[Path, ...],
    labels: tuple[str, ...],
    output: Path,
    csv_out: Path | None,
    data_dir: Path | None,
) -> None:
    """Every problem of the command line itself, in one report, before anything is read."""
    problems = []
    if labels and len(labels) != len(preds):
        problems.append(
            f"{len(labels)} --label for {len(preds)} predictions files; give one per file, in order"
        )
    if sum(str(p) == "-" for p in preds) > 1:
        problems.append("stdin (-) can be read only once")
    if output.suffix.lower() != ".png":
        problems.append(f"-o {output}: the figure is a PNG; name it *.png")
    outputs = {"-o": output} | ({"--csv": csv_out} if csv_out is not None else {})
    problems += [
        f"{opt} {out} is the predictions file {p}; write it elsewhere"
        for opt, out in outputs.items()
        for p in preds
        if str(p) != "-" and same_file(out, p)
    ]
    if csv_out is not None and same_file(output, csv_out):
        problems.append(f"-o and --csv name the same file {output}")
    problems += data_folder_problems(outputs, data_dir)
    if problems:
        raise UsageError("cannot plot", problems)


def _score_all(
    preds: tuple[Path, ...], set_name: str, benchmark: str | None, split: str | None, data_dir: Path | None
) -> list[Any]:
    """Validate and score each file on ``set_name``; every file's problems in one error.

    The evaluator's pipeline (parse, coverage, score), with the set loaded once per
    benchmark and split, and each file's benchmark and split checked before any data is read.
    """
    from odmd_bench.data.registry import check_set, get_benchmark
    from odmd_bench.data.store import load_split
    from odmd_bench.evaluation.coverage import check_coverage
    from odmd_bench.evaluation.parse import parse_predictions
    from odmd_bench.evaluation.scoring import score

    loaded: dict[tuple[str, str], Any] = {}
    results: list[Any] = []
    problems: list[str] = []
    first: tuple[str, str] | None = None
    for p in preds:
        name = "<stdin>" if str(p) == "-" else str(p)
        try:
            parsed = parse_predictions(
                stdin_bytes() if str(p) == "-" else p, name=name, benchmark=benchmark, strict=False
            )
            if parsed.benchmark is None or parsed.split is None:
                raise parsed.problems.error(parsed.name)
        except ValidationError as e:
            problems += [f"{e.message}: {q}" for q in e.problems] or [e.message]
            continue
        key = (parsed.benchmark, parsed.split)
        if split is not None and parsed.split != split:
            problems.append(f"{name} is for split {parsed.split!r}, not --split {split!r}")
            continue
        if first is not None and key != first:
            problems.append(
                f"{name} is for {key[0]} {key[1]}, the first file for {first[0]} {first[1]}; "
                "plot one benchmark and split at a time"
            )
            continue
        first = key
        bench = get_benchmark(parsed.benchmark)
        check_set(bench, set_name)
        if key not in loaded:
            loaded[key] = load_split(parsed.split, bench, data_dir, [set_name])
        examples = loaded[key]
        try:
            predictions = check_coverage(parsed, {set_name: len(examples[set_name])}, sets=[set_name])
            results.append(score(predictions, examples, bench=bench))
        except ValidationError as e:
            problems += [f"{e.message}: {q}" for q in e.problems] or [e.message]
            continue
        for w in results[-1].warnings:
            if not w.startswith(_IGNORED_SETS):
                click.echo(f"warning: {name}: {w}", err=True)
    if problems:
        raise ValidationError(f"cannot plot: {len(problems)} problem(s) in the predictions files", problems)
    return results


@click.command("plot")
@click.argument("preds", nargs=-1, required=True, type=_PREDS)
@click.option("--set", "set_name", required=True, help="The set whose examples are plotted, e.g. driving.")
@click.option("-o", "--output", type=_OUT, required=True, help="The PNG to write.")
@click.option(
    "--benchmark",
    default=None,
    help="Benchmark the files are for [default: the files' benchmark column, else odmd-v1].",
)
@click.option(
    "--split", type=click.Choice(["val", "test"]), default=None, help="Refuse files of another split."
)
@click.option(
    "--error",
    type=click.Choice(list(ERRORS)),
    default="absolute",
    show_default=True,
    help="absolute: |Z - Z_hat| in metres; percent: |Z - Z_hat| / Z * 100.",
)
@click.option(
    "--bins",
    default=str(DEFAULT_BINS),
    show_default=True,
    help="Number of equal-width bins over the set's true depth range, or comma-separated edges in metres.",
)
@click.option(
    "--label",
    "labels",
    multiple=True,
    help="A method's name in the legend, once per file, in order [default: file names].",
)
@click.option(
    "--band/--no-band",
    default=True,
    show_default=True,
    help="Shade each method's interquartile range per bin.",
)
@click.option(
    "--title", default=None, help="The figure's title [default: error kind, set, benchmark, split, examples]."
)
@click.option("--csv", "csv_out", type=_OUT, default=None, help="Also write the binned numbers to this CSV.")
@click.option(
    "--reliability",
    is_flag=True,
    help="Draw a reliability diagram instead: the observed coverage of each file's error bars against "
    "their nominal level (the normal of depth_std at several levels, the stated interval as one point); "
    "--csv then writes those numbers.",
)
@data_dir_option
def plot_command(
    preds: tuple[Path, ...],
    set_name: str,
    output: Path,
    benchmark: str | None,
    split: str | None,
    error: str,
    bins: str,
    labels: tuple[str, ...],
    band: bool,
    title: str | None,
    csv_out: Path | None,
    reliability: bool,
    data_dir: Path | None,
) -> None:
    """Plot error against true depth for one set: one line per predictions file PREDS.

    Each PREDS file (CSV, .csv.gz, or - for stdin) is validated and scored as by
    `evaluate`, on the set --set only; its rows of other sets are checked, not plotted. The set's
    examples are binned by true depth; each method's line is its mean error per bin,
    with its interquartile range shaded, and a bar chart below counts the examples per
    bin. All files must be for one benchmark and split. Needs the plot extra
    (matplotlib). Labels may use matplotlib's $...$ math text.

    \b
    The paper's figure (DBox_p^z against DBox_Abs^z on the Driving set):
      odmd-bench plot p-z.csv abs-z.csv --benchmark odms-detection \\
        --set driving --label 'DBox$_p^z$' --label 'DBox$_{Abs}^z$' -o driving.png
    """
    from odmd_bench.data.registry import check_set, get_benchmark
    from odmd_bench.evaluation.depth_bins import error_curves, format_curves_csv, parse_bins
    from odmd_bench.evaluation.plot import default_title, draw_error_curves, text_problems
    from odmd_bench.extras import require

    _check_usage(preds, labels, output, csv_out, data_dir)
    edges = parse_bins(bins)
    if benchmark is not None:
        check_set(get_benchmark(benchmark), set_name)
    require("matplotlib", "plot", "odmd-bench plot")  # before scoring: fail fast
    texts = [("--label", t) for t in labels] + ([("--title", title)] if title is not None else [])
    bad_text = text_problems(texts)
    if bad_text:
        raise UsageError("cannot draw these texts", bad_text)

    results = _score_all(preds, set_name, benchmark, split, data_dir)
    if reliability:
        _reliability(results, _labels(preds, labels), set_name, output, csv_out, title)
        return
    curves = error_curves(results, _labels(preds, labels), set_name, error=error, bins=edges)
    first = results[0]
    heading = title or default_title(first.benchmark, first.split, set_name, error, curves[0].n)
    from odmd_bench.outputs import atomic_texts

    # The numbers and the figure replace their old files together, or neither does.
    outputs: list[tuple[Path, str]] = []
    if csv_out is not None:
        numbers = format_curves_csv(
            curves, benchmark=first.benchmark, split=first.split, set_name=set_name, error=error
        )
        outputs.append((csv_out, numbers))
    with atomic_texts(outputs, also=[output]) as (figure,):
        draw_error_curves(curves, figure, error=error, title=heading, band=band)
    click.echo(f"wrote the figure to {output}", err=True)
    if csv_out is not None:
        click.echo(f"wrote the binned numbers to {csv_out}", err=True)
    outside = curves[0].bins.outside
    if outside:
        click.echo(
            f"note: {outside} of {curves[0].n} examples lie outside the bin edges and are not shown", err=True
        )


def _reliability(
    results: list[Any],
    labels: list[str],
    set_name: str,
    output: Path,
    csv_out: Path | None,
    title: str | None,
) -> None:
    """``plot --reliability``: coverage against level for the files' error bars on ``set_name``."""
    from odmd_bench.evaluation.plot import draw_reliability
    from odmd_bench.evaluation.uncertainty import RELIABILITY_LEVELS, reliability
    from odmd_bench.outputs import atomic_texts

    curves = []
    lacking = []
    rows = ["label,kind,level,coverage"]
    for label, r in zip(labels, results, strict=True):
        unc = r.uncertainty.get(set_name, {})
        truth = r.examples[set_name].depth
        levels: tuple[float, ...] = ()
        cover: list[float] = []
        if "depth_std" in unc:
            levels, cover = RELIABILITY_LEVELS, reliability(truth, r.predictions[set_name], unc["depth_std"])
            rows += [f"{label},normal,{lv!r},{c!r}" for lv, c in zip(levels, cover, strict=True)]
        interval = None
        if "coverage" in r.sets[set_name]:
            cov = r.sets[set_name]["coverage"]
            interval = (cov["level"], cov["observed"])
            rows.append(f"{label},interval,{interval[0]!r},{interval[1]!r}")
        if not levels and interval is None:
            lacking.append(f"{label}: no error bars (columns depth_lo, depth_hi, level or depth_std)")
        curves.append((label, levels, cover, interval))
    if lacking:
        raise UsageError("a reliability diagram needs error bars", lacking)
    first = results[0]
    heading = title or f"Reliability: {set_name.capitalize()} set\n{first.benchmark} {first.split}"
    outputs = [(csv_out, "\n".join(rows) + "\n")] if csv_out is not None else []
    with atomic_texts(outputs, also=[output]) as (figure,):
        draw_reliability(curves, figure, title=heading)
    click.echo(f"wrote the reliability diagram to {output}", err=True)


COMMANDS: list[click.Command] = [plot_command]
