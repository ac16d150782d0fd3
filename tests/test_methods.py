"""Methods as plug-ins.

The entry-point registry, its errors, the options a method takes, and a third-party
method run by ``odmd-bench baseline`` without touching this package.
"""

from __future__ import annotations

import ast
import csv
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

import odmd_bench
from odmd_bench import methods
from odmd_bench.cli.main import cli
from odmd_bench.errors import UsageError

DOCS = Path(__file__).resolve().parents[1] / "docs"

THIRD_PARTY = '''
"""A method from another distribution: a constant depth, and a report."""
import numpy as np

def predict_report(examples, scale=1.0):
    n = len(examples)
    return np.full(n, 2.0 * scale), {"n": n, "guessed": n, "source": "a constant"}

def predict(examples, scale=1.0):
    return predict_report(examples, scale)[0]
'''


def plugin(root: Path, dist: str, entries: dict[str, str], modules: dict[str, str]) -> Path:
    """A distribution on ``root``: its ``*.dist-info`` with entry points, and its modules."""
    info = root / f"{dist}-1.0.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {dist}\nVersion: 1.0\n")
    lines = "".join(f"{name} = {target}\n" for name, target in entries.items())
    (info / "entry_points.txt").write_text(f"[{methods.GROUP}]\n{lines}")
    for name, code in modules.items():
        (root / f"{name}.py").write_text(textwrap.dedent(code))
    return root


