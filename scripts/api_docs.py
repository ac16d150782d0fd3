"""Build the API reference from the docstrings with pdoc; any warning fails the build.

    python scripts/api_docs.py [OUT]     # default OUT: a new temporary folder

Writes ``OUT/index.html`` and one page per module of ``odmd_bench`` and
``odmd_bench_baselines`` (Google-style docstrings). Every warning pdoc gives (a type
annotation it cannot resolve, a broken cross-reference, a module that fails to import) is
printed, and the exit status is then 1. ``scripts/check.sh`` runs it, so CI builds the
reference on every change; nothing it writes is committed.
"""

from __future__ import annotations

import sys
import tempfile
import warnings
from pathlib import Path

PACKAGES = ("odmd_bench", "odmd_bench_baselines")


def modules() -> list[str]:
    """The specs that give every module of the two packages one page.

    pdoc walks a package's submodules, except those its ``__all__`` leaves out: each
    module that no spec reaches yet is added as a spec of its own (with its submodules).
    """
    import importlib
    import pkgutil

    from pdoc.extract import walk_specs

    every = []
    for top in PACKAGES:
        package = importlib.import_module(top)
        every.append(top)
        every += [i.name for i in pkgutil.walk_packages(package.__path__, prefix=top + ".")]
    every = [m for m in every if not m.endswith("__main__")]
    specs = list(PACKAGES)
    reached = set(walk_specs(specs))
    for m in every:
        if m not in reached:
            specs.append(m)
            reached.update(walk_specs([m]))
    return specs


def main(argv: list[str]) -> int:
    import pdoc
    import pdoc.render

    out = Path(argv[0]) if argv else Path(tempfile.mkdtemp(prefix="odmd-bench-api-"))
    pdoc.render.configure(docformat="google", search=True, show_source=False)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        pdoc.pdoc(*modules(), output_directory=out)
    for w in caught:
        print(f"api_docs: {w.category.__name__}: {w.message} ({w.filename}:{w.lineno})", file=sys.stderr)
    if caught:
        print(f"api_docs: FAILED: {len(caught)} warnings (above)", file=sys.stderr)
        return 1
    pages = sum(1 for _ in out.rglob("*.html"))
    print(f"API reference: {out / 'index.html'} ({pages} pages, no warnings)")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
