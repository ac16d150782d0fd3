"""Methods as plug-ins.

The entry-point registry, its errors, the options a method takes, and a third-party
method run by ``odmd-bench baseline`` without touching this package.
"""

from __future__ import annotations

import ast
import csv
import re
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


DECLARED = '''
"""A method that declares its options (OPTIONS), as docs/format.md#methods shows."""
import numpy as np
from odmd_bench.methods import MethodOption

OPTIONS = (
    MethodOption("scale", float, 1.0, "Multiply the guess of 2 m by this."),
    MethodOption("shape", str, "flat", "flat: one depth; ramp: rising by example.", choices=("flat", "ramp")),
    MethodOption("repeat", int, 1, "A whole number, reported."),
    MethodOption("loud", bool, False, "A flag, reported."),
)


def predict_report(examples, scale=1.0, shape="flat", repeat=1, loud=False):
    n = len(examples)
    depths = np.full(n, 2.0 * scale) + (np.arange(n) if shape == "ramp" else 0.0)
    return depths, {"n": n, "repeat": repeat, "loud": str(loud)}


def predict(examples, **options):
    return predict_report(examples, **options)[0]
'''

BAD_DECLARATION = """
from pathlib import Path
from odmd_bench.methods import MethodOption

OPTIONS = (
    MethodOption("scale", float, 2.0, "its default is not the functions'"),
    MethodOption("gone", int, 1, "no function takes it"),
    MethodOption("kind", int, 1, "choices on a whole number", choices=("a",)),
    "not an option",
    MethodOption("when", complex, None, "an unsupported type"),
)

def predict_report(examples, scale=1.0, kind=1, when=None):
    return examples.depth, {}

predict = predict_report
"""

