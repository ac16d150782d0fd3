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
