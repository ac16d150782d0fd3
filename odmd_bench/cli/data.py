"""``generate``, ``import``, ``info`` and ``describe``."""

from __future__ import annotations

import json
from pathlib import Path

import click

from odmd_bench.cli.options import FINITE_FLOAT, data_dir_option, data_dir_or_out_option
from odmd_bench.data.registry import BENCHMARKS, SPLITS, resolve_data_dir
from odmd_bench.errors import UsageError

__all__ = ["COMMANDS"]


@click.command()
@click.option(
    "--benchmark",
    default="odmd-v1",
    show_default=True,
    type=click.Choice([b for b, v in BENCHMARKS.items() if v.generated]),
    help="Generated benchmark to write.",
)
@click.option("--split", type=click.Choice(SPLITS), default=None, help="Only this split (default: both).")
@data_dir_or_out_option
@click.option("--force", is_flag=True, help="Regenerate even files that are already right.")
def generate(benchmark: str, split: str | None, data_dir: Path | None, force: bool) -> None:
    """Write the val and test files of a generated benchmark, verified against splits/.

    A file that is missing, damaged, altered or stale is rebuilt (and the reason
    printed); a right one is reused.
    """
    from odmd_bench.data.store import ensure_generated

    splits = [split] if split else list(SPLITS)
    result = ensure_generated(
        benchmark, splits, data_dir, force=force, progress=lambda m: click.echo(m, err=True)
    )
    for s, info in result.items():
        state = "reused" if info["reused"] else "rebuilt" if info["replaced"] else "written"
        sets = ", ".join(f"{k} {v[:12]}" for k, v in info["sets"].items())
        click.echo(f"{benchmark} {s}: {info['path']} ({state}; verified: {sets})")


@click.command(name="import")
@click.argument("source", type=click.Path(path_type=Path))
@click.argument("kitti_paths", nargs=-1, type=click.Path(path_type=Path), metavar="[KITTI_PATHS]...")
@click.option(
    "--benchmark",
    type=click.Choice([b for b, v in BENCHMARKS.items() if not v.generated]),
    default=None,
    help="Import only the files of this benchmark (default: every known file found).",
)
@data_dir_option
@click.option(
    "--allow-unknown",
    is_flag=True,
    help="Also import files whose SHA-256 is not one of the pinned originals (not comparable with the paper).",
)
@click.option(
    "--output",
    type=click.Path(file_okay=False, path_type=Path),
    default=None,
    help="kitti-tracking: write OUTPUT/val.h5 and OUTPUT/test.h5, also when they are not the "
    "pinned sets (one's own poses); without it they must be the pinned sets and go to the data folder.",
)
@click.option(
    "--image-size",
    type=(FINITE_FLOAT, FINITE_FLOAT),
    default=None,
    metavar="WIDTH HEIGHT",
    help="kitti-tracking with KITTI's calib/NNNN.txt, which gives no image size: the images' size in pixels.",
)
def import_(
    source: Path,
    kitti_paths: tuple[Path, ...],
    benchmark: str | None,
    data_dir: Path | None,
    allow_unknown: bool,
    output: Path | None,
    image_size: tuple[float, float] | None,
) -> None:
    """Convert original ODMD / ODMS-detection .pk files (a file or a folder) into HDF5.

    Sets already in the data folder are kept when they pass every check; a damaged
    one (or an unreadable file) is replaced, and a warning says which.

    `odmd-bench import kitti-tracking KITTI_DIR` (a folder with label_02/, poses/ and
    calib/) or `odmd-bench import kitti-tracking LABEL_DIR POSE_DIR CALIB_DIR` makes the
    kitti-tracking val and test sets from KITTI tracking labels, camera poses (KITTI
    odometry format) and intrinsics, by the rules of docs/kitti.md.
    """
    if str(source) == "kitti-tracking":
        if benchmark is not None or allow_unknown:
            raise UsageError("--benchmark and --allow-unknown are for the original release's .pk files")
        if image_size is not None and not all(v > 0 for v in image_size):
            raise UsageError(
                f"--image-size: WIDTH and HEIGHT must be positive numbers of pixels; got {image_size[0]:g} "
                f"{image_size[1]:g}"
            )
        if len(kitti_paths) not in (1, 3):
            raise UsageError(
                "odmd-bench import kitti-tracking takes one folder (with label_02/, poses/, calib/) "
                f"or three (LABEL_DIR POSE_DIR CALIB_DIR); got {len(kitti_paths)}"
            )
        from odmd_bench.kitti.sets import import_kitti

        done = import_kitti(
            *kitti_paths,
            data_dir=data_dir,
            output=output,
            image_size=image_size,
            progress=lambda m: click.echo(f"warning: {m}", err=True),
        )
        for split, info in done.items():
            hashes = ", ".join(f"{k} {v[:12]}" for k, v in info["sets"].items())
            kept = ", ".join(f"{k} {v}" for k, v in info["counts"].items())
            state = "the pinned sets" if info["pinned"] else "NOT the pinned sets"
            click.echo(f"kitti-tracking {split}: {info['path']} ({state}; {hashes}); windows: {kept}")
        return
    if kitti_paths or output is not None or image_size is not None:
        raise UsageError(
            "more than one path, --output and --image-size are for `odmd-bench import kitti-tracking`"
        )
    from odmd_bench.data.importer import import_release
    from odmd_bench.data.registry import get_benchmark, set_file

    written = import_release(
        source,
        data_dir,
        benchmark=benchmark,
        allow_unknown=allow_unknown,
        progress=lambda m: click.echo(f"warning: {m}", err=True),
    )
    for (bench, split), sets in written.items():
        click.echo(f"{bench} {split}: {set_file(get_benchmark(bench), split, data_dir)} ({', '.join(sets)})")