CLASH = """
from odmd_bench.methods import MethodOption

OPTIONS = (MethodOption("split", str, None, "the command's own option"),)

def predict_report(examples, split=None):
    return examples.depth, {}

predict = predict_report
"""


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
            "declared": "odmd_thirdparty_declared",
            "bad-options": "odmd_thirdparty_bad_options",
            "clash": "odmd_thirdparty_clash",
        },
        {
            "odmd_thirdparty_method": THIRD_PARTY,
            "odmd_thirdparty_declared": DECLARED,
            "odmd_thirdparty_bad_options": BAD_DECLARATION,
            "odmd_thirdparty_clash": CLASH,
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


@pytest.fixture
def own_methods_only(monkeypatch: pytest.MonkeyPatch) -> None:
    """Only this package's methods are registered, whatever plug-ins the environment has.

    The suite must not depend on which third-party plug-ins are installed (one named like
    ``median`` would change the "did you mean" below).
    """
    from importlib import metadata

    own = [ep for ep in metadata.distribution("odmd-bench").entry_points if ep.group == methods.GROUP]
    monkeypatch.setattr(methods, "_entry_points", lambda: own)


def test_an_unknown_method_lists_the_registered_ones(own_methods_only: None) -> None:
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
        assert f"  {name}: fallbacks: none; counted: guessed {n}\n" in done.stdout  # (no FALLBACKS declared)
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
    also use the command line's shared options (``odmd_bench.cli.options``), and a
    method declares its options with ``odmd_bench.methods`` (``MethodOption``).
    """
    from odmd_bench.cli import options

    public = {"odmd_bench"} | {f"odmd_bench.{name}" for name in odmd_bench.__all__}
    public |= {f"odmd_bench.cli.options.{name}" for name in options.__all__}
    public |= {f"odmd_bench.methods.{name}" for name in methods.__all__}
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


# ----------------------------------------------------------------------------- declared options

#: The options each shipped method declares, by their flags (what the command line took
#: before the declarations, when the options were hard-wired).
SHIPPED_OPTIONS = {
    "box-ls": [],
    "parallax": ["--combine"],
    "expansion": ["--combine"],
    "robust": ["--mode"],
    "dbox": ["--weights", "--weights-sha256", "--config", "--selection", "--device"],
    "dbox-guard": [],
}


@pytest.mark.parametrize("name", sorted(SHIPPED_OPTIONS))
def test_each_shipped_method_declares_the_options_it_takes(name: str) -> None:
    """Declared, each taken by both functions with the declared default (checked at load)."""
    method = methods.load(name)
    assert [o.flag for o in method.options] == SHIPPED_OPTIONS[name]
    assert methods.declaration_problems(method.options, (method.predict, method.predict_report)) == []
    for o in method.options:
        assert o.help and o.type in methods.OPTION_TYPES
        assert method.accepts(o.name)


def test_a_declaration_is_checked_when_the_method_is_loaded(plugins: Path) -> None:
    with pytest.raises(UsageError, match=r"method 'bad-options' .* is not usable: its OPTIONS") as e:
        methods.load("bad-options")
    problems = "\n".join(e.value.problems)
    assert "option 'scale': its default 2.0 is not predict_report()'s, 1.0" in problems
    assert "option 'gone': predict_report() does not take it" in problems
    assert "option 'kind': choices are for a str option" in problems
    assert "OPTIONS[3] is a str, not an odmd_bench.methods.MethodOption" in problems
    assert "option 'when': type <class 'complex'> is not one of" in problems
    assert len(e.value.problems) == 5  # every problem at once, each once


def test_values_are_checked_and_converted_naming_every_problem(plugins: Path) -> None:
    method = methods.load("declared")
    got = method.values({"loud": "true", "repeat": "3", "scale": "0.5", "shape": "ramp"})
    assert got == {"scale": 0.5, "shape": "ramp", "repeat": 3, "loud": True}  # declaration order
    assert list(got) == ["scale", "shape", "repeat", "loud"]
    assert method.values({"scale": 2, "loud": False}) == {"scale": 2.0, "loud": False}
    with pytest.raises(UsageError, match="cannot take") as e:
        method.values({"scale": "fast", "shape": "cube", "repeat": 1.5, "loud": "maybe", "mode": "x"})
    assert sorted(e.value.problems) == sorted(
        [
            "--mode: method 'declared' declares no such option (it declares: --scale, --shape, --repeat, --loud)",
            "--scale: 'fast' is not a number",
            "--shape: 'cube' is not one of flat, ramp",
            "--repeat: 1.5 is not a whole number",
            "--loud: 'maybe' is not true or false",
        ]
    )
    with pytest.raises(UsageError, match="'nan' is not a finite number"):
        method.values({"scale": "nan"})


def test_a_plug_in_takes_its_declared_options_on_the_command_line(
    plugins: Path, v1_data_dir: Path, tmp_path: Path
) -> None:
    out = tmp_path / "declared.csv"
    args = ["baseline", "declared", "--split", "val", "--data-dir", str(v1_data_dir), "-o", str(out)]
    result = CliRunner().invoke(cli, [*args, "--scale", "1.5", "--repeat", "4", "--loud", "true"])
    assert result.exit_code == 0, result.output
    with open(out, newline="") as fh:
        assert {float(r["depth"]) for r in csv.DictReader(fh)} == {3.0}
    assert (
        "  loud True\n" in result.output and "  normal: fallbacks: none; counted: repeat 4\n" in result.output
    )  # (no FALLBACKS declared)
    command = f"odmd-bench baseline declared --scale 1.5 --repeat 4 --loud true --benchmark odmd-v1 --split val -o {out}"
    assert f"  command: {command}\n" in result.output
    assert methods.parse_command(command) == (
        "declared",
        {"scale": "1.5", "repeat": "4", "loud": "true"},
        {"--benchmark": "odmd-v1", "--split": "val", "-o": str(out)},
    )
    # the option may come before the name, as click allows for the command's own options
    again = CliRunner().invoke(cli, ["baseline", "--split", "val", "declared", "--shape=ramp", *args[4:]])
    assert again.exit_code == 0, again.output
    with open(out, newline="") as fh:
        assert len({float(r["depth"]) for r in csv.DictReader(fh)}) > 1


@pytest.mark.parametrize(
    ("given", "message"),
    [
        (["--scale", "fast"], "Invalid value for '--scale': 'fast' is not a valid float"),
        (["--shape", "cube"], "Invalid value for '--shape': 'cube' is not one of 'flat', 'ramp'"),
        (["--repeat", "1.5"], "Invalid value for '--repeat': '1.5' is not a valid integer"),
        (["--mode", "scale"], "--mode applies to robust only, not to 'declared'"),
        (["--nothing-takes-this", "1"], "No such option '--nothing-takes-this'"),
    ],
)
def test_a_bad_option_value_is_a_located_usage_error(
    plugins: Path, v1_data_dir: Path, given: list[str], message: str
) -> None:
    result = CliRunner().invoke(cli, ["baseline", "declared", "--data-dir", str(v1_data_dir), *given])
    assert result.exit_code == 2 and message in result.output, result.output
    assert "Traceback" not in result.output


def test_help_and_list_show_a_methods_options(plugins: Path) -> None:
    shown = CliRunner().invoke(cli, ["baseline", "declared", "--help"], terminal_width=200)
    assert shown.exit_code == 0, shown.output
    mine = shown.output.split("Options of method declared (odmd_thirdparty 1.0):")[1]
    assert "--scale FLOAT" in mine and "Multiply the guess of 2 m by this. [default: 1.0]" in mine
    assert "--shape [flat|ramp]" in mine and "[default: flat]" in mine
    assert "--loud BOOLEAN" in mine and "[default: false]" in mine
    assert "--split" not in mine and "--split" in shown.output  # the command's own, above
    plain = CliRunner().invoke(cli, ["baseline", "--help"], terminal_width=200)
    assert (
        "odmd-bench baseline NAME --help lists them" in plain.output
        and "Options of method" not in plain.output
    )
    plain = CliRunner().invoke(cli, ["predict", "--help"], terminal_width=200)
    assert "odmd-bench predict --method NAME --help lists them" in plain.output
    robust = CliRunner().invoke(cli, ["baseline", "robust", "--help"], terminal_width=200)
    assert "--mode [full|scale]" in robust.output and "--combine" not in robust.output
    none = CliRunner().invoke(cli, ["baseline", "thirdparty", "--help"])
    assert "none (its module declares no OPTIONS)" in none.output
    listed = CliRunner().invoke(cli, ["baseline", "--list"])
    assert listed.exit_code == 0, listed.output
    block = listed.output.split("declared: ")[1].split("\n")
    assert block[0].endswith("takes --scale --shape --repeat --loud")
    assert block[1] == "    --scale FLOAT (default 1.0): Multiply the guess of 2 m by this."
    assert block[2].startswith("    --shape flat|ramp (default flat): flat: one depth")
    assert "clash: not usable" not in listed.output  # loads; only the command refuses it
    assert "bad-options: not usable: method 'bad-options'" in listed.output


def test_an_option_clashing_with_the_commands_own_is_refused(plugins: Path) -> None:
    result = CliRunner().invoke(cli, ["baseline", "clash"])
    assert result.exit_code == 2
    assert (
        "method 'clash'" in result.output
        and "declares --split, which odmd-bench baseline takes itself" in (result.output)
    )


def test_undeclared_keywords_of_a_plug_in_are_not_command_line_options(plugins: Path) -> None:
    """``thirdparty``'s ``predict`` takes ``scale``, but it declares nothing: the Python API only."""
    assert methods.load("thirdparty").accepts("scale") and methods.load("thirdparty").options == ()
    result = CliRunner().invoke(cli, ["baseline", "thirdparty", "--scale", "2"])
    assert result.exit_code == 2 and "--scale applies to declared only, not to 'thirdparty'" in result.output


def test_predict_takes_a_plug_ins_options(plugins: Path, tmp_path: Path) -> None:
    out = tmp_path / "d.csv"
    args = ["predict", str(DOCS / "sequences-example.csv"), "--image-size", "4032", "3024", "-o", str(out)]
    result = CliRunner().invoke(cli, [*args, "--method", "declared", "--scale", "2"])
    assert result.exit_code == 0, result.output
    with open(out, newline="") as fh:
        assert {float(r["depth"]) for r in csv.DictReader(fh)} == {4.0}
    bad = CliRunner().invoke(cli, [*args, "--method=declared", "--shape", "cube"])
    assert bad.exit_code == 2 and "'cube' is not one of 'flat', 'ramp'" in bad.output
    shown = CliRunner().invoke(cli, ["predict", "--method", "declared", "--help"])
    assert "Options of method declared" in shown.output and "--scale" in shown.output


def test_the_command_of_every_committed_entry_reads_back_and_is_written_the_same() -> None:
    """parse_command and format_command are inverses on what the board records."""
    import yaml

    entries = sorted((ROOT / "leaderboard" / "entries").glob("*/*/entry.yaml"))
    assert entries
    for path in entries:
        command = yaml.safe_load(path.read_text(encoding="utf-8"))["command"]
        name, options, own = methods.parse_command(command)
        method = methods.load(name)
        assert set(method.values(options)) == set(options), path  # every option declared, valid
        written = methods.format_command(
            name, options, own.get("--benchmark"), own.get("--split"), own.get("-o")
        )
        assert written == command.split(" (")[0], path


@pytest.mark.parametrize(
    ("command", "message"),
    [
        ("odmd-bench evaluate p.csv", "not `odmd-bench baseline NAME ...`"),
        ("odmd-bench baseline robust --mode", "gives --mode no value"),
        ("odmd-bench baseline robust --mode a --mode b", "gives --mode twice"),
        ("odmd-bench baseline a b", "names 2 methods"),
        ("odmd-bench baseline robust -x 1", "not --NAME: -x"),
        ("odmd-bench baseline 'robust", "cannot be read as words"),
    ],
)
def test_parse_command_says_what_is_wrong(command: str, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        methods.parse_command(command)


def test_format_command_quotes_what_a_shell_would_split() -> None:
    text = methods.format_command("mine", {"weights": Path("my weights.pt"), "loud": True, "scale": 0.1})
    assert text == "odmd-bench baseline mine --weights 'my weights.pt' --loud true --scale 0.1"
    assert methods.parse_command(text)[1] == {"weights": "my weights.pt", "loud": "true", "scale": "0.1"}


def test_the_documented_plug_in_with_options_runs_as_documented(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, v1_data_dir: Path
) -> None:
    """docs/format.md's example module of "A method's options", installed as a plug-in."""
    text = (DOCS / "format.md").read_text(encoding="utf-8").split("#### A method's options")[1]
    code = re.findall(r"```python\n(.*?)\n```", text, flags=re.S)[0]
    root = plugin(tmp_path / "site", "my_package", {"my-method": "my_method_doc"}, {"my_method_doc": code})
    monkeypatch.syspath_prepend(str(root))
    out = tmp_path / "mine.csv"
    args = ["baseline", "my-method", "--split", "val", "--data-dir", str(v1_data_dir), "-o", str(out)]
    result = CliRunner().invoke(cli, [*args, "--scale", "0.5", "--shape", "ramp"])
    assert result.exit_code == 0, result.output
    with open(out, newline="") as fh:
        depths = [float(r["depth"]) for r in csv.DictReader(fh)]
    assert depths[:3] == [0.5, 1.5, 2.5]
    shown = CliRunner().invoke(cli, ["baseline", "my-method", "--help"])
    assert "Options of method my-method" in shown.output and "--shape [flat|ramp]" in shown.output
    refused = CliRunner().invoke(cli, [*args, "--mode", "scale"])
    assert "--mode applies to robust only, not to 'my-method'" in refused.output


def test_an_unknown_method_asked_for_help_says_so_and_completion_still_works(plugins: Path) -> None:
    result = CliRunner().invoke(cli, ["baseline", "boxls", "--help"])
    assert (
        result.exit_code == 2 and "no method 'boxls' is registered; did you mean 'box-ls'?" in result.output
    )
    listed = CliRunner().invoke(cli, ["baseline", "boxls", "--list"])
    assert listed.exit_code == 0 and "declared: " in listed.output
    env = {
        "_ODMD_BENCH_COMPLETE": "bash_complete",
        "COMP_WORDS": "odmd-bench baseline boxls --",
        "COMP_CWORD": "3",
    }
    done = CliRunner().invoke(cli, [], env=env, prog_name="odmd-bench")
    assert done.exit_code == 0 and "--split" in done.output and "Traceback" not in done.output
    env["COMP_WORDS"] = "odmd-bench baseline declared --s"
    done = CliRunner().invoke(cli, [], env=env, prog_name="odmd-bench")
    assert "--scale" in done.output and "--shape" in done.output and "--split" in done.output


def test_recorded_options_are_the_entrys_or_its_commands_and_must_agree() -> None:
    command = (
        "odmd-bench baseline dbox --config p-z --selection per-set --benchmark odmd-v1 --split test -o p.csv"
    )
    assert methods.recorded_options(command) == ("dbox", {"config": "p-z", "selection": "per-set"})
    recorded = {"config": "p-z", "selection": "per-set"}
    assert methods.recorded_options(command, recorded) == ("dbox", recorded)
    with pytest.raises(ValueError, match=r"disagree on config \(options: ns, command: p-z\)"):
        methods.recorded_options(command, {"config": "ns", "selection": "per-set"})
    with pytest.raises(ValueError, match=r"disagree on device \(options: cuda, command: not given\)"):
        methods.recorded_options(command, {**recorded, "device": "cuda"})
    # YAML scalars are compared as the command writes them
    assert methods.recorded_options("odmd-bench baseline mine --loud true --n 3", {"loud": True, "n": 3})[
        1
    ] == {
        "loud": True,
        "n": 3,
    }


def test_a_declaration_against_an_array_default_is_a_problem_not_a_crash() -> None:
    def predict_report(examples: object, scale: object = np.ones(3)) -> None: ...

    option = methods.MethodOption("scale", float, 1.0, "x")
    assert methods.declaration_problems((option,), (predict_report,)) == [
        "option 'scale': its default 1.0 is not predict_report()'s, array([1., 1., 1.])"
    ]
