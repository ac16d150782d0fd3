"""docs/python.md: its code blocks run in order, as a user runs them, and print what their comments say."""

from __future__ import annotations

import contextlib
import io
import re
from pathlib import Path

import pytest
from conftest import boards_data

REPO = Path(__file__).resolve().parents[1]
PAGE = REPO / "docs" / "python.md"


def _blocks() -> list[str]:
    return re.findall(r"```python\n(.*?)\n```", PAGE.read_text(encoding="utf-8"), flags=re.S)


def test_the_python_page_prints_what_its_comments_say(
    v1_data_dir: Path, paper_data_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    pytest.importorskip("torch")
    pytest.importorskip("pandas")
    # every board's data: the leaderboard is built from its entries
    data = boards_data(tmp_path / "data", paper_data_dir, v1_data_dir)
    monkeypatch.setenv("ODMD_BENCH_DATA", str(data))
    monkeypatch.chdir(REPO)  # build("leaderboard"): "from the repository's root"
    code = "\n".join(_blocks())
    promised = [m.group(1).split(" (")[0] for m in re.finditer(r"^print\(.*\)\s+# (.+)$", code, re.M)]
    assert len(promised) == 10
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(compile(code, str(PAGE), "exec"), {"__name__": "python_docs"})
    assert out.getvalue().splitlines() == promised


def test_the_dataloader_workers_draw_distinct_batches() -> None:
    """What the page says of GeneratedBatches, checked on the batches themselves, not on one value."""
    torch = pytest.importorskip("torch")
    from torch.utils.data import DataLoader

    from odmd_bench.datasets import GeneratedBatches

    batches = GeneratedBatches(batch_size=8, batches_per_epoch=6, seed=1)
    two = [b["boxes"] for b in DataLoader(batches, batch_size=None, num_workers=2)]
    one = [b["boxes"] for b in DataLoader(batches, batch_size=None, num_workers=1)]
    mine = [batches.batch(k)["boxes"] for k in range(6)]
    assert all(torch.equal(a, b) and torch.equal(a, c) for a, b, c in zip(two, one, mine, strict=True))
    assert all(not torch.equal(mine[i], mine[j]) for i in range(6) for j in range(i))
    batches.set_epoch(1)
    assert not torch.equal(next(iter(DataLoader(batches, batch_size=None)))["boxes"], mine[0])
