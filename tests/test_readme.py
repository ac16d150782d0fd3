"""README.md's Python quick start, run as a user runs it, printing what its comments say."""

from __future__ import annotations

import contextlib
import io
import re
from pathlib import Path

import pytest

README = Path(__file__).resolve().parents[1] / "README.md"


def _python_quick_start() -> str:
    text = README.read_text(encoding="utf-8")
    section = text[text.index("## Python quick start") :]
    start = section.index("```python\n") + len("```python\n")
    return section[start : section.index("\n```", start)]


def test_the_python_quick_start_prints_what_its_comments_say(
    v1_data_dir: Path, monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    code = _python_quick_start()
    promised = [m.group(1).split(" (")[0] for m in re.finditer(r"^print\(.*\)\s+# (.+)$", code, re.M)]
    assert promised == ["All 3.00", "B better"]
    monkeypatch.setenv("ODMD_BENCH_DATA", str(v1_data_dir))
    monkeypatch.chdir(tmp_path)  # it writes mine.csv
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(compile(code, str(README), "exec"), {"__name__": "readme"})
    assert out.getvalue().splitlines() == promised
    assert (tmp_path / "mine.csv").is_file()


REPO = README.parent


def _command(label: str) -> str:
    """The one-line bash command after the README's bold ``label`` (``Run it``, ``Test it``)."""
    text = README.read_text(encoding="utf-8")
    section = text[text.index(f"**{label}**") :]
    start = section.index("```bash\n") + len("```bash\n")
    (line,) = section[start : section.index("\n```", start)].splitlines()
    return line


def test_the_run_command_installs_no_torch() -> None:
    """First contact needs neither torch nor an extra: generate, Box_LS and evaluate run without."""
    steps = [s.strip() for s in _command("Run it").split("&&")]
    assert "torch" not in _command("Run it")
    assert steps[:3] == ["python3 -m venv .venv", ". .venv/bin/activate", "pip install -e ."]
    assert [s.split()[1] for s in steps[3:]] == ["generate", "baseline", "evaluate"]


def test_the_test_command_is_what_ci_runs_and_pins_torch_first() -> None:
    steps = [s.strip() for s in _command("Test it").split("&&")]
    assert steps == [
        "python3 -m venv .venv",
        ". .venv/bin/activate",
        "pip install torch==2.13.0",
        'pip install -e ".[dev]"',
        "bash scripts/check.sh",
    ]
    ci = [
        line.replace("python -m pip install -q ", "pip install ")
        for line in (REPO / ".ci" / "run").read_text(encoding="utf-8").splitlines()
        if line and not line.startswith("#")
    ]
    done = [s for s in steps if s in ci]
    assert done == steps, f"not in .ci/run: {[s for s in steps if s not in done]}"
    assert (
        ci.index("pip install torch==2.13.0")
        < ci.index('pip install -e ".[dev]"')
        < ci.index("bash scripts/check.sh")
    )
    development = (REPO / "docs" / "development.md").read_text(encoding="utf-8")
    assert f"```bash\n{_command('Test it')}\n```" in development


def test_every_torch_install_in_the_readme_is_the_pinned_cpu_build() -> None:
    text = README.read_text(encoding="utf-8")
    for extra in ("dbox", "all"):
        assert f'`pip install torch==2.13.0 && pip install ".[{extra}]"`' in text
    assert set(re.findall(r"pip install torch[\w=.]*", text)) == {"pip install torch==2.13.0"}
