"""The leaderboard as a static web site (``odmd-bench leaderboard site -o DIR``).

The site, every file written from the board built from the committed entries (nothing is
fetched from elsewhere)::

    index.html                 a table per board (<table data-board="BENCHMARK-SPLIT">, a
                               <tr data-method="METHOD"> per entry); sorting and filtering by
                               the URL query: ?board=...&sort=KEY&order=asc|desc&FACET=VALUE
    methods/METHOD.html        a page per method, across its boards
    reported.html              results printed in papers (never ranked)
    downloads/leaderboard.json, downloads/BOARD.csv
    downloads/BENCHMARK.croissant.json   with ``croissant``: each ranked benchmark in Croissant
    predictions/METHOD/BOARD/  each entry's predictions file
    figures/                   error against depth per entry, accuracy against speed ([plot] extra)
    assets/site.css, site.js   the templates' companions (templates: site/templates/)

Layers: :mod:`~odmd_bench.leaderboard.site.data` builds ``leaderboard.json`` from the
entries, each re-scored; :mod:`~odmd_bench.leaderboard.site.pages` renders the files
(numbers by :func:`~odmd_bench.leaderboard.render.format_number`, as ``LEADERBOARD.md``);
:mod:`~odmd_bench.leaderboard.site.figures` draws. Nothing but the CLI imports this package.
Two builds of one board give byte-identical files.
"""

from __future__ import annotations

import importlib.util
import os
import shutil
import tempfile
from pathlib import Path

from odmd_bench.errors import UsageError
from odmd_bench.leaderboard.site.data import FACETS, REFERENCE_METHOD, SiteData, facets, load_site_data
from odmd_bench.leaderboard.site.pages import EXTRA_COLUMNS, ExtraColumn, render_site

__all__ = [
    "EXTRA_COLUMNS",
    "FACETS",
    "GENERATOR_MARK",
    "REFERENCE_METHOD",
    "ExtraColumn",
    "SiteData",
    "build_site",
    "facets",
    "load_site_data",
    "render_site",
    "write_site",
]

#: How an index.html written by this package says so (a folder holding one may be replaced).
GENERATOR_MARK = b'<meta name="generator" content="odmd-bench leaderboard site">'


def build_site(
    root: str | os.PathLike[str],
    data_dir: str | os.PathLike[str] | None = None,
    original: str | os.PathLike[str] | None = None,
    *,
    figures: bool | None = None,
    source_url: str | None = None,
    n_resamples: int | None = None,
    croissant: bool = False,
) -> tuple[dict[str, bytes], list[str]]:
    """The site's files for the leaderboard folder ``root``, and what was skipped.

    Args:
        root: the leaderboard folder.
        data_dir: the data folder (default: the package's).
        original: the original release's folder, imported from where a set is missing.
        figures: draw the figures; None: where matplotlib is installed.
        source_url: where repository paths link to (see :func:`render_site`).
        n_resamples: resamples of the paired comparisons (default: the rank groups').
        croissant: also write the Croissant description of each benchmark with a ranked
            board (:mod:`odmd_bench.data.croissant`; its val and test sets are loaded, verified).

    Returns:
        ``({relative path: bytes}, [one line per thing skipped])``.
    """
    said = []
    have_plot = importlib.util.find_spec("matplotlib") is not None
    if figures is None:
        figures = have_plot
        if not have_plot:
            said.append("drew no figures: matplotlib is not installed (pip install 'odmd-bench[plot]')")
    site = load_site_data(root, data_dir, original, n_resamples=n_resamples)
    extra = _croissant_downloads(site, data_dir, original) if croissant else None
    return render_site(site, figures=figures, source_url=source_url, extra_downloads=extra), said


def _croissant_downloads(
    site: SiteData, data_dir: str | os.PathLike[str] | None, original: str | os.PathLike[str] | None
) -> dict[str, tuple[bytes, str]]:
    """``{BENCHMARK.croissant.json: (bytes, what)}`` for each benchmark with a ranked board."""
    from odmd_bench.data.croissant import SUFFIX, croissant, croissant_text
    from odmd_bench.data.registry import get_benchmark
    from odmd_bench.leaderboard.board import load_board_data

    out = {}
    for name in dict.fromkeys(b.spec.benchmark for b in site.boards if b.rows):
        bench = get_benchmark(name)
        doc, _ = croissant(bench, {s: load_board_data(name, s, data_dir, original) for s in bench.splits})
        what = f"{name} described in Croissant 1.0 (odmd-bench describe --format croissant {name})"
        out[f"{name}{SUFFIX}"] = (croissant_text(doc).encode("utf-8"), what)
    return out


def write_site(files: dict[str, bytes], out: str | os.PathLike[str]) -> None:
    """Write the site to the folder ``out``, whole or not at all.

    The files are written to a new folder beside ``out``, which then takes its place; a
    folder ``out`` that exists must be empty or hold a site this package wrote.

    Raises:
        UsageError: When ``out`` is a file, or a folder holding something else.
    """
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise UsageError(f"{out} is a file; give a folder for the site")
    if out.is_dir() and any(out.iterdir()):
        index = out / "index.html"
        if not index.is_file() or GENERATOR_MARK not in index.read_bytes()[:4096]:
            raise UsageError(
                f"{out} is not empty and holds no site written by odmd-bench; give a new or empty folder"
            )
    out.parent.mkdir(parents=True, exist_ok=True)
    staged = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    try:
        for rel, data in files.items():
            path = staged / rel
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_bytes(data)
        staged.chmod(0o755)
        old = None
        if out.exists():
            old = Path(tempfile.mkdtemp(prefix=f".{out.name}.old.", dir=out.parent))
            os.replace(out, old / "site")
        os.replace(staged, out)
        if old is not None:
            shutil.rmtree(old)
    except BaseException:
        shutil.rmtree(staged, ignore_errors=True)
        raise
