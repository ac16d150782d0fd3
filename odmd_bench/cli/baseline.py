"""``baseline``: run a registered method on every set of a split and write predictions.

The methods are plug-ins (:mod:`odmd_bench.methods`): ``NAME`` is looked up among the
entry points of the group ``odmd_bench.methods``, and the method's module is imported
only then, so that torch is loaded for a method that needs it alone and a missing one is
a usage error naming the extra to install.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import click

from odmd_bench.cli.options import (
    FiniteFloatRange,
    MethodCommand,
    data_dir_option,
    data_folder_problems,
    given_options,
)
from odmd_bench.data.registry import BENCHMARKS, DEFAULT_BENCHMARK, SPLITS
from odmd_bench.errors import UsageError


def _list_methods(ctx: click.Context, _param: click.Parameter, value: bool) -> None:
    if not value or ctx.resilient_parsing:
        return
    from odmd_bench import methods
    from odmd_bench.errors import UsageError

    for name in methods.names():
        try:
            method = methods.load(name)
        except UsageError as e:  # a broken plug-in is listed as such, not a failure of --list
            click.echo(f"{name}: not usable: {e}")
            continue
        taken = [o.flag for o in method.options]
        click.echo(
            f"{name}: {method.target} (from {method.source})"
            + (f"; takes {' '.join(taken)}" if taken else "")
        )
        for option in method.options:
            click.echo(f"    {option.describe()}")
    ctx.exit(0)


def default_output(name: str, benchmark: str, split: str) -> Path:
    """``preds-<name>-<benchmark>-<split>.csv`` in the current folder."""
    return Path(f"preds-{name}-{benchmark}-{split}.csv")


@click.command(cls=MethodCommand, method_param="name")
@click.argument("name")
@click.option(
    "--list",
    "list_",
    is_flag=True,
    expose_value=False,
    is_eager=True,
    callback=_list_methods,
    help="List the registered methods, where each comes from and the options it declares, and exit.",
)
@click.option(
    "--benchmark",
    default=DEFAULT_BENCHMARK,
    show_default=True,
    type=click.Choice(list(BENCHMARKS)),
    help="Benchmark whose sets are estimated.",
)
@click.option(
    "--split", default="test", show_default=True, type=click.Choice(SPLITS), help="Split to run on."
)
@click.option(
    "-o",
    "--output",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="Predictions CSV to write ('-': stdout, the messages then go to stderr; "
    "default: preds-NAME-BENCHMARK-SPLIT.csv here).",
)
@click.option(
    "--interval",
    type=FiniteFloatRange(0, 1, min_open=True, max_open=True),
    default=None,
    metavar="LEVEL",
    help="Also write error bars: a central interval of this nominal coverage (e.g. 0.9) and a "
    "normal's depth_std, calibrated on the benchmark's val sets (split conformal, on the "
    "method's own spread where it gives one); docs/uncertainty.md.",
)
@data_dir_option
def baseline(
    name: str,
    benchmark: str,
    split: str,
    output: Path | None,
    interval: float | None,
    data_dir: Path | None,
    **method_values: Any,  # the options method NAME declares (MethodCommand)
) -> None:
    """Run method NAME on every set of a split and write a predictions CSV.

    NAME is a method registered under the entry-point group odmd_bench.methods, by this
    package or any other installed one: --list shows them. The options a method declares
    are given after its name (odmd-bench baseline NAME --help lists them).
    """
    import numpy as np

    from odmd_bench import load_split, methods
    from odmd_bench.evaluation.predictions import format_predictions, write_predictions

    to_stdout = output is not None and str(output) == "-"
    path = output if output is not None else default_output(name, benchmark, split)
    misplaced = [] if to_stdout else data_folder_problems({"-o": path}, data_dir)
    if misplaced:
        raise UsageError("refusing to write the predictions", misplaced)
    method = methods.load(name)
    options = given_options(method, **method_values)

    from odmd_bench.predict.checks import method_warnings, scale_warnings
    from odmd_bench.predict.report import report_line

    sets = load_split(split, benchmark, data_dir)
    depths: dict[str, np.ndarray] = {}
    reports: dict[str, dict[str, int | str]] = {}
    warnings: list[str] = []
    for set_name, examples in sets.items():
        checked = scale_warnings([examples], "examples") + method_warnings(
            method, examples.without_truth(), options
        )
        warnings += [f"{set_name}: {w}" for w in checked]
        depths[set_name], reports[set_name] = method.run(examples, **options)

    uncertainty = None
    said_interval = ""
    if interval is not None:
        from odmd_bench.predict.intervals import calibrate_method, method_spread

        calibration = calibrate_method(method, options, benchmark, interval, data_dir)
        uncertainty = {
            s: calibration.intervals(depths[s], method_spread(method, ex, options), key=s)
            for s, ex in sets.items()
        }
        said_interval = calibration.describe()
        if split == "val":
            warnings.append("the intervals are calibrated on the very val sets they are for (in-sample)")
    if to_stdout:
        click.echo(
            format_predictions(split, depths, benchmark=benchmark, uncertainty=uncertainty, level=interval),
            nl=False,
        )
    else:
        write_predictions(path, split, depths, benchmark=benchmark, uncertainty=uncertainty, level=interval)

    def say(line: str) -> None:
        click.echo(line, err=to_stdout)

    if said_interval:
        say(said_interval)

    n = sum(len(v) for v in depths.values())
    where = "standard output" if to_stdout else str(path)
    say(f"{name} on {benchmark} {split}: wrote {n} predictions ({', '.join(depths)}) to {where}")
    say(
        f"  command: {methods.format_command(name, options, benchmark, split, '-' if to_stdout else str(path))}"
    )
    # The report's strings (what the method says of its run) once where every set agrees.
    said = [{k: v for k, v in r.items() if isinstance(v, str)} for r in reports.values()]
    common = {k: v for k, v in said[0].items() if all(d.get(k) == v for d in said)} if said else {}
    if common:
        say("  " + "; ".join(f"{k} {v}" for k, v in common.items()))
    for set_name, report in reports.items():
        say(f"  {set_name}: {report_line(method, report, skip=common)}")
    for line in warnings:
        click.echo(f"warning: {line}", err=True)
    hint = f"odmd-bench evaluate {'-' if to_stdout else path}"
    if benchmark != DEFAULT_BENCHMARK:
        hint += f" --benchmark {benchmark}"
    if data_dir is not None:
        hint += f" --data-dir {data_dir}"
    say(f"score it with: {hint}" + (" (reading the predictions from standard input)" if to_stdout else ""))


COMMANDS: list[click.Command] = [baseline]
