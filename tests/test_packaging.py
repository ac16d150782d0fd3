"""Packaging: what ``pip install odmd-bench`` requires, the extras and the entry points.

Also the error a command gives when its extra is missing. The built wheel itself,
installed outside the repository with and without torch, is tested by
``scripts/check_wheel.sh``.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

import odmd_bench
from odmd_bench import extras, methods
from odmd_bench.errors import UsageError

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def project() -> dict:
    tomllib = pytest.importorskip("tomllib")  # Python 3.11+; only the tests reading pyproject need it
    with open(ROOT / "pyproject.toml", "rb") as fh:
        return tomllib.load(fh)["project"]


def names(requirements: list[str]) -> set[str]:
    return {re.match(r"[A-Za-z0-9._-]+", r).group(0).lower() for r in requirements}  # type: ignore[union-attr]


def closure(project: dict, extra: str) -> set[str]:
    """Every distribution an extra pulls, through its references to odmd-bench's own extras."""
    found: set[str] = set()
    for req in project["optional-dependencies"][extra]:
        own = re.fullmatch(r"odmd-bench\[([^\]]+)\]", req.replace(" ", ""))
        if own:
            for e in own.group(1).split(","):
                found |= closure(project, e)
        else:
            found |= names([req])
    return found


def test_the_base_install_needs_neither_torch_nor_matplotlib(project: dict) -> None:
    assert not names(project["dependencies"]) & {"torch", "matplotlib"}
    assert closure(project, "dbox") == {"torch"}
    assert closure(project, "plot") == {"matplotlib"}
    assert {"torch", "matplotlib"} <= closure(project, "all")
    assert closure(project, "all") <= closure(project, "dev")  # the tests cover every command
    assert "pytest" in closure(project, "dev")


def test_mypy_targets_the_oldest_python_supported(project: dict) -> None:
    import tomllib  # the project fixture has skipped where it is missing

    with open(ROOT / "pyproject.toml", "rb") as fh:
        mypy = tomllib.load(fh)["tool"]["mypy"]
    assert project["requires-python"] == f">={mypy['python_version']}"


def test_every_entry_point_names_a_module_with_both_functions(project: dict) -> None:
    declared = project["entry-points"][methods.GROUP]
    assert set(declared) <= set(methods.names()), (
        "the installed entry points are stale: run `pip install --no-deps -e .`"
    )
    for name, target in declared.items():
        method = methods.load(name)
        assert method.target == target
        assert method.source.startswith("odmd-bench ")


def test_every_package_folder_is_a_regular_package() -> None:
    """setup.py finds packages by their ``__init__.py``.

    A folder without one would be left out of the wheel (a namespace package is not found).
    """
    folders = {p.parent for top in ("odmd_bench", "baselines") for p in (ROOT / top).rglob("*.py")}
    assert not [str(f.relative_to(ROOT)) for f in folders if not (f / "__init__.py").is_file()]


def test_require_names_the_extra_to_install() -> None:
    with pytest.raises(
        UsageError, match=re.escape("baseline 'x' needs no_such_module_odmd, which is not")
    ) as e:
        extras.require("no_such_module_odmd.sub", "dbox", "baseline 'x'")
    assert "pip install 'odmd-bench[dbox]'" in str(e.value)
    assert extras.require("json", "plot").dumps([1]) == "[1]"


def test_require_re_raises_a_module_missing_inside_an_installed_one(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    (tmp_path / "odmd_broken_pkg.py").write_text("import no_such_dependency_of_odmd\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(ModuleNotFoundError, match="no_such_dependency_of_odmd"):
        extras.require("odmd_broken_pkg", "dbox")


def test_the_extra_of_a_module_comes_from_the_installed_metadata() -> None:
    assert extras.extra_providing("torch.nn") == "dbox"
    assert extras.extra_providing("matplotlib.figure") == "plot"
    assert extras.extra_providing("numpy") is None  # required by the base install


def test_dbox_without_torch_exits_2_naming_the_extra(v1_data_dir: Path, tmp_path: Path) -> None:
    code = "import sys; sys.modules['torch'] = None\nfrom odmd_bench.cli.main import main; main()"
    out = tmp_path / "p.csv"
    done = subprocess.run(
        [sys.executable, "-c", code, "baseline", "dbox", "--data-dir", str(v1_data_dir), "-o", str(out)],
        capture_output=True,
        text=True,
        check=False,
    )
    assert done.returncode == 2, done.stderr
    assert "pip install 'odmd-bench[dbox]'" in done.stderr
    assert "Traceback" not in done.stderr and not out.exists()


def test_citation_version_is_the_package_version() -> None:
    """CITATION.cff cites the version this checkout is."""
    text = (ROOT / "CITATION.cff").read_text(encoding="utf-8")
    versions = [
        line.split(":", 1)[1].strip().strip("\"'")
        for line in text.splitlines()
        if line.startswith("version:")
    ]
    assert versions == [odmd_bench.__version__]


def test_shell_completion_script_is_served() -> None:
    """The completion line docs/format.md gives produces a bash function (click's completion)."""
    env = {**os.environ, "_ODMD_BENCH_COMPLETE": "bash_source"}
    script = Path(sys.executable).with_name("odmd-bench")  # the installed console script
    out = subprocess.run([str(script)], env=env, capture_output=True, text=True, check=True)
    assert "_odmd_bench_completion()" in out.stdout


def test_no_module_is_shadowed_by_an_attribute_of_its_package() -> None:
    """``import odmd_bench.X as m`` gives the module X wherever X is a module (no function of that name)."""
    import importlib
    import pkgutil

    shadowed = []
    for info in pkgutil.walk_packages(odmd_bench.__path__, "odmd_bench."):
        if info.name.endswith("datasets"):
            continue  # needs torch; it exports classes of other names
        parent_name, _, child = info.name.rpartition(".")
        parent = importlib.import_module(parent_name)
        module = importlib.import_module(info.name)
        if getattr(parent, child) is not module:
            shadowed.append(info.name)
    assert not shadowed


def test_the_manifests_are_found_from_a_source_checkout_too(monkeypatch: pytest.MonkeyPatch) -> None:
    """Python started in the repository's root imports its odmd_bench/, which has no splits."""
    from importlib import resources

    from odmd_bench.data import manifests

    def missing(name: str) -> None:
        raise ModuleNotFoundError(f"No module named {name!r}", name=name)

    monkeypatch.setattr(resources, "files", missing)
    checkout = Path(manifests.__file__).resolve().parents[2] / "splits"
    if (checkout / "odmd-v1.json").is_file():  # the tests run on the source tree
        assert manifests.splits_dir() == checkout
    else:  # on the installed wheel, where a missing odmd_bench.splits is a broken install
        with pytest.raises(odmd_bench.DataError, match="are not installed; reinstall odmd-bench"):
            manifests.splits_dir()


def test_a_python_the_tests_start_imports_the_same_odmd_bench() -> None:
    """A `python -c` started from the checkout imports what the tests import.

    On the installed wheel (scripts/check_wheel.sh) it must not import the checkout's
    odmd_bench/ while the tests import the wheel's.
    """
    code = (
        "import odmd_bench, odmd_bench_baselines; print(odmd_bench.__file__, odmd_bench_baselines.__file__)"
    )
    repo = Path(__file__).resolve().parents[1]
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=repo)
    import odmd_bench_baselines

    assert done.stdout.split() == [odmd_bench.__file__, odmd_bench_baselines.__file__]
