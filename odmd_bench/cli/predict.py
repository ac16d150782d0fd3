"""``predict``: depths for a user's own detections and camera motion (a sequences CSV).

The format is :mod:`odmd_bench.predict.sequences`'s; the method is any registered one
(:mod:`odmd_bench.methods`), run by :mod:`odmd_bench.predict`.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from odmd_bench.cli.options import (
    FINITE_FLOAT,
    FiniteFloatRange,
    MethodCommand,
    data_dir_option,
    given_options,
    same_file,
)
from odmd_bench.errors import UsageError

if TYPE_CHECKING:
    from odmd_bench.predict import Missing
    from odmd_bench.predict.convention import Order, Orientation


def default_output(source: str, method: str) -> Path:
    """``<input name>-<method>.csv`` in the current folder (``depths-<method>.csv`` for stdin)."""
    stem = "depths" if source == "-" else Path(source).name.removesuffix(".gz").removesuffix(".csv")
    return Path(f"{stem}-{method}.csv")


def error_summary(truth: Any, depth: Any) -> str:
    """The error table of ``evaluate`` for the sequences whose true depth is known."""
    import numpy as np

    from odmd_bench.evaluation.metrics import STATS, set_metrics

    known = np.isfinite(truth) & np.isfinite(depth)
    m = set_metrics(truth[known], depth[known])
    rows = {
        "percent error (%)": [f"{m['percent_error'][s]:.2f}" for s in STATS],
        "absolute error (m)": [f"{m['absolute_error'][s]:.4f}" for s in STATS],
    }
    # Each column as wide as its widest cell and at least 9, so that large errors
    # never run into each other.
    widths = [max(8, len(s), *(len(r[k]) for r in rows.values())) + 1 for k, s in enumerate(STATS)]
    lines = [
        f"error against the true depths given ({m['n']} of {len(truth)} sequences"
        + (
            f"; {int((np.isfinite(truth) & ~known).sum())} with a truth were given no depth):"
            if (np.isfinite(truth) & ~known).any()
            else "):"
        ),
        f"{'':20}" + "".join(f"{s:>{w}}" for s, w in zip(STATS, widths, strict=True)),
        *(
            f"{name:20}" + "".join(f"{c:>{w}}" for c, w in zip(cells, widths, strict=True))
            for name, cells in rows.items()
        ),
    ]
    return "\n".join(lines)


@click.command(cls=MethodCommand, method_param="method_name")
@click.argument("sequences", metavar="SEQUENCES.csv")
@click.option(
    "--method",
    "method_name",
    required=True,
    help="Registered method (odmd-bench baseline --list); the options it declares follow "
    "(odmd-bench predict --method NAME --help lists them).",
)
@click.option(
    "--image-size",
    nargs=2,
    type=FiniteFloatRange(min=0, min_open=True),
    required=True,
    metavar="W H",
    help="Width and height in pixels of the images the boxes are in.",
)
@click.option(
    "--intrinsics",
    nargs=4,
    type=FINITE_FLOAT,
    default=None,
    metavar="FX FY CX CY",
    help="Camera intrinsics in pixels (same pixel frame as the boxes), for the calibrated methods "
    "(see odmd-bench baseline --list).",
)
@click.option(
    "--normalized-boxes",
    is_flag=True,
    default=False,
    help="The boxes are fractions of the image (0 to 1), not pixels: multiplied by W and H.",
)
@click.option(
    "--orientation",
    type=click.Choice(["camera-to-world", "world-to-camera"]),
    default="camera-to-world",
    show_default=True,
    help="What the quaternions cam_qx..cam_qw rotate: camera coordinates into the fixed frame "
    "(the format's), or the inverse.",
)
@click.option(
    "--quaternion-order",
    type=click.Choice(["xyzw", "wxyz"]),
    default="xyzw",
    show_default=True,
    help="The order of the quaternion's components in the columns cam_qx, cam_qy, cam_qz, cam_qw: "
    "x, y, z, w (the format's, TUM's) or w, x, y, z (Eigen's).",
)
@click.option(
    "--missing",
    type=click.Choice(["omit", "fill"]),
    default=None,
    help="Missed detections: omit (the default: each method gets the detected observations only, "
    "the depth carried to the last) or fill (the paper's rule, each method's own: the box of the "
    "nearest detection; the default and the only choice for a method built for a fixed number of "
    "observations, DBox).",
)
@click.option(
    "-o",
    "--output",
    default=None,
    help="Depths CSV to write; '-' for standard output (default: SEQUENCES-METHOD.csv here).",
)
@click.option(
    "--interval",
    type=FiniteFloatRange(0, 1, min_open=True, max_open=True),
    default=None,
    metavar="LEVEL",
    help="Also write error bars (depth_lo, depth_hi, level, depth_std): a central interval of this "
    "nominal coverage, calibrated on the val sets of --calibrate-on (pooled over its sets); "
    "docs/uncertainty.md.",
)
@click.option(
    "--calibrate-on",
    default="odmd-v1",
    show_default=True,
    help="Benchmark whose val sets calibrate --interval (its data is generated or imported as for evaluate).",
)
@data_dir_option
def predict(
    sequences: str,
    method_name: str,
    image_size: tuple[float, float],
    intrinsics: tuple[float, float, float, float] | None,
    normalized_boxes: bool,
    orientation: Orientation,
    quaternion_order: Order,
    missing: Missing | None,
    output: str | None,
    interval: float | None,
    calibrate_on: str,
    data_dir: Path | None,
    **method_values: Any,  # the options the method declares (MethodCommand)
) -> None:
    """Estimate the depth at the last observation of every sequence in SEQUENCES.csv.

    One row per observation with the columns sequence, observation, x1, y1, x2, y2
    (box corners in pixels; all four empty: missed detection), cam_x, cam_y, cam_z
    (camera position in metres, camera axes, any fixed origin), an optional depth
    (the truth, metres) and the optional orientation cam_qx, cam_qy, cam_qz, cam_qw (a
    unit quaternion, camera to fixed frame; needs --intrinsics). Observations are ordered by 'observation'; the last is
    estimated. SEQUENCES.csv may be '-' (standard input). Writes sequence,depth,
    observations,detections (and true_depth,percent_error where truth is given);
    prints the error summary where truth is given. See docs/own-data.md.
    """
    import numpy as np

    from odmd_bench import methods
    from odmd_bench.outputs import atomic_write
    from odmd_bench.predict import format_depths, method_observations, predict_sequences
    from odmd_bench.predict.report import report_line
    from odmd_bench.predict.sequences import read_sequences

    target = (
        None
        if output == "-"
        else Path(output)
        if output is not None
        else default_output(sequences, method_name)
    )
    if target is not None and str(sequences) != "-" and same_file(target, Path(sequences)):
        raise UsageError(f"-o {target} is the sequences file being read; write the estimates elsewhere")
    method = methods.load(method_name)
    options = given_options(method, **method_values)

    seqs = read_sequences(
        sequences,
        image_size,
        intrinsics,
        normalized_boxes=normalized_boxes,
        orientation=orientation,
        quaternion_order=quaternion_order,
    )
    calibration = None
    if interval is not None:
        from odmd_bench.data.registry import resolve_benchmark
        from odmd_bench.predict.intervals import calibrate_method

        calibration = calibrate_method(method, options, resolve_benchmark(calibrate_on), interval, data_dir)
    result = predict_sequences(seqs, method, missing, calibration, **options)
    text = format_depths(result)
    to_stdout = output == "-"
    path = target
    if path is None:
        click.echo(text, nl=False)
    else:
        with atomic_write(path, "w") as fh:
            fh.write(text)

    def say(line: str) -> None:
        click.echo(line, err=to_stdout)

    lengths = np.unique(seqs.n_obs)
    span = str(lengths[0]) if lengths.size == 1 else f"{lengths[0]}-{lengths[-1]}"
    wanted = method_observations(method)
    chose = "" if wanted is None or wanted >= lengths.max() else f" ({wanted} chosen evenly, the last kept)"
    omitted = int((seqs.n_obs - result.observations).sum()) if wanted is None else 0
    if omitted:
        chose += f" ({omitted} missed detections omitted)"
    where = "standard output" if path is None else str(path)
    say(
        f"{result.method} on {seqs.source}: {len(seqs)} sequence{'' if len(seqs) == 1 else 's'} "
        f"of {span} observations{chose}; "
        f"depths written to {where}"
    )
    if calibration is not None:
        say(f"  error bars: {calibration.describe()}; the pooled factor applies")
    say(f"  {report_line(method, result.counts)}")
    empty = [r for r in result.reasons if r]
    if empty:
        say(f"  no depth for {len(empty)} of {len(seqs)} sequences (the reason column says why)")
    if seqs.ignored_columns:
        say(f"  ignored columns: {', '.join(seqs.ignored_columns)}")
    if seqs.oriented:
        say(
            f"  orientation: turns of up to {float(seqs.turn.max()):.3g} degrees, taken into account; "
            "depths along each sequence's last optical axis"
        )
    for line in seqs.warnings + result.warnings:
        say(f"warning: {line}")
    nonpositive = int((result.depth <= 0).sum())
    if nonpositive:
        say(
            f"warning: {nonpositive} estimated depths are zero or negative (no valid solution for those sequences)"
        )
    if (np.isfinite(result.truth) & np.isfinite(result.depth)).any():
        say(error_summary(result.truth, result.depth))


COMMANDS: list[click.Command] = [predict]