@click.command()
@click.argument("file", type=click.Path(path_type=Path))
@click.option("--json", "as_json", is_flag=True, help="Print the summary as JSON.")
@click.option(
    "--stats",
    is_flag=True,
    help="Also read every set (verified against its hashes) and give the ranges of depth Z_n, "
    "camera travel L = |c_1 - c_n| and Z_n / L, the share of forward and of x,y camera motion, "
    "and missing detections.",
)
def info(file: Path, as_json: bool, stats: bool) -> None:
    """Show what an odmd-bench HDF5 file holds."""
    from odmd_bench.data.describe import describe, format_description
    from odmd_bench.data.io import file_summary, read_set

    summary = file_summary(file)
    if stats:
        for name, s in summary["sets"].items():
            s["stats"] = describe(read_set(file, name))
    if as_json:
        click.echo(json.dumps(summary, indent=2, default=str))
        return
    click.echo(f"{summary['path']}")
    for k, v in summary["attrs"].items():
        click.echo(f"  {k}: {v}")
    for name, s in summary["sets"].items():
        a = s["attrs"]
        click.echo(f"set {name}: {a.get('n')} examples x {a.get('n_obs')} observations")
        for k in sorted(a):
            if k not in ("n", "n_obs", "config"):
                click.echo(f"  {k}: {a[k]}")
        if "config" in a:
            click.echo(f"  config: {a['config']}")
        for arr, (dtype, shape) in s["arrays"].items():
            click.echo(f"  array {arr}: {dtype} {tuple(shape)}")
    if stats:
        for name, s in summary["sets"].items():
            for line in format_description(name, s["stats"]):
                click.echo(line)


@click.command(name="describe")
@click.argument("benchmark", type=click.Choice(list(BENCHMARKS)))
@click.option(
    "--format",
    "fmt",
    type=click.Choice(["text", "croissant"]),
    default="text",
    show_default=True,
    help="text: the ranges of every split and set (as info --stats); croissant: a Croissant 1.0 "
    "description (JSON-LD) of every split and set.",
)
@click.option(
    "-o",
    "--out",
    type=click.Path(file_okay=False, path_type=Path),
    default=None,
    help="croissant: write DIR/BENCHMARK.croissant.json and the JSON file of every set it describes "
    "(what mlcroissant loads) [default: print the description only].",
)
@data_dir_option
def describe_cmd(benchmark: str, fmt: str, out: Path | None, data_dir: Path | None) -> None:
    """Describe every split and set of BENCHMARK, each verified as it is loaded.

    \b
    odmd-bench describe odmd-v1                              ranges of depth and motion
    odmd-bench describe --format croissant odmd-v1 -o DIR   for mlcroissant (docs/data.md)

    A generated benchmark missing from the data folder is generated first; an imported
    one must have been imported (odmd-bench import).
    """
    from odmd_bench.data.registry import get_benchmark
    from odmd_bench.errors import UsageError

    b = get_benchmark(benchmark)
    if fmt == "text":
        if out is not None:
            raise UsageError("--out is for --format croissant; the text goes to standard output")
        from odmd_bench.data.describe import describe, format_description
        from odmd_bench.data.store import load_split

        for split in b.splits:
            for name, ex in load_split(split, b, data_dir).items():
                for line in format_description(f"{split} {name}", describe(ex)):
                    click.echo(line)
        return
    from odmd_bench.data.croissant import croissant_text, describe_benchmark, write_croissant

    doc, files = describe_benchmark(b, data_dir)
    if out is None:
        click.echo(croissant_text(doc), nl=False)
        return
    for path in write_croissant(out, b, doc, files):
        click.echo(str(path))


@click.command(name="data-dir")
def data_dir_cmd() -> None:
    """Print the data folder in use."""
    click.echo(str(resolve_data_dir(None)))


COMMANDS: list[click.Command] = [generate, import_, info, describe_cmd, data_dir_cmd]
