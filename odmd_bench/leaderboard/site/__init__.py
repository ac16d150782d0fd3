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
entries, each re-scored; :mod:`~odmd_bench.leaderboard.site.pages` renders the pages from
the Jinja2 templates of ``site/templates/``, autoescaped (numbers by
:func:`~odmd_bench.leaderboard.render.format_number`, as ``LEADERBOARD.md``);
:mod:`~odmd_bench.leaderboard.site.downloads` makes the downloads (a CSV per board);
:mod:`~odmd_bench.leaderboard.site.figures` draws. Jinja2 is the ``[site]`` extra; without it
:func:`render_site` is a usage error naming it. Nothing but the CLI imports this package.
Two builds of one board give byte-identical files.
"""

from __future__ import annotations

import importlib.util
import json
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
    "MANIFEST",
    "REFERENCE_METHOD",
    "ExtraColumn",
    "SiteData",
    "build_site",
    "check_site_folder",
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
    made: dict[str, bytes] = {}  # a set two benchmarks hold is written out once
    for name in dict.fromkeys(b.spec.benchmark for b in site.boards if b.rows):
        bench = get_benchmark(name)
        splits = {s: load_board_data(name, s, data_dir, original) for s in bench.splits}
        doc, _ = croissant(bench, splits, made)
        what = f"{name} described in Croissant 1.0 (odmd-bench describe --format croissant {name})"
        out[f"{name}{SUFFIX}"] = (croissant_text(doc).encode("utf-8"), what)
    return out


#: The list of the files a build wrote, beside them (a later build removes only these).
MANIFEST = ".odmd-bench-site.json"


def _tree(folder: Path) -> tuple[list[str], list[str]]:
    """(files, folders) under ``folder``, relative POSIX paths; a link counts as a file."""
    files, folders = [], []
    for path in sorted(folder.rglob("*")):
        rel = path.relative_to(folder).as_posix()
        if path.is_dir() and not path.is_symlink():
            folders.append(rel)
        else:
            files.append(rel)
    return files, folders


def _written_before(out: Path, new: dict[str, bytes]) -> set[str] | None:
    """The files of ``out`` an earlier build wrote; None where ``out`` holds no site.

    Read from the manifest; a site built before the manifest (its index.html says it
    was generated here) is taken to be every file under the names the site writes at
    its top level (index.html, methods/, ...), the rest being the user's.
    """
    manifest = out / MANIFEST
    if manifest.is_file():
        try:
            listed = json.loads(manifest.read_text(encoding="utf-8"))["files"]
            if isinstance(listed, list) and all(isinstance(f, str) for f in listed):
                return set(listed)
        except (OSError, ValueError, KeyError, TypeError):
            pass
        raise UsageError(
            f"{manifest} is not a site manifest written by odmd-bench; remove it or give another folder"
        )
    index = out / "index.html"
    if not index.is_file() or GENERATOR_MARK not in index.read_bytes()[:4096]:
        return None
    tops = {rel.split("/")[0] for rel in new}
    return {rel for rel in _tree(out)[0] if rel.split("/")[0] in tops}


def check_site_folder(out: str | os.PathLike[str]) -> None:
    """Refuse ``out`` as :func:`write_site` would before it writes: a file, or a folder of other files.

    ``leaderboard site`` calls it before it scores and builds (which takes a while), and
    :func:`write_site` again before it writes.

    Raises:
        UsageError: ``out`` is a file, a non-empty folder that holds no site this package
            wrote, or a folder whose site manifest is not one.
    """
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise UsageError(f"{out} is a file; give a folder for the site")
    if out.is_dir() and any(out.iterdir()) and _written_before(out, {}) is None:
        raise _not_a_site(out)


def _not_a_site(out: Path) -> UsageError:
    return UsageError(
        f"{out} is not empty and holds no site written by odmd-bench; give a new or empty folder"
    )


def write_site(files: dict[str, bytes], out: str | os.PathLike[str]) -> list[str]:
    """Write the site to the folder ``out``, whole or not at all; keep what it did not write.

    The files are written to a new folder beside ``out``, with the list of them
    (:data:`MANIFEST`), which then takes ``out``'s place. A folder ``out`` that exists must
    be empty or hold a site this package wrote: the files of the earlier build (its
    manifest) are replaced or removed, every other file (a ``CNAME``, notes) is kept, as
    it was (hard-linked into the new folder, or copied where a link cannot be made).

    Returns:
        The files kept that a build did not write (relative paths).

    Raises:
        UsageError: When ``out`` is a file, a folder holding something else, or a folder
            holding a file of the user's where the site writes one (named; nothing is
            written).
    """
    out = Path(out)
    check_site_folder(out)
    kept: list[str] = []
    folders: list[str] = []
    if out.is_dir() and any(out.iterdir()):
        ours = _written_before(out, files)
        if ours is None:  # changed since check_site_folder
            raise _not_a_site(out)
        present, folders = _tree(out)
        folders = [rel for rel in folders if not any((out / rel).iterdir())]  # the user's empty ones
        kept = [rel for rel in present if rel not in ours and rel != MANIFEST]
        clash = [rel for rel in kept + folders if _collides(rel, files)]
        if clash:
            raise UsageError(
                f"{out} holds files that odmd-bench did not write where the site writes its own; "
                "move them, or give another folder",
                sorted(clash),
            )
    out.parent.mkdir(parents=True, exist_ok=True)
    staged = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    try:
        for rel, data in files.items():
            path = staged / rel
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_bytes(data)
        manifest = {"generator": "odmd-bench leaderboard site", "files": sorted(files)}
        (staged / MANIFEST).write_text(json.dumps(manifest, indent=1) + "\n", encoding="utf-8")
        for rel in folders:
            (staged / rel).mkdir(parents=True, exist_ok=True)
        for rel in kept:
            _keep(out / rel, staged / rel)
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
    return kept


def _collides(rel: str, files: dict[str, bytes]) -> bool:
    """Whether the user's ``rel`` stands where the site writes: the same path, above or below one."""
    parts = rel.split("/")
    above = ("/".join(parts[:i]) for i in range(1, len(parts)))
    return rel in files or any(a in files for a in above) or any(f.startswith(rel + "/") for f in files)


def _keep(source: Path, target: Path) -> None:
    """``source`` at ``target`` as it is: a link re-made, a file hard-linked (or copied)."""
    target.parent.mkdir(parents=True, exist_ok=True)
    if source.is_symlink():
        os.symlink(os.readlink(source), target)
        return
    try:
        os.link(source, target)
    except OSError:
        shutil.copy2(source, target)
