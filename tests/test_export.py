"""`odmd-bench leaderboard export`: the board as Hugging Face eval results and as plain JSON, read back."""

from __future__ import annotations

import datetime
import json
import shutil
from pathlib import Path
from typing import Any

import pytest
import yaml
from click.testing import CliRunner
from conftest import two_entry_board

from odmd_bench import leaderboard as lb
from odmd_bench.cli.main import cli
from odmd_bench.leaderboard.export import HF_DATASET, HF_FILE, JSON_FILE, _slug, export_files
from odmd_bench.leaderboard.specs import rounded

FAST = 200  # rank-group resamples of the boards built here
REPO = Path(__file__).resolve().parents[1]

#: The keys of an .eval_results item (https://huggingface.co/docs/hub/eval-results).
HF_KEYS = {"dataset", "value", "verifyToken", "date", "source", "notes"}
HF_DATASET_KEYS = {"id", "task_id", "revision"}
HF_SOURCE_KEYS = {"url", "name", "user"}


@pytest.fixture(scope="module")
def board(v1_data_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A leaderboard folder: two odmd-v1 entries and the committed results reported in papers."""
    root = two_entry_board(tmp_path_factory.mktemp("export"), v1_data_dir)
    shutil.copy(REPO / "leaderboard" / lb.REPORTED, root / lb.REPORTED)
    return root


@pytest.fixture(scope="module")
def built(board: Path, v1_data_dir: Path) -> lb.Built:
    return lb.build(board, v1_data_dir, n_resamples=FAST)


def _export(
    board: Path, data_dir: Path, fmt: str, out: Path, monkeypatch: pytest.MonkeyPatch, *extra: str
) -> Any:
    monkeypatch.setattr("odmd_bench.leaderboard.ranking.RANK_RESAMPLES", FAST)
    return CliRunner().invoke(
        cli,
        [
            "leaderboard",
            "export",
            "--format",
            fmt,
            "-o",
            str(out),
            "--root",
            str(board),
            "--data-dir",
            str(data_dir),
        ]
        + list(extra),
    )


def test_json_export_reads_back_as_the_board(
    board: Path, v1_data_dir: Path, built: lb.Built, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    r = _export(board, v1_data_dir, "json", tmp_path, monkeypatch)
    assert r.exit_code == 0, r.output + r.stderr
    assert r.stdout.splitlines() == [str(tmp_path / JSON_FILE)]
    doc = json.loads((tmp_path / JSON_FILE).read_text(encoding="utf-8"))
    results = doc["results"]
    board_json = json.loads(built.json_text)  # the board in memory, as leaderboard.json would hold it
    rescored = [x for x in results if x["provenance"]["kind"] == "rescored"]
    reported = [x for x in results if x["provenance"]["kind"] == "reported"]
    rows = [(b, row) for b in board_json["boards"] for row in b["rows"]]
    assert len(rescored) == len(rows) == 2 and len(reported) == len(built.reported) > 0
    for (b, row), rec in zip(rows, rescored, strict=True):
        assert (rec["benchmark"], rec["split"], rec["method"], rec["name"]) == (
            b["benchmark"],
            b["split"],
            row["method"],
            row["name"],
        )
        assert rec["all"] == row["all"] and (rec["position"], rec["group"]) == (row["position"], row["group"])
        assert rec["sets"] == {s: v["percent_error"]["mean"] for s, v in row["sets"].items()}
        assert rec["n"] == {s: v["n"] for s, v in row["sets"].items()}
        prov = rec["provenance"]
        assert prov["predictions_sha256"] == row["predictions_csv_sha256"]
        assert prov["sets_content_sha256"] == row["metadata"]["sets_content_sha256"]
        assert prov["command"] == row["metadata"]["command"] and prov["entry"] == row["entry"]
    for rep, rec in zip(built.reported, reported, strict=True):
        assert rec["all"] == float(rep.all) and rec["sets"] == {s: float(v) for s, v in rep.sets.items()}
        assert rec["provenance"]["as_printed"] == {"all": rep.all, "sets": dict(rep.sets)}
        assert rec["provenance"]["source"] == rep.source and rec["group"] is None


def test_hf_eval_results_read_back_as_the_board(
    board: Path, v1_data_dir: Path, built: lb.Built, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    r = _export(board, v1_data_dir, "hf-eval-results", tmp_path, monkeypatch)
    assert r.exit_code == 0, r.output + r.stderr
    files = sorted(p.relative_to(tmp_path).as_posix() for p in tmp_path.rglob("*") if p.is_file())
    assert files == sorted(r.stdout.splitlines()[i].removeprefix(f"{tmp_path}/") for i in range(len(files)))
    read: dict[str, dict[str, float]] = {}
    for rel in files:
        items = yaml.safe_load((tmp_path / rel).read_text(encoding="utf-8"))
        assert isinstance(items, list) and items
        for item in items:
            assert set(item) <= HF_KEYS and {"dataset", "value"} <= set(item)
            assert set(item["dataset"]) <= HF_DATASET_KEYS and item["dataset"]["id"] == HF_DATASET
            if "source" in item:
                assert set(item["source"]) <= HF_SOURCE_KEYS and item["source"]["url"].startswith("https://")
            if "date" in item:
                datetime.date.fromisoformat(item["date"])
            assert isinstance(item["value"], float)
            read.setdefault(rel.removesuffix("/" + HF_FILE), {})[item["dataset"]["task_id"]] = item["value"]
    expected: dict[str, dict[str, float]] = {}
    for b in built.boards:
        for row in b.rows:
            mine = expected.setdefault(row.entry.method, {})
            mine[f"{b.benchmark}-{b.split}"] = rounded(row.result.all_percent_error_mean)
            for s, m in row.result.sets.items():
                mine[f"{b.benchmark}-{b.split}-{s}"] = rounded(m["percent_error"]["mean"])
    for rep in built.reported:
        mine = expected.setdefault(f"reported/{_slug(rep.method)}", {})
        mine[f"{rep.benchmark}-{rep.split}"] = float(rep.all)
        mine.update({f"{rep.benchmark}-{rep.split}-{s}": float(v) for s, v in rep.sets.items()})
    assert read == expected


def test_the_hf_dataset_id_can_be_given(built: lb.Built) -> None:
    files = export_files(built, "hf-eval-results", hf_dataset="someone/odmd")
    items = yaml.safe_load(files[f"box-ls/{HF_FILE}"])
    assert {i["dataset"]["id"] for i in items} == {"someone/odmd"}
    assert [i["dataset"]["task_id"] for i in items] == [
        "odmd-v1-test",
        "odmd-v1-test-normal",
        "odmd-v1-test-camera",
        "odmd-v1-test-object",
        "odmd-v1-test-robot",
    ]


def test_usage_errors_exit_2(
    board: Path, v1_data_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    a_file = tmp_path / "a-file"
    a_file.write_text("x")
    r = _export(board, v1_data_dir, "json", a_file, monkeypatch)
    assert r.exit_code == 2 and "is a file" in r.stderr and a_file.read_text() == "x"
    r = _export(board, v1_data_dir, "csv", tmp_path / "out", monkeypatch)
    assert r.exit_code == 2 and "hf-eval-results" in r.stderr and not (tmp_path / "out").exists()