@pytest.fixture
def plugins(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A folder on sys.path with third-party plug-ins, good and broken."""
    root = tmp_path / "site"
    plugin(
        root,
        "odmd_thirdparty",
        {
            "thirdparty": "odmd_thirdparty_method",
            "no-report": "odmd_thirdparty_half",
            "raises": "odmd_thirdparty_raises",
            "needs-dep": "odmd_thirdparty_needs",
            "gone": "odmd_thirdparty_not_there",
            "bad-shape": "odmd_thirdparty_bad:Bad",
            "fails": "odmd_thirdparty_fails",
            "peek": "odmd_thirdparty_peek",
            "box-ls": "odmd_thirdparty_method",  # a second box-ls: ambiguous
        },
        {
            "odmd_thirdparty_method": THIRD_PARTY,
            "odmd_thirdparty_half": "def predict(examples):\n    return examples.depth\n",
            "odmd_thirdparty_raises": "raise RuntimeError('plug-in failed at import')\n",
            "odmd_thirdparty_needs": "import no_such_dependency_of_odmd\n",
            "odmd_thirdparty_peek": """
                import numpy as np

                def predict_report(examples):
                    assert examples.observation_depth is None and examples.extras == {}
                    return examples.depth, {}

                predict = predict_report
            """,
            "odmd_thirdparty_fails": "def predict_report(examples):\n    return 1 / 0\n\npredict = predict_report\n",
            "odmd_thirdparty_bad": """
                import numpy as np

                class Bad:
                    @staticmethod
                    def predict(examples, shape=None):
                        return Bad.predict_report(examples, shape)[0]

                    @staticmethod
                    def predict_report(examples, shape=None):
                        if shape == "nan":
                            return np.full(len(examples), np.nan), {}
                        if shape == "raise":
                            raise ZeroDivisionError("the plug-in divided by zero")
                        if shape == "report":
                            return np.ones(len(examples)), {"n": "x" * 3, "bad": object()}
                        return np.ones(len(examples) + 1), {}
            """,
        },
    )
    monkeypatch.syspath_prepend(str(root))
    return root


def test_this_package_registers_its_methods_with_both_functions() -> None:
    registered = methods.names()
    assert {"box-ls", "parallax", "expansion", "dbox", "robust"} <= set(registered)
    for name in ("box-ls", "parallax", "expansion", "dbox", "robust"):
        method = methods.load(name)
        assert method.source.startswith("odmd-bench ")
        assert callable(method.predict) and callable(method.predict_report)


def test_options_reach_only_the_methods_whose_functions_take_them() -> None:
    assert methods.load("dbox").accepts("weights")
    assert methods.load("robust").accepts("mode")
    assert not methods.load("box-ls").accepts("weights")
    assert not methods.load("robust").accepts("weights")
    assert "dbox" in methods.accepting("weights") and "box-ls" not in methods.accepting("weights")
    with pytest.raises(UsageError, match=r"--mode applies to .*robust.* only, not to 'box-ls'"):
        methods.check_options(methods.load("box-ls"), {"mode": "scale"}, spell=lambda k: f"--{k}")
    with pytest.raises(UsageError, match="no registered method") as e:
        methods.check_options(methods.load("box-ls"), {"mode": "scale", "nothing_takes_this": 1})
    assert len(e.value.problems) == 2  # every refused option named at once


def test_an_unknown_method_lists_the_registered_ones() -> None:
    with pytest.raises(UsageError, match="no method 'median' is registered") as e:
        methods.load("median")
    assert "box-ls" in str(e.value) and "robust" in str(e.value) and "did you mean" not in str(e.value)
    with pytest.raises(UsageError, match="no method 'boxls' is registered; did you mean 'box-ls'?"):
        methods.load("boxls")


def test_a_third_party_method_is_found_and_run(plugins: Path) -> None:
    method = methods.load("thirdparty")
    assert method.source == "odmd_thirdparty 1.0"
    assert method.accepts("scale") and not method.accepts("weights")
    ex = odmd_bench.generate(5, rng=0)
    depths, report = method.run(ex, scale=1.5)
    np.testing.assert_array_equal(depths, np.full(5, 3.0))
    assert report == {"n": 5, "guessed": 5, "source": "a constant"}
    with pytest.raises(UsageError, match="takes no option 'weights'"):
        method.run(ex, weights="w.pt")


@pytest.mark.parametrize(
    ("name", "message"),
    [
        ("no-report", r"is not usable: it has no predict_report\(\)"),
        ("raises", r"cannot be loaded: RuntimeError: plug-in failed at import"),
        ("needs-dep", r"needs no_such_dependency_of_odmd, which is not installed"),
        ("gone", r"its module odmd_thirdparty_not_there is not installed"),
        ("box-ls", r"registered more than once"),
    ],
)
def test_a_broken_plug_in_is_a_clear_usage_error(plugins: Path, name: str, message: str) -> None:
    with pytest.raises(UsageError, match=message) as e:
        methods.load(name)
    assert name in str(e.value)


def test_a_plug_in_breaking_its_promise_is_named_as_the_culprit(plugins: Path) -> None:
    method = methods.load("bad-shape")
    assert not method.is_own and methods.load("robust").is_own
    ex = odmd_bench.generate(3, rng=0)
    with pytest.raises(
        odmd_bench.MethodError, match=r"'bad-shape' \(odmd_thirdparty_bad:Bad, from odmd_thirdparty 1.0\)"
    ):
        method.run(ex)
    with pytest.raises(odmd_bench.MethodError, match="3 non-finite depths"):
        method.run(ex, shape="nan")
    with pytest.raises(odmd_bench.MethodError, match="not depths and a report of counts: TypeError"):
        method.run(ex, shape="report")
    with pytest.raises(odmd_bench.MethodError) as e:
        method.run(ex, shape="raise")
    text = str(e.value)
    assert "failed: ZeroDivisionError: the plug-in divided by zero (raised at " in text
    assert "odmd_thirdparty_bad.py:" in text and "in predict_report)" in text
    assert text.endswith("a bug of that method, not of odmd-bench")


def test_a_method_never_sees_the_answer(plugins: Path) -> None:
    """Methods run on ``Examples.without_truth()``.

    A method that returns the true depth gets NaN, which is refused; the generator's
    extras are not passed either.
    """
    ex = odmd_bench.generate(4, perturbation="both", rng=0)
    assert ex.extras and np.isfinite(ex.depth).all() and ex.observation_depth is not None
    view = ex.without_truth()
    assert np.isnan(view.depth).all() and view.observation_depth is None and view.extras == {}
    assert view.attrs == ex.attrs
    for name in ("boxes", "detected", "camera"):  # its own read-only copies (issue 45)
        mine = getattr(view, name)
        assert np.array_equal(mine, getattr(ex, name)) and not np.shares_memory(mine, getattr(ex, name))
        assert not mine.flags.writeable
    with pytest.raises(odmd_bench.MethodError, match="returned 4 non-finite depths"):
        methods.load("peek").run(ex)
    seqs = odmd_bench.read_sequences(DOCS / "sequences-example.csv", image_size=(4032, 3024))
    with pytest.raises(odmd_bench.MethodError, match="non-finite depths"):
        odmd_bench.predict_sequences(seqs, "peek")


def test_a_failing_plug_in_is_an_error_naming_it_not_an_internal_error(
    plugins: Path, v1_data_dir: Path
) -> None:
    run = [sys.executable, "-c", "from odmd_bench.cli.main import main; main()", "baseline"]
    env = {"PYTHONPATH": str(plugins), "ODMD_BENCH_DATA": str(v1_data_dir), "PATH": ""}
    for name, expected in (
        ("bad-shape", "(odmd_thirdparty_bad:Bad, from odmd_thirdparty 1.0) returned shape (2401,)"),
        ("fails", "(odmd_thirdparty_fails, from odmd_thirdparty 1.0) failed: ZeroDivisionError: "),
    ):
        done = subprocess.run(
            [*run, name, "--split", "val", "-o", "-"], capture_output=True, text=True, env=env
        )
        assert done.returncode == 2, done.stderr
        assert "internal error" not in done.stderr and "Traceback" not in done.stderr, done.stderr
        assert f"error: method '{name}' {expected}" in done.stderr, done.stderr


def test_list_shows_each_method_with_its_options_and_the_broken_ones(plugins: Path) -> None:
    result = CliRunner().invoke(cli, ["baseline", "--list"])
    assert result.exit_code == 0, result.output
    lines = {line.split(":")[0]: line for line in result.output.splitlines()}
    assert "takes --weights" in lines["dbox"] and "takes --mode" in lines["robust"]
    assert "takes" not in lines["thirdparty"] and "from odmd_thirdparty 1.0" in lines["thirdparty"]
    assert "not usable" in lines["raises"]


def test_a_third_party_method_runs_through_the_command_line(
    plugins: Path, v1_data_dir: Path, tmp_path: Path
) -> None:
    """Installed only as a ``*.dist-info`` on PYTHONPATH: ``odmd-bench baseline`` runs it."""
    out = tmp_path / "third.csv"
    run = [sys.executable, "-c", "from odmd_bench.cli.main import main; main()", "baseline", "thirdparty"]
    env = {"PYTHONPATH": str(plugins), "ODMD_BENCH_DATA": str(v1_data_dir), "PATH": ""}
    done = subprocess.run([*run, "--split", "val", "-o", str(out)], capture_output=True, text=True, env=env)
    assert done.returncode == 0, done.stderr
    sizes = {name: len(ex) for name, ex in odmd_bench.load_split("val", "odmd-v1", v1_data_dir).items()}
    assert "  source a constant\n" in done.stdout  # the same on every set: said once
    for name, n in sizes.items():
        assert f"  {name}: fallbacks: guessed {n}\n" in done.stdout
    with open(out, newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == sum(sizes.values()) and {float(r["depth"]) for r in rows} == {2.0}
    scored = CliRunner().invoke(cli, ["evaluate", str(out), "--data-dir", str(v1_data_dir)])
    assert scored.exit_code == 0, scored.output
    refused = subprocess.run([*run, "--mode", "scale"], capture_output=True, text=True, env=env)
    assert refused.returncode == 2
    assert "--mode applies to" in refused.stderr and "not to 'thirdparty'" in refused.stderr
    assert "Traceback" not in refused.stderr


ROOT = Path(__file__).resolve().parents[1]
BASELINES = sorted((ROOT / "baselines").rglob("*.py"))


def library_names_used(source: str) -> set[str]:
    """Every ``odmd_bench`` name a module imports or reads (``odmd_bench.X``, ``from odmd_bench.a import``)."""
    used = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            used |= {a.name for a in node.names if a.name.split(".")[0] == "odmd_bench"}
        elif isinstance(node, ast.ImportFrom) and node.module and node.module.split(".")[0] == "odmd_bench":
            prefix = node.module + "." if node.module != "odmd_bench" else "odmd_bench."
            used |= {prefix + a.name for a in node.names}
        elif (
            isinstance(node, ast.Attribute)
            and isinstance(node.value, ast.Name)
            and node.value.id == "odmd_bench"
        ):
            used.add(f"odmd_bench.{node.attr}")
    return used


@pytest.mark.parametrize("path", BASELINES, ids=[p.relative_to(ROOT).as_posix() for p in BASELINES])
def test_the_baselines_use_only_the_public_api(path: Path) -> None:
    """What a method needs from the library is exported by ``odmd_bench`` (its ``__all__``).

    The baselines are written as a third-party method would be. A plug-in command may
    also use the command line's shared options (``odmd_bench.cli.options``).
    """
    from odmd_bench.cli import options

    public = {"odmd_bench"} | {f"odmd_bench.{name}" for name in odmd_bench.__all__}
    public |= {f"odmd_bench.cli.options.{name}" for name in options.__all__}
    private = library_names_used(path.read_text(encoding="utf-8")) - public
    assert not private, f"{path.name} uses what odmd_bench does not export: {sorted(private)}"


def test_the_public_api_check_sees_every_way_of_reaching_inside() -> None:
    source = "import odmd_bench, odmd_bench.data.io\nfrom odmd_bench.errors import DataError\nfrom odmd_bench import load, _x\nodmd_bench.data\n"
    assert library_names_used(source) == {
        "odmd_bench",
        "odmd_bench.data.io",
        "odmd_bench.errors.DataError",
        "odmd_bench.load",
        "odmd_bench._x",
        "odmd_bench.data",
    }
