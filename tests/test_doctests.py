"""The docstring examples of every module of ``odmd_bench`` and ``odmd_bench_baselines`` run.

Modules are found from the installed packages' folders (``baselines/`` is imported as
``odmd_bench_baselines``, ``splits/`` as ``odmd_bench.splits``), so an editable and a
wheel install are covered alike. Every ``>>>`` line of a module must be an example that
doctest finds and runs: none skipped, none hidden where doctest cannot see it. Examples
that need an optional extra skip with the module when the extra is not installed.
"""

from __future__ import annotations

import doctest
import importlib
import importlib.util
import re
from pathlib import Path

import pytest

from odmd_bench.extras import is_installed

ROOT = Path(__file__).resolve().parents[1]

#: The import packages whose modules are searched, and the repository folder of each.
PACKAGES = {"odmd_bench": "odmd_bench", "odmd_bench.splits": "splits", "odmd_bench_baselines": "baselines"}

#: Modules whose examples need an optional dependency (the module imports it).
NEEDS = {"odmd_bench.datasets": "torch"}
#: Modules whose examples read the repository's committed leaderboard, as a user in a
#: checkout does (they write nothing): run from the repository's root, not a temporary folder.
IN_CHECKOUT: set[str] = set()

_PROMPT = re.compile(r"^\s*>>>", re.MULTILINE)


def _modules(package: str, folder: Path) -> dict[str, Path]:
    """``{module name: source file}`` for the modules of ``package`` found in ``folder``."""
    found = {}
    for path in sorted(folder.rglob("*.py")):
        parts = path.relative_to(folder).with_suffix("").parts
        if parts[-1] == "__main__":  # importing it would run the command line
            continue
        parts = parts[:-1] if parts[-1] == "__init__" else parts
        found[".".join((package, *parts))] = path
    return found


def _installed(package: str) -> Path:
    spec = importlib.util.find_spec(package)
    assert spec is not None and spec.origin is not None, f"{package} is not installed"
    return Path(spec.origin).parent


def _with_examples(modules: dict[str, Path]) -> list[str]:
    return sorted(name for name, path in modules.items() if _PROMPT.search(path.read_text("utf-8")))


MODULE_FILES = {k: v for p in PACKAGES for k, v in _modules(p, _installed(p)).items()}
WITH_EXAMPLES = _with_examples(MODULE_FILES)


def test_every_module_with_examples_is_run() -> None:
    """The modules run below are exactly those of the repository's folders with a ``>>>``."""
    in_repo = {k: v for p, folder in PACKAGES.items() for k, v in _modules(p, ROOT / folder).items()}
    assert len(WITH_EXAMPLES) >= 10  # the package documents its API with examples
    assert _with_examples(in_repo) == WITH_EXAMPLES


@pytest.mark.parametrize("name", WITH_EXAMPLES)
def test_doctests(name: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    needs = NEEDS.get(name)
    if needs is not None and not is_installed(needs):
        pytest.skip(f"{name}'s examples need {needs}, which is not installed")
    # Examples make their own temporary data folders; should one forget, it writes here.
    monkeypatch.setenv("ODMD_BENCH_DATA", str(tmp_path / "data"))
    monkeypatch.chdir(ROOT if name in IN_CHECKOUT else tmp_path)
    module = importlib.import_module(name)
    tests = doctest.DocTestFinder(exclude_empty=True).find(module)
    examples = [ex for t in tests for ex in t.examples]

    source = MODULE_FILES[name].read_text("utf-8")
    assert len(examples) == len(_PROMPT.findall(source)), "a >>> line that doctest does not run"
    assert not [ex.source for ex in examples if ex.options.get(doctest.SKIP)], "skipped examples"

    report: list[str] = []
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS)
    for test in tests:
        runner.run(test, out=report.append)
    result = runner.summarize(verbose=False)
    assert result.attempted == len(examples)
    assert result.failed == 0, "".join(report)
