"""``leaderboard add`` and ``leaderboard speed``: an entry made from a method's predictions, and its speed.

Commands of the ``leaderboard`` group (:mod:`~odmd_bench.cli.leaderboard`, which adds them).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import click

from odmd_bench.cli.options import data_dir_option as _data_option
from odmd_bench.cli.options import leaderboard_root as _root
from odmd_bench.cli.options import original_option as _original_option
from odmd_bench.cli.options import root_option as _root_option
from odmd_bench.data.registry import BENCHMARKS, SPLITS
from odmd_bench.leaderboard.rules import MAX_PARAMETERS, SELECTED_ON, TRAINING_KINDS


@click.command("add")
@click.argument("predictions", type=click.Path(exists=True, dir_okay=False, path_type=Path))
@click.option("--method", required=True, help="Method id, lowercase (the entry folder's name), e.g. dbox.")
@click.option(
    "--name", required=True, help="Name shown in the table, e.g. DBox_p (one line, at most 80 characters)."
)
@click.option("--description", required=True, help="One or two sentences (at most 500 characters).")
@click.option("--paper", required=True, help="Link to the paper, or 'none'.")
@click.option("--code", required=True, help="Link to the code, or a path in this repository.")
@click.option(
    "--training-data",
    required=True,
    help="What it trained or tuned on, in words ('none' for analytical methods).",
)
@click.option(
    "--training-kind",
    required=True,
    type=click.Choice(TRAINING_KINDS),
    help="The kind of training data: none (nothing fitted to data), generator (generated examples), "
    "real (recorded data), other.",
)
@click.option(
    "--selected-on",
    required=True,
    type=click.Choice(SELECTED_ON),
    help="What the weights, hyperparameters or checkpoint were chosen on: val, test (refused: it uses the "
    "test labels) or nothing.",
)
@click.option(
    "--uses-test-labels/--no-test-labels",
    required=True,
    help="Whether the test labels were used in any way (training, tuning, selection); the board takes "
    "--no-test-labels only.",
)
@click.option(
    "--command",
    "command_",
    default=None,
    help="The exact command that produced the predictions (or give --baseline).",
)
@click.option(
    "--baseline",
    default=None,
    help="The method `odmd-bench baseline NAME` ran; the command is made from it and --option.",
)
@click.option(
    "--option",
    "option_pairs",
    multiple=True,
    metavar="NAME=VALUE",
    help="An option the predictions were made with (repeat it), recorded as the entry's options.",
)
@click.option(
    "--requirement",
    default=None,
    metavar="NAME==VERSION",
    help="A plug-in method's pinned requirement: how anyone gets it (pip install NAME==VERSION).",
)
@click.option(
    "--plugin-source",
    type=click.Path(exists=True, file_okay=False, path_type=Path),
    default=None,
    help="A plug-in method's folder of plain .py files, copied into the entry (plugin/); with --plugin-module.",
)
@click.option("--plugin-module", default=None, help="The module in --plugin-source that is the method.")
@click.option(
    "--parameters",
    type=click.IntRange(0, MAX_PARAMETERS),
    default=None,
    help="The number of trained parameters (network weights) the command runs; 0 without trained weights.",
)
@click.option(
    "--speed",
    "speed_file",
    type=click.Path(exists=True, dir_okay=False, path_type=Path),
    default=None,
    help="The JSON file `odmd-bench leaderboard speed ... -o FILE` wrote: recorded as the entry's speed.",
)
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
def add_command(
    predictions: Path,
    root: Path | None,
    command_: str | None,
    option_pairs: tuple[str, ...],
    speed_file: Path | None,
    **fields: Any,
) -> None:
    """Add the predictions CSV PREDICTIONS as an entry (validated, hashed, scored, compressed).

    The entry records the predictions' SHA-256 and their scores (which `check` compares
    with a re-scoring), the honesty fields (--uses-test-labels, --selected-on,
    --training-kind), and for a plug-in method how to get it (--requirement, or
    --plugin-source with --plugin-module). Give the command that made the predictions,
    or --baseline NAME and its --option NAME=VALUE.
    """
    from odmd_bench.leaderboard import add_entry
    from odmd_bench.leaderboard.add import parse_options
    from odmd_bench.leaderboard.speed import read_speed

    if (command_ is None) == (fields["baseline"] is None):
        raise click.UsageError(
            "give --command (the command that made the predictions) or --baseline, not both"
        )
    options = parse_options(option_pairs)
    speed = read_speed(speed_file) if speed_file is not None else None
    # The other options are add_entry's keywords, under the same names.
    entry = add_entry(
        _root(root), predictions, command=command_, options=options or None, speed=speed, **fields
    )
    click.echo(
        f"added {entry.folder}; run `odmd-bench leaderboard check`, then open a pull request with that folder"
    )


@click.command("speed")
@click.argument("name")
@click.option("--benchmark", required=True, type=click.Choice(list(BENCHMARKS)))
@click.option("--split", default="test", show_default=True, type=click.Choice(SPLITS))
@click.option(
    "--option",
    "option_pairs",
    multiple=True,
    metavar="NAME=VALUE",
    help="An option of the method, as the entry records it (repeat it).",
)
@click.option(
    "-o",
    "--output",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="Write the speed as JSON, for `leaderboard add --speed FILE`.",
)
@_data_option
@_original_option
def speed_command(
    name: str,
    benchmark: str,
    split: str,
    option_pairs: tuple[str, ...],
    output: Path | None,
    data_dir: Path | None,
    original: Path | None,
) -> None:
    """Measure the examples per second of `odmd-bench baseline NAME` as the entries' speed is measured.

    One thread (BLAS, OpenMP and torch: the command runs itself again with
    OPENBLAS_NUM_THREADS, OMP_NUM_THREADS and MKL_NUM_THREADS at 1 where they are not),
    every set of the board's split in one call each, the best of 5 rounds; the CPU model
    is recorded with the figure. Prints the entry's `speed`; -o writes it for `add --speed`.
    """
    import os
    import subprocess
    import sys

    from odmd_bench.leaderboard.add import parse_options
    from odmd_bench.leaderboard.speed import THREAD_VARIABLES, measure, one_thread, speed_text
    from odmd_bench.outputs import atomic_write

    if not one_thread():  # BLAS reads them once, at start: run again with them set
        argv = ["leaderboard", "speed", name, "--benchmark", benchmark, "--split", split]
        argv += [a for pair in option_pairs for a in ("--option", pair)]
        given = (("-o", output), ("--data-dir", data_dir), ("--original", original))
        argv += [a for flag, value in given if value is not None for a in (flag, str(value))]
        env = {**os.environ, **dict.fromkeys(THREAD_VARIABLES, "1")}
        done = subprocess.run([sys.executable, "-m", "odmd_bench", *argv], env=env, check=False)
        click.get_current_context().exit(done.returncode)
    options = parse_options(option_pairs)
    speed = measure(name, options, benchmark, split, data_dir=data_dir, original=original)
    if output is not None:
        import json

        with atomic_write(output, "w") as fh:
            fh.write(json.dumps(speed, indent=2) + "\n")
        click.echo(
            f"wrote {output}; record it with `odmd-bench leaderboard add ... --speed {output}`", err=True
        )
    click.echo(speed_text(speed), nl=False)
