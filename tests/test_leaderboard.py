"""The leaderboard: metadata checks, re-scoring, rank groups, check's precise diffs, CLI."""

from __future__ import annotations

import gzip
import json
import os
import shutil
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from click.testing import CliRunner
from conftest import add_entry as _add

from odmd_bench import leaderboard as lb
from odmd_bench.cli.main import cli
from odmd_bench.errors import UsageError, ValidationError
from odmd_bench.leaderboard import ranking

#: The boards here hold the same files build after build: each parsed and resampled once (conftest).
pytestmark = pytest.mark.usefixtures("boards_ranked_once")

REPO = Path(__file__).resolve().parents[1]
FAST = 200  # resamples for boards built by the tests (the committed board uses lb.RANK_RESAMPLES)


# ----------------------------------------------------------------------------- helpers


def _predictions(data_dir: Path, tmp: Path, method: str) -> Path:
    """A predictions CSV of a real baseline on odmd-v1 test."""
    import importlib

    from odmd_bench import load_split
    from odmd_bench.evaluation.predictions import write_predictions

    module = importlib.import_module(f"odmd_bench_baselines.{method}")
    sets = load_split("test", "odmd-v1", data_dir)
    path = tmp / f"{method}.csv"
    write_predictions(path, "test", {s: module.predict(ex) for s, ex in sets.items()}, benchmark="odmd-v1")
    return path


@pytest.fixture(scope="module")
def v1_preds(v1_data_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    tmp = tmp_path_factory.mktemp("preds")
    return {m: _predictions(v1_data_dir, tmp, m) for m in ("box_ls", "expansion")}


@pytest.fixture(scope="module")
def built_board(
    v1_data_dir: Path, v1_preds: dict[str, Path], tmp_path_factory: pytest.TempPathFactory
) -> Path:
    """A built leaderboard folder with two odmd-v1 entries (made once; tests get copies)."""
    root = tmp_path_factory.mktemp("board") / "leaderboard"
    (root / lb.ENTRIES).mkdir(parents=True)
    _add(root, v1_data_dir, v1_preds["box_ls"], "box-ls")
    _add(root, v1_data_dir, v1_preds["expansion"], "expansion", calibrated=False)
    lb.write(root, lb.build(root, v1_data_dir, n_resamples=FAST), plot=False)
    return root


@pytest.fixture
def board(built_board: Path, tmp_path: Path) -> Path:
    """A fresh copy of the built leaderboard folder, free to change."""
    root = tmp_path / "leaderboard"
    shutil.copytree(built_board, root)
    return root


def _check(root: Path, data_dir: Path) -> list[str]:
    """``check`` of a board (with the tests' resamples)."""
    return lb.check(root, data_dir, n_resamples=FAST)


def _edit_meta(root: Path, entry: str, edit: Callable[[dict[str, Any]], object]) -> Path:
    """Change the metadata of ``entries/ENTRY/odmd-v1-test`` in place; returns its file."""
    path = root / lb.ENTRIES / entry / "odmd-v1-test" / "entry.yaml"
    meta = yaml.safe_load(path.read_text())
    edit(meta)
    path.write_text(yaml.safe_dump(meta, sort_keys=False))
    return path


def _rows(data: dict[str, Any]) -> list[dict[str, Any]]:
    """The rows of the one board with entries in a leaderboard.json."""
    (bd,) = [b for b in data["boards"] if b["rows"]]
    return list(bd["rows"])


def _deeper_first_row(text: str) -> str:
    """A predictions CSV with its first depth a thousandth deeper (any column order)."""
    lines = text.splitlines(keepends=True)
    col = lines[0].rstrip("\n").split(",").index("depth")
    cells = lines[1].rstrip("\n").split(",")
    cells[col] = repr(float(cells[col]) * 1.001)
    lines[1] = ",".join(cells) + "\n"
    return "".join(lines)


def _rewrite_gz(path: Path, edit: Callable[[str], str]) -> None:
    text = gzip.decompress(path.read_bytes()).decode()
    path.write_bytes(gzip.compress(edit(text).encode()))


# ----------------------------------------------------------------------------- rank groups


def test_rank_groups_ties_share_a_group_and_order_is_by_all_then_id() -> None:
    rng = np.random.default_rng(1)
    base = {"normal": rng.gamma(2.0, 2.0, 300), "robot": rng.gamma(2.0, 5.0, 300)}
    same = {s: v.copy() for s, v in base.items()}
    worse = {s: v + 5.0 for s, v in base.items()}
    ranked = lb.rank_groups({"zeta": same, "alpha": base, "bad": worse}, n_resamples=FAST)
    assert [(r.key, r.group) for r in ranked] == [("alpha", 1), ("zeta", 1), ("bad", 2)]
    assert ranked[0].versus_leader is None and ranked[0].leader == "alpha"
    assert ranked[1].leader == "alpha" and ranked[1].versus_leader is not None
    assert ranked[1].versus_leader.difference == 0.0
    # A new group's leader keeps the comparison that separated it.
    assert ranked[2].leader == "bad" and ranked[2].versus_previous is not None
    assert ranked[2].versus_previous.verdict != "not distinguishable"


def test_rank_groups_noise_level_differences_tie_and_groups_never_decrease() -> None:
    rng = np.random.default_rng(2)
    e = {"normal": rng.gamma(2.0, 2.0, 400)}
    noisy = {"normal": e["normal"] + rng.normal(0, 0.5, 400)}  # mean shift ~0, not distinguishable
    far = {"normal": e["normal"] * 3 + 10}
    far_tie = {"normal": far["normal"] + rng.normal(0, 0.5, 400)}
    ranked = lb.rank_groups({"a": e, "b": noisy, "c": far, "d": far_tie}, n_resamples=FAST)
    groups = {r.key: r.group for r in ranked}
    assert groups["a"] == groups["b"] == 1
    assert groups["c"] == groups["d"] == 2
    assert [r.group for r in ranked] == sorted(r.group for r in ranked)


def test_rank_groups_distinct_methods_get_distinct_groups() -> None:
    x = np.linspace(1, 2, 300)
    ranked = lb.rank_groups({"a": {"s": x}, "b": {"s": x + 1}, "c": {"s": x + 2}}, n_resamples=FAST)
    assert [r.group for r in ranked] == [1, 2, 3]


# ----------------------------------------------------------------------------- build and check


def test_build_then_check_passes(board: Path, v1_data_dir: Path) -> None:
    assert _check(board, v1_data_dir) == []
    data = json.loads((board / lb.JSON_FILE).read_text())
    assert [(b["benchmark"], b["split"]) for b in data["boards"]] == [
        (b.benchmark, b.split) for b in lb.BOARDS
    ]
    (bd,) = [b for b in data["boards"] if b["rows"]]
    assert bd["benchmark"] == "odmd-v1" and [r["method"] for r in bd["rows"]] == ["box-ls", "expansion"]
    assert bd["rows"][0]["group"] == 1
    md = (board / lb.MARKDOWN).read_text()
    assert "## odmd-v1 test" in md and "(generator v1 + imported robot)" in md


def _nudged(path: Path, tmp_path: Path, by: float = 1e-6) -> Path:
    """The predictions of ``path`` with its first estimate ``by`` (relative) deeper."""
    lines = path.read_text().splitlines(keepends=True)
    fields = lines[1].rstrip("\n").split(",")
    fields[3] = repr(float(fields[3]) * (1 + by))
    out = tmp_path / f"nudged-{path.name}"
    out.write_text("".join([lines[0], ",".join(fields) + "\n", *lines[2:]]))
    return out


def test_a_copy_is_refused_and_nearly_identical_predictions_share_group_1(
    board: Path, v1_data_dir: Path, v1_preds: dict[str, Path], tmp_path: Path
) -> None:
    before = sorted(board.rglob("*"))
    with pytest.raises(ValidationError) as info:
        _add(board, v1_data_dir, v1_preds["box_ls"], "a-copy")
    assert info.value.problems == [
        "its predictions are those of box-ls/odmd-v1-test on every set of odmd-v1 test; "
        "a copy is not a new result"
    ]
    assert f"{v1_preds['box_ls']} cannot be added as a-copy/odmd-v1-test" in info.value.render()
    assert sorted(board.rglob("*")) == before  # nothing written
    # Replacing an entry with its own predictions again is not a copy.
    source = board / lb.ENTRIES / "box-ls" / "odmd-v1-test"
    _add(board, v1_data_dir, v1_preds["box_ls"], "box-ls", replace=True)
    # A copy made by hand, not by add, is refused by build (and check).
    copy = board / lb.ENTRIES / "a-copy" / "odmd-v1-test"
    shutil.copytree(source, copy)
    meta = yaml.safe_load((copy / "entry.yaml").read_text())
    (copy / "entry.yaml").write_text(
        yaml.safe_dump(meta | {"method": "a-copy", "name": "Copy"}, sort_keys=False)
    )
    with pytest.raises(ValidationError) as info:
        lb.build(board, v1_data_dir, n_resamples=FAST)
    assert "a-copy/odmd-v1-test and box-ls/odmd-v1-test have the same predictions" in info.value.render()
    shutil.rmtree(board / lb.ENTRIES / "a-copy")
    # A re-run elsewhere differs in the last bits (about 1e-14 for Box_LS): still a copy.
    with pytest.raises(ValidationError, match="a copy is not a new result"):
        _add(board, v1_data_dir, _nudged(v1_preds["box_ls"], tmp_path, by=1e-12), "a-rerun")
    # Differing by a millionth on one example is a different result, sharing group 1.
    _add(board, v1_data_dir, _nudged(v1_preds["box_ls"], tmp_path), "a-near")
    built = lb.build(board, v1_data_dir, n_resamples=FAST)
    rows = next(b for b in built.boards if b.rows).rows
    assert [(r.entry.method, r.group) for r in rows] == [("box-ls", 1), ("a-near", 1), ("expansion", 2)]
    assert rows[1].leader == "box-ls" and rows[1].versus_leader is not None
    assert abs(rows[1].versus_leader.difference) < 1e-6
    assert "| 1 | [A-NEAR](entries/a-near/odmd-v1-test/) |" in built.markdown


def test_plain_csv_predictions_are_read_too(board: Path, v1_data_dir: Path) -> None:
    folder = board / lb.ENTRIES / "box-ls" / "odmd-v1-test"
    gz = folder / "predictions.csv.gz"
    (folder / "predictions.csv").write_bytes(gzip.decompress(gz.read_bytes()))
    gz.unlink()
    meta = yaml.safe_load((folder / "entry.yaml").read_text())
    (folder / "entry.yaml").unlink()
    (folder / "entry.json").write_text(json.dumps(meta | {"predictions": "predictions.csv"}))
    before = _rows(json.loads((board / lb.JSON_FILE).read_text()))[0]
    assert _check(board, v1_data_dir) == []  # the same content: the same SHA-256 and scores
    after = _rows(json.loads(lb.build(board, v1_data_dir, n_resamples=FAST).json_text))[0]
    assert after["predictions_file"] == "predictions.csv"
    assert after["predictions_csv_sha256"] == before["predictions_csv_sha256"]
    assert after["sets"] == before["sets"]


def test_rescoring_matches_the_evaluator(board: Path, v1_data_dir: Path, v1_preds: dict[str, Path]) -> None:
    from odmd_bench.evaluation.scoring import evaluate

    direct = evaluate(v1_preds["box_ls"], benchmark="odmd-v1", data_dir=v1_data_dir)
    row = _rows(json.loads((board / lb.JSON_FILE).read_text()))[0]
    assert row["all"] == pytest.approx(direct.all_percent_error_mean, abs=1e-6)
    assert row["predictions_csv_sha256"] == direct.provenance["predictions_sha256"]


def test_add_records_the_predictions_sha256_and_the_scores(board: Path, v1_data_dir: Path) -> None:
    row = _rows(json.loads((board / lb.JSON_FILE).read_text()))[0]
    meta = yaml.safe_load((board / lb.ENTRIES / "box-ls" / "odmd-v1-test" / "entry.yaml").read_text())
    assert meta["predictions_sha256"] == row["predictions_csv_sha256"]
    assert meta["scores"] == {
        **{s: m["percent_error"]["mean"] for s, m in row["sets"].items()},
        "all": row["all"],
    }
    assert list(meta["scores"]) == ["normal", "camera", "object", "robot", "all"]


def test_changing_one_recorded_score_fails_check_precisely(board: Path, v1_data_dir: Path) -> None:
    recorded: dict[str, float] = {}

    def bump(meta: dict[str, Any]) -> None:
        recorded["old"] = meta["scores"]["camera"]
        meta["scores"]["camera"] = round(recorded["old"] + 0.000001, 6)
        recorded["new"] = meta["scores"]["camera"]

    _edit_meta(board, "box-ls", bump)
    assert _check(board, v1_data_dir) == [
        f"entries/box-ls/odmd-v1-test/entry.yaml: scores.camera: recorded {recorded['new']!r}, "
        f"re-scored {recorded['old']!r}"
    ]
    report = lb.check_report(board, v1_data_dir, n_resamples=FAST)
    assert report.invalid == [] and len(report.differences) == 1  # a difference: exit 1, not 2


def test_a_recorded_score_must_be_one_of_the_boards_sets(board: Path, v1_data_dir: Path) -> None:
    _edit_meta(board, "box-ls", lambda m: m["scores"].pop("robot"))
    (problem,) = _check(board, v1_data_dir)
    assert "scores lack robot; run `odmd-bench leaderboard add` again" in problem
    _edit_meta(board, "box-ls", lambda m: m.pop("scores"))
    (problem,) = _check(board, v1_data_dir)
    assert problem.startswith(
        "entry box-ls/odmd-v1-test: metadata is incomplete or wrong: missing field 'scores'"
    )


def test_changing_one_prediction_fails_check_precisely(board: Path, v1_data_dir: Path) -> None:
    gz = board / lb.ENTRIES / "expansion" / "odmd-v1-test" / "predictions.csv.gz"

    def bump(text: str) -> str:
        lines = text.splitlines(keepends=True)
        parts = lines[1].split(",")
        parts[3] = repr(float(parts[3]) * 1.5)
        lines[1] = ",".join(parts)
        return "".join(lines)

    _rewrite_gz(gz, bump)
    problems = _check(board, v1_data_dir)
    where = "entries/expansion/odmd-v1-test/entry.yaml: "
    assert [p.split(":")[1].strip() for p in problems] == [
        "predictions_sha256",
        "scores.normal",
        "scores.all",
    ]
    assert all(p.startswith(where) for p in problems)
    assert "(a changed prediction)" in problems[0]
    assert problems[1].startswith(f"{where}scores.normal: recorded 0.0, re-scored ")


def test_predictions_for_other_data_fail(board: Path, v1_data_dir: Path) -> None:
    path = board / lb.ENTRIES / "box-ls" / "odmd-v1-test" / "entry.yaml"
    meta = yaml.safe_load(path.read_text())
    meta["sets_content_sha256"]["camera"] = "0" * 64
    path.write_text(yaml.safe_dump(meta, sort_keys=False))
    problems = _check(board, v1_data_dir)
    assert len(problems) == 1, problems  # one problem, counted once, saying whose it is
    assert problems[0].startswith("entry box-ls/odmd-v1-test: predictions are for different data: ")
    assert "odmd-v1 test camera with content SHA-256 0000000000000000..." in problems[0]


def test_invalid_predictions_fail_with_the_evaluators_message(board: Path, v1_data_dir: Path) -> None:
    gz = board / lb.ENTRIES / "box-ls" / "odmd-v1-test" / "predictions.csv.gz"
    _rewrite_gz(gz, lambda t: "".join(t.splitlines(keepends=True)[:-1]))  # drop the last row
    problems = _check(board, v1_data_dir)
    assert len(problems) == 1, problems
    assert problems[0].startswith("entry box-ls/odmd-v1-test: predictions.csv.gz fails validation: ")
    assert "of set 'robot' have no row (missing indices 2999)" in problems[0]


def test_incomplete_metadata_fails_check(board: Path, v1_data_dir: Path) -> None:
    path = board / lb.ENTRIES / "box-ls" / "odmd-v1-test" / "entry.yaml"
    meta = yaml.safe_load(path.read_text())
    del meta["training_data"]
    path.write_text(yaml.safe_dump(meta, sort_keys=False))
    problems = _check(board, v1_data_dir)
    assert len(problems) == 1, problems
    assert problems[0].startswith("entry box-ls/odmd-v1-test: metadata is incomplete or wrong: ")
    assert "missing field 'training_data'" in problems[0]


def test_the_views_are_not_checked_they_are_derived(board: Path, v1_data_dir: Path) -> None:
    """LEADERBOARD.md and leaderboard.json are build's output, not input: check never reads them."""
    (board / lb.JSON_FILE).unlink()
    (board / lb.MARKDOWN).write_text("anything\n")
    assert _check(board, v1_data_dir) == []


def test_add_refuses_an_existing_entry_and_bad_predictions(
    board: Path, v1_data_dir: Path, tmp_path: Path, v1_preds: dict[str, Path]
) -> None:
    with pytest.raises(UsageError, match="already exists"):
        _add(board, v1_data_dir, v1_preds["box_ls"], "box-ls")
    bad = tmp_path / "bad.csv"
    bad.write_text("split,set,index,depth\ntest,normal,0,1.0\n")
    with pytest.raises(ValidationError) as info:
        _add(board, v1_data_dir, bad, "newbie")
    assert not (board / lb.ENTRIES / "newbie" / "odmd-v1-test").exists()
    # named by the user's file; a missing set is not told to use --sets, which add has not
    assert info.value.message == f"{bad} cannot be added as newbie/odmd-v1-test"
    missing = [q for q in info.value.problems if "has no rows" in q]
    assert missing and all("a board needs predictions for every example" in q for q in missing)
    assert "--sets" not in info.value.render()


def test_reported_results_are_checked(tmp_path: Path) -> None:
    (tmp_path / lb.REPORTED).write_text(
        yaml.safe_dump(
            [{"method": "X", "benchmark": "odmd-paper", "split": "test", "sets": {"normal": "1"}, "all": "x"}]
        )
    )
    with pytest.raises(ValidationError) as info:
        lb.read_reported(tmp_path)
    text = info.value.render()
    assert "missing field 'source'" in text and "sets must be exactly" in text and "not a number: 'x'" in text


def test_find_root_from_a_subfolder(board: Path) -> None:
    assert lb.find_root(board / lb.ENTRIES / "box-ls") == board.resolve()
    with pytest.raises(UsageError, match="no leaderboard folder"):
        lb.find_root(board.parent.parent)


# ----------------------------------------------------------------------------- plot


def test_plot_is_written(board: Path, v1_data_dir: Path) -> None:
    pytest.importorskip("matplotlib")
    said = lb.write(board, lb.build(board, v1_data_dir, n_resamples=FAST))
    png = board / lb.PLOT
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and f"wrote {png}" in said


def test_two_entries_of_one_name_take_one_row(
    board: Path, v1_data_dir: Path, v1_preds: dict[str, Path], tmp_path: Path
) -> None:
    nudged = _nudged(v1_preds["expansion"], tmp_path)
    clash = (
        "expansion-2/odmd-v1-test: has the name 'EXPANSION' of expansion/odmd-v1-test on odmd-v1 test; "
        "rename one of them"
    )
    # add refuses the name that build would refuse, in the same words
    with pytest.raises(ValidationError) as info:
        _add(board, v1_data_dir, nudged, "expansion-2", name="EXPANSION")
    assert info.value.problems == [clash]
    assert not (board / lb.ENTRIES / "expansion-2" / "odmd-v1-test").exists()
    # given by hand, build keeps the first and names the second
    entry = _add(board, v1_data_dir, nudged, "expansion-2", name="Expansion 2").folder / "entry.yaml"
    entry.write_text(entry.read_text().replace("name: Expansion 2", "name: EXPANSION"))
    boards, problems = lb.collect(board, v1_data_dir, n_resamples=FAST)
    assert problems == [
        "expansion-2/odmd-v1-test: has the name 'EXPANSION' of expansion/odmd-v1-test on odmd-v1 test; "
        "rename one of them"
    ]
    (v1,) = [b for b in boards if b.rows]
    assert sorted(r.entry.method for r in v1.rows) == ["box-ls", "expansion"]


def test_names_cannot_make_links_or_html_in_the_table(
    board: Path, v1_data_dir: Path, v1_preds: dict[str, Path]
) -> None:
    for entry in (board / lb.ENTRIES).iterdir():
        shutil.rmtree(entry)
    _add(board, v1_data_dir, v1_preds["box_ls"], "box-ls", name="x](http://evil.example) <b>bold</b>")
    md = lb.build(board, v1_data_dir, n_resamples=FAST).markdown
    assert "[x\\](http://evil.example) &lt;b&gt;bold&lt;/b&gt;](entries/box-ls/odmd-v1-test/)" in md


def test_a_failed_write_leaves_every_file_of_the_board_as_it_was(
    board: Path, v1_data_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    pytest.importorskip("matplotlib")
    import errno

    from odmd_bench.leaderboard import plot as plot_module

    built = lb.build(board, v1_data_dir, n_resamples=FAST)
    for name in (lb.MARKDOWN, lb.JSON_FILE):
        (board / name).write_text("OLD\n")

    def full_disk(*args: object, **kwargs: object) -> None:
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(plot_module, "plot_boards", full_disk)
    with pytest.raises(OSError):
        lb.write(board, built)
    assert all((board / name).read_text() == "OLD\n" for name in (lb.MARKDOWN, lb.JSON_FILE))
    assert not [p for p in board.iterdir() if p.name.endswith(".tmp")]


def test_a_file_that_cannot_be_replaced_leaves_the_plot_as_it_was(board: Path, v1_data_dir: Path) -> None:
    """The tables, the JSON and the plot are replaced together or not at all."""
    pytest.importorskip("matplotlib")
    built = lb.build(board, v1_data_dir, n_resamples=FAST)
    (board / lb.PLOT).write_bytes(b"old plot")
    (board / lb.MARKDOWN).write_text("OLD\n")
    (board / lb.JSON_FILE).unlink()
    (board / lb.JSON_FILE).mkdir()  # a folder where the JSON belongs
    with pytest.raises(OSError, match="a folder stands where the file belongs"):
        lb.write(board, built)
    assert (board / lb.PLOT).read_bytes() == b"old plot" and (board / lb.MARKDOWN).read_text() == "OLD\n"
    assert not [p for p in (*board.iterdir(), *board.parent.iterdir()) if p.name.endswith(".tmp")]


def test_build_without_matplotlib_says_so(
    board: Path, v1_data_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    for name in [m for m in sys.modules if m == "matplotlib" or m.startswith("matplotlib.")]:
        monkeypatch.delitem(sys.modules, name)
    monkeypatch.setitem(sys.modules, "matplotlib", None)
    said = lb.write(board, lb.build(board, v1_data_dir, n_resamples=FAST))
    assert any("skipped the plot" in s and "odmd-bench[plot]" in s for s in said)
    assert not (board / lb.PLOT).exists()
    # The core install runs add, build and check: the plot is not part of any gate.
    monkeypatch.setattr(ranking, "RANK_RESAMPLES", FAST)
    common = ["--root", str(board), "--data-dir", str(v1_data_dir)]
    built = CliRunner().invoke(cli, ["leaderboard", "build", *common])
    assert built.exit_code == 0 and "skipped the plot" in built.output
    checked = CliRunner().invoke(cli, ["leaderboard", "check", *common])
    assert checked.exit_code == 0, checked.output
    assert "matplotlib" not in sys.modules or sys.modules["matplotlib"] is None


def test_a_plot_records_its_board_and_a_stale_one_is_not_left_beside_a_build_without_it(
    board: Path, v1_data_dir: Path
) -> None:
    pytest.importorskip("matplotlib")
    from odmd_bench.leaderboard.plot import plot_boards

    built = lb.build(board, v1_data_dir, n_resamples=FAST)
    lb.write(board, built)
    png = board / lb.PLOT
    assert lb.plot_source(png) == lb.board_digest((board / lb.JSON_FILE).read_text(encoding="utf-8"))
    # Built again without the plot: the plot of this board stays ...
    assert not any("removed" in line for line in lb.write(board, built, plot=False))
    assert png.is_file()
    # ... one drawn from another board is removed (it would show other numbers beside the JSON).
    plot_boards(built.boards, png, source="0" * 64)
    said = lb.write(board, built, plot=False)
    assert f"removed {png}: it was drawn from another board" in said and not png.exists()


def test_plot_source_reads_only_up_to_the_image_data(tmp_path: Path) -> None:
    import struct
    import zlib

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    head = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", bytes(13))
    key = lb.PLOT_SOURCE_KEY.encode()
    path = tmp_path / "p.png"
    path.write_bytes(head + chunk(b"tEXt", key + b"\0abc") + chunk(b"IDAT", b"") + chunk(b"IEND", b""))
    assert lb.plot_source(path) == "abc"
    # after the image data: not read; truncated or absurd chunk lengths: None
    path.write_bytes(head + chunk(b"IDAT", b"") + chunk(b"tEXt", key + b"\0abc"))
    assert lb.plot_source(path) is None
    path.write_bytes(head + struct.pack(">I", 2**31) + b"tEXt")
    assert lb.plot_source(path) is None
    path.write_bytes(head[:20])
    assert lb.plot_source(path) is None


# ----------------------------------------------------------------------------- CLI


def test_cli_check_exits_1_on_a_difference_and_2_on_a_broken_entry_with_a_line_per_board(
    board: Path, v1_data_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The gate (a recorded score or SHA-256 that differs from the re-scoring) exits 1, bad input 2."""
    monkeypatch.setattr(ranking, "RANK_RESAMPLES", FAST)
    runner = CliRunner()
    args = ["leaderboard", "check", "--root", str(board), "--data-dir", str(v1_data_dir)]
    (board / lb.JSON_FILE).unlink()  # the views are not needed (nor read)
    ok = runner.invoke(cli, args)
    assert ok.exit_code == 0, ok.output
    assert ok.stdout.startswith("leaderboard check passed: ")
    progress = [line for line in ok.stderr.splitlines() if "up to date" not in line]  # the data's log
    assert [line.split(":")[0] for line in progress] == [spec.key for spec in lb.BOARDS]
    assert "odmd-v1 test: 2 entries re-scored and ranked (" in ok.stderr
    assert "odmd-paper test: no entries" in progress
    _edit_meta(board, "box-ls", lambda m: m["scores"].update(all=m["scores"]["all"] + 1))
    bad = runner.invoke(cli, args)
    assert bad.exit_code == 1, bad.output
    assert (
        "fail: leaderboard check (" in bad.stderr
        and "1 difference between what the entries record" in bad.stderr
    )
    assert "entries/box-ls/odmd-v1-test/entry.yaml: scores.all: recorded " in bad.stderr
    assert "error:" not in bad.stderr and bad.stdout == ""
    entry = board / lb.ENTRIES / "box-ls" / "odmd-v1-test" / "entry.yaml"
    meta = yaml.safe_load(entry.read_text())
    del meta["training_data"]
    entry.write_text(yaml.safe_dump(meta, sort_keys=False))
    broken = runner.invoke(cli, args)
    assert broken.exit_code == 2, broken.output
    assert broken.stderr.splitlines()[-2].startswith("error: leaderboard check failed (")
    assert "1 problem with the entries" in broken.stderr and "missing field 'training_data'" in broken.stderr


def test_check_report_tells_invalid_entries_from_differences(board: Path, v1_data_dir: Path) -> None:
    assert lb.check_report(board, v1_data_dir, n_resamples=FAST) == lb.CheckReport([], [])
    _edit_meta(board, "expansion", lambda m: m.update(predictions_sha256="0" * 64))
    report = lb.check_report(board, v1_data_dir, n_resamples=FAST)
    assert report.invalid == [] and len(report.differences) == 1
    assert report.differences[0].startswith("entries/expansion/odmd-v1-test/entry.yaml: predictions_sha256: ")
    gz = board / lb.ENTRIES / "box-ls" / "odmd-v1-test" / "predictions.csv.gz"
    _rewrite_gz(gz, lambda t: "".join(t.splitlines(keepends=True)[:-1]))
    lines: list[str] = []
    report = lb.check_report(board, v1_data_dir, n_resamples=FAST, progress=lines.append)
    assert report.differences == [] and len(report.invalid) == 1
    assert "of set 'robot' have no row" in report.invalid[0]
    assert lines[1].startswith("odmd-v1 test: 2 entries re-scored, 1 problem (")


def test_cli_build_writes_the_files(
    board: Path, v1_data_dir: Path, monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    monkeypatch.setattr(ranking, "RANK_RESAMPLES", FAST)
    common = ["--root", str(board), "--data-dir", str(v1_data_dir), "--no-plot"]
    result = CliRunner().invoke(cli, ["leaderboard", "build", *common])
    assert result.exit_code == 0, result.output
    out = lb.build_folder(board)
    assert out == board / "build" and f"2 entries on {len(lb.BOARDS)} boards" in result.output
    assert (out / lb.MARKDOWN).is_file() and (out / lb.JSON_FILE).is_file()
    elsewhere = tmp_path / "views"
    result = CliRunner().invoke(cli, ["leaderboard", "build", "-o", str(elsewhere), *common])
    assert result.exit_code == 0, result.output
    assert (elsewhere / lb.JSON_FILE).read_text() == (out / lb.JSON_FILE).read_text()


def test_the_default_build_folder_is_ignored_by_git() -> None:
    """What build writes by default never shows up as a change to commit."""
    import subprocess

    if not (REPO / ".git").exists():
        pytest.skip("not a git checkout")
    for name in (lb.MARKDOWN, lb.JSON_FILE, lb.PLOT):
        for path in (f"leaderboard/{lb.BUILD}/{name}", f"leaderboard/{name}"):
            done = subprocess.run(["git", "check-ignore", "-q", path], cwd=REPO, check=False)
            assert done.returncode == 0, f"{path} is not ignored by git"
    tracked = subprocess.run(
        ["git", "ls-files", "leaderboard"], cwd=REPO, capture_output=True, text=True, check=True
    ).stdout.split()
    assert not [t for t in tracked if t.rsplit("/", 1)[-1] in (lb.MARKDOWN, lb.JSON_FILE, lb.PLOT)]


# ----------------------------------------------------------------------------- the committed leaderboard


@pytest.fixture(scope="module")
def both_data_dir(paper_data_dir: Path, v1_data_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    data = tmp_path_factory.mktemp("both-data")
    for bench, source in (
        ("odmd-paper", paper_data_dir),
        ("odms-detection", paper_data_dir),
        ("odmd-v1", v1_data_dir),
    ):
        if (source / bench).exists():
            (data / bench).symlink_to(source / bench)
    return data


def test_committed_leaderboard_passes_check(both_data_dir: Path) -> None:
    assert lb.check_report(REPO / "leaderboard", both_data_dir) == lb.CheckReport([], [])


def test_committed_leaderboard_reproduces_the_paper_box_ls() -> None:
    meta = yaml.safe_load(
        (REPO / "leaderboard" / lb.ENTRIES / "box-ls" / "odmd-paper-test" / "entry.yaml").read_text()
    )
    means = [round(meta["scores"][s], 2) for s in ("normal", "camera", "object", "robot")]
    assert means == [0.0, 4.47, 21.60, 21.23]


def test_a_copy_of_the_committed_leaderboard_with_one_changed_number_or_prediction_fails(
    both_data_dir: Path, tmp_path: Path
) -> None:
    root = tmp_path / "leaderboard"
    shutil.copytree(REPO / "leaderboard", root, ignore=shutil.ignore_patterns(lb.BUILD))
    # Entries name their code by repository path, resolved inside the repository: copy it.
    shutil.copytree(
        REPO / "baselines", tmp_path / "baselines", ignore=shutil.ignore_patterns("*.pt", "__pycache__")
    )
    entry = root / lb.ENTRIES / "box-ls" / "odmd-paper-test" / "entry.yaml"
    text = entry.read_text()
    assert "  all: 11.825009\n" in text  # the committed number, as a reader sees it
    entry.write_text(text.replace("  all: 11.825009\n", "  all: 11.835009\n"))
    report = lb.check_report(root, both_data_dir)
    assert report.invalid == [] and report.differences == [
        "entries/box-ls/odmd-paper-test/entry.yaml: scores.all: recorded 11.835009, re-scored 11.825009"
    ]
    entry.write_text(text)
    _rewrite_gz(
        root / lb.ENTRIES / "robust" / "odmd-paper-test" / "predictions.csv.gz",  # not audited
        _deeper_first_row,
    )
    report = lb.check_report(root, both_data_dir)
    assert report.invalid == [] and report.differences[0].startswith(
        "entries/robust/odmd-paper-test/entry.yaml: predictions_sha256: recorded "
    )


def test_cli_add_makes_an_entry_that_build_ranks(
    board: Path, v1_data_dir: Path, v1_preds: dict[str, Path], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(ranking, "RANK_RESAMPLES", FAST)
    runner = CliRunner()
    common = ["--root", str(board), "--data-dir", str(v1_data_dir)]
    nudged = _nudged(v1_preds["expansion"], board.parent)  # the expansion entry's, not a copy
    args = ["leaderboard", "add", str(nudged), "--method", "exp2", "--name", "Exp 2"]
    args += [
        "--description",
        "d",
        "--paper",
        "none",
        "--code",
        "https://example.org",
        "--training-data",
        "none",
    ]
    args += ["--training-kind", "none", "--selected-on", "nothing", "--no-test-labels"]
    args += [
        "--baseline",
        "expansion",
        "--benchmark",
        "odmd-v1",
        "--uncalibrated",
        "--parameters",
        "0",
        *common,
    ]
    added = runner.invoke(cli, args)
    assert added.exit_code == 0, added.output
    meta = yaml.safe_load((board / lb.ENTRIES / "exp2" / "odmd-v1-test" / "entry.yaml").read_text())
    assert meta["calibrated"] is False and meta["split"] == "test" and len(meta["sets_content_sha256"]) == 4
    assert (
        meta["command"] == "odmd-bench baseline expansion --benchmark odmd-v1 --split test -o predictions.csv"
    )
    assert (meta["uses_test_labels"], meta["selected_on"], meta["training_kind"]) == (
        False,
        "nothing",
        "none",
    )
    assert meta["parameters"] == 0 and "options" not in meta and "plugin" not in meta
    # an entry PR is the entry folder: check passes at once, nothing else to regenerate
    assert runner.invoke(cli, ["leaderboard", "check", *common]).exit_code == 0
    built = runner.invoke(cli, ["leaderboard", "build", "--no-plot", *common])
    assert built.exit_code == 0 and f"3 entries on {len(lb.BOARDS)} boards" in built.output
    # the honesty fields are required, and test labels are refused
    missing = runner.invoke(cli, [a for a in args if a not in ("--no-test-labels",)] + ["--replace"])
    assert missing.exit_code == 2 and "--uses-test-labels" in missing.output
    used = runner.invoke(cli, [*args, "--uses-test-labels", "--replace"])
    assert (
        used.exit_code == 2 and "the board ranks only methods that never used the test labels" in used.output
    )


# ----------------------------------------------------------------------------- boards, hardening, frame


def test_every_board_is_shown_and_an_empty_one_says_so(board: Path, v1_data_dir: Path) -> None:
    built = lb.build(board, v1_data_dir, n_resamples=FAST)
    assert [b.spec for b in built.boards] == list(lb.BOARDS)
    empty = [b for b in built.boards if not b.rows]
    assert {b.benchmark for b in empty} == {"odmd-paper", "odms-detection", "kitti-tracking"}
    text = built.markdown
    section = text[text.index("odms-detection test") :].split("#", 1)[0]
    assert (
        "\nNo entries yet. Add one with `odmd-bench leaderboard add PREDS.csv --benchmark odms-detection"
        in section
    )
    odms = next(b for b in json.loads(built.json_text)["boards"] if b["benchmark"] == "odms-detection")
    assert odms["rows"] == [] and odms["sets"] == ["normal", "perturb", "robot", "driving"]
    assert odms["data_version"] is None


def test_boards_match_the_registry() -> None:
    from odmd_bench.data.registry import BENCHMARKS

    assert [b.key for b in lb.BOARDS] == [
        "odmd-paper test",
        "odmd-v1 test",
        "odms-detection test",
        "kitti-tracking test",
    ]
    for spec in lb.BOARDS:
        assert (
            spec.sets == BENCHMARKS[spec.benchmark].sets and spec.split in BENCHMARKS[spec.benchmark].splits
        )


def test_a_copy_of_another_entrys_predictions_is_refused(board: Path, v1_data_dir: Path) -> None:
    """Equal scores would let a copy (ties broken by method id) take the original's place."""
    import shutil

    source = board / lb.ENTRIES / "box-ls" / "odmd-v1-test"
    copy = board / lb.ENTRIES / "aaa-copy" / "odmd-v1-test"
    shutil.copytree(source, copy)
    meta = yaml.safe_load((copy / "entry.yaml").read_text())
    (copy / "entry.yaml").write_text(
        yaml.safe_dump(meta | {"method": "aaa-copy", "name": "Copy", "calibrated": False}, sort_keys=False)
    )
    problems = _check(board, v1_data_dir)
    assert (
        "aaa-copy/odmd-v1-test and box-ls/odmd-v1-test have the same predictions on every set of "
        "odmd-v1 test; a copy is not a new result: remove the copy"
    ) in problems, problems
    # one changed estimate makes it a result of its own (here: a worse one, ranked below)
    _rewrite_gz(copy / "predictions.csv.gz", lambda t: t.replace("\ntest,normal,0,", "\ntest,normal,0,9", 1))
    assert not any("a copy is not a new result" in q for q in _check(board, v1_data_dir))


def test_a_link_to_another_entrys_predictions_fails_check(board: Path, v1_data_dir: Path) -> None:
    mine = board / lb.ENTRIES / "box-ls" / "odmd-v1-test" / "predictions.csv.gz"
    mine.unlink()
    mine.symlink_to(board / lb.ENTRIES / "expansion" / "odmd-v1-test" / "predictions.csv.gz")
    problems = _check(board, v1_data_dir)
    assert problems[:1] == [
        "entry box-ls/odmd-v1-test: symbolic links are not allowed: "
        "box-ls/odmd-v1-test/predictions.csv.gz is a symbolic link; an entry holds plain files "
        "(links are not followed)",
    ]


@pytest.mark.parametrize(
    ("over", "expected"),
    [
        ({"date": "2999-01-01"}, "date 2999-01-01 is in the future"),
        ({"code": "baselines/../../../../etc/passwd"}, "is a path outside the repository"),
        ({"name": "N" * 5000}, "field 'name' is 5000 characters long; at most 80"),
        ({"method": "../../escape"}, "method '../../escape' must be lowercase letters"),
    ],
)
def test_add_applies_the_same_validation_as_check(
    board: Path, v1_data_dir: Path, v1_preds: dict[str, Path], over: dict[str, Any], expected: str
) -> None:
    before = sorted(p for p in board.parent.rglob("*"))
    with pytest.raises(ValidationError) as info:
        _add(board, v1_data_dir, v1_preds["box_ls"], str(over.pop("method", "newbie")), **over)
    assert expected in info.value.render()
    assert sorted(p for p in board.parent.rglob("*")) == before  # nothing written


def test_add_names_a_linked_predictions_file_as_a_link(
    board: Path, v1_data_dir: Path, v1_preds: dict[str, Path], tmp_path: Path
) -> None:
    link = tmp_path / "link.csv"
    link.symlink_to(_nudged(v1_preds["box_ls"], tmp_path))
    with pytest.raises(ValidationError) as info:
        _add(board, v1_data_dir, link, "newbie")
    assert info.value.problems == ["the file is a symbolic link, which is not followed; give the file itself"]


def test_add_refuses_a_split_without_a_board(
    board: Path, v1_data_dir: Path, v1_preds: dict[str, Path]
) -> None:
    with pytest.raises(UsageError, match="there is no board for odmd-v1 val"):
        _add(board, v1_data_dir, v1_preds["box_ls"], "newbie", split="val")


def test_frame_holds_the_leaderboard(board: Path, v1_data_dir: Path) -> None:
    pytest.importorskip("pandas")
    df = lb.frame(board)
    rows = _rows(json.loads((board / lb.JSON_FILE).read_text()))
    assert list(df["method"]) == [r["method"] for r in rows]
    assert list(df["all"]) == [r["all"] for r in rows]
    assert list(df["camera"]) == [r["sets"]["camera"]["percent_error"]["mean"] for r in rows]
    assert list(df["group"]) == [r["group"] for r in rows] and str(df["group"].dtype) == "Int64"
    assert {"perturb", "driving"}.isdisjoint(df.columns)  # no board with entries has them
    built = lb.build(board, v1_data_dir, n_resamples=FAST)
    assert lb.frame(built).equals(df)


def test_board_data_is_rebuilt_where_stale(tmp_path: Path, original_release: Path) -> None:
    """A data folder left by an older odmd-bench (older file format) is rebuilt, not refused."""
    import h5py

    from odmd_bench.data.registry import get_benchmark, set_file
    from odmd_bench.leaderboard.board import load_board_data

    for benchmark in ("odmd-v1", "odmd-paper"):
        first = load_board_data(benchmark, "test", tmp_path, original_release)
        with h5py.File(set_file(get_benchmark(benchmark), "test", tmp_path), "r+") as f:
            f.attrs["format_version"] = 1  # what an older release wrote
        again = load_board_data(benchmark, "test", tmp_path, original_release)
        assert {s: ex.attrs["content_sha256"] for s, ex in again.items()} == {
            s: ex.attrs["content_sha256"] for s, ex in first.items()
        }


def test_a_hard_link_in_an_entry_is_refused_unread(board: Path, v1_data_dir: Path, tmp_path: Path) -> None:
    secret = tmp_path / "secret.txt"
    secret.write_text("first line of another file\n")
    meta = board / lb.ENTRIES / "box-ls" / "odmd-v1-test" / "entry.yaml"
    meta.unlink()
    os.link(secret, meta)  # not a symbolic link: a second name for the same file
    problems = _check(board, v1_data_dir)
    assert problems[:1] == [
        "entry box-ls/odmd-v1-test: only plain files are allowed: box-ls/odmd-v1-test/entry.yaml has 2 "
        "hard links; an entry holds files of its own (a hard link is another file's content under a "
        "second name): copy it instead"
    ]
    assert not any("first line" in p for p in problems)
    meta.unlink()
    os.mkfifo(meta)  # read, it would wait for a writer forever
    assert "entry.yaml is not a regular file" in _check(board, v1_data_dir)[0]


def test_check_reads_predictions_exactly_as_evaluate_does(board: Path, v1_data_dir: Path) -> None:
    """A file gzipped twice: evaluate refuses it, and so do check and add (the score would be right)."""
    import gzip

    from odmd_bench.evaluation.scoring import evaluate

    preds = board / lb.ENTRIES / "box-ls" / "odmd-v1-test" / "predictions.csv.gz"
    twice = gzip.compress(preds.read_bytes())
    with pytest.raises(ValidationError) as by_evaluate:
        evaluate(twice, benchmark="odmd-v1", data_dir=v1_data_dir)
    preds.write_bytes(twice)
    problems = _check(board, v1_data_dir)
    assert problems and problems[0].startswith(
        "entry box-ls/odmd-v1-test: predictions.csv.gz fails validation"
    )
    assert by_evaluate.value.problems[0] in problems[0]


# ----------------------------------------------------------------------------- plug-ins, options, speed


def test_add_keeps_a_plugins_plain_source_in_the_entry(
    board: Path, v1_data_dir: Path, v1_preds: dict[str, Path], tmp_path: Path
) -> None:
    source = tmp_path / "src"
    (source / "mine").mkdir(parents=True)
    (source / "mine" / "__init__.py").write_text("")
    (source / "mine" / "depth.py").write_text("def predict(examples):\n    return None\n")
    (source / "mine" / "__pycache__").mkdir()
    (source / "mine" / "__pycache__" / "depth.cpython-311.pyc").write_bytes(b"\0")  # a cache: left out
    (source / ".git").mkdir()
    (source / ".git" / "HEAD").write_text("ref")  # hidden: left out
    nudged = _nudged(v1_preds["expansion"], tmp_path)
    entry = _add(board, v1_data_dir, nudged, "mine", plugin_source=source, plugin_module="mine.depth")
    assert entry.meta.plugin == {"source": "plugin", "module": "mine.depth"}
    kept = sorted(p.relative_to(entry.folder).as_posix() for p in entry.folder.rglob("*") if p.is_file())
    assert kept == ["entry.yaml", "plugin/mine/__init__.py", "plugin/mine/depth.py", "predictions.csv.gz"]
    assert _check(board, v1_data_dir) == []
    # a link or another kind of file is refused before anything is written
    (source / "mine" / "weights.bin").write_bytes(b"\0")
    (source / "mine" / "link.py").symlink_to(source / "mine" / "depth.py")
    with pytest.raises(ValidationError) as info:
        _add(
            board, v1_data_dir, nudged, "mine", plugin_source=source, plugin_module="mine.depth", replace=True
        )
    assert info.value.problems == [
        "mine/link.py is a symbolic link; copy the file itself",
        "mine/weights.bin is not a .py file; a plug-in's source is plain Python files only",
    ]
    assert (entry.folder / "plugin" / "mine" / "depth.py").is_file()  # the entry as it was
    # the source's module must be in it
    (source / "mine" / "weights.bin").unlink()
    (source / "mine" / "link.py").unlink()
    with pytest.raises(ValidationError, match="has no module mine.other"):
        _add(
            board, v1_data_dir, nudged, "mine", plugin_source=source, plugin_module="mine.other", replace=True
        )
    # replaced by a source with fewer files: what the new source lacks goes
    (source / "mine" / "__init__.py").unlink()
    entry = _add(
        board, v1_data_dir, nudged, "mine", plugin_source=source, plugin_module="mine.depth", replace=True
    )
    assert sorted(
        p.relative_to(entry.folder / "plugin").as_posix() for p in (entry.folder / "plugin").rglob("*")
    ) == [
        "mine",
        "mine/depth.py",
    ]
    # a pinned requirement instead: the old source folder goes with the replaced entry
    entry = _add(board, v1_data_dir, nudged, "mine", requirement="mine-depth==2.0", replace=True)
    assert entry.meta.plugin == {"requirement": "mine-depth==2.0"} and not (entry.folder / "plugin").exists()
    with pytest.raises(ValidationError, match="must be pinned as NAME==VERSION"):
        _add(board, v1_data_dir, nudged, "mine", requirement="mine-depth>=2", replace=True)


def test_add_records_the_options_and_derives_the_command(
    board: Path, v1_data_dir: Path, v1_preds: dict[str, Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from odmd_bench.leaderboard.add import parse_options

    options = parse_options(["fill=all", "fallback-depth=2.5", "combine=lsq"])
    assert options == {"fill": "all", "fallback_depth": 2.5, "combine": "lsq"}
    with pytest.raises(ValidationError) as info:
        parse_options(["fill", "a=1", "a=2", "Bad=x"])
    assert info.value.problems == [
        "option 'fill' is not NAME=VALUE",
        "option 'a' is given twice",
        "options: name 'Bad' must be lowercase letters, digits and '_' (the method's keyword)",
    ]
    nudged = _nudged(v1_preds["expansion"], tmp_path)
    entry = _add(board, v1_data_dir, nudged, "exp-lsq", command=None, baseline="expansion", options=options)
    assert entry.meta.options == options
    assert entry.meta.command == (
        "odmd-bench baseline expansion --fill all --fallback-depth 2.5 --combine lsq "
        "--benchmark odmd-v1 --split test -o predictions.csv"
    )
    with pytest.raises(
        ValidationError, match="give either the command that made the predictions or the baseline"
    ):
        _add(board, v1_data_dir, nudged, "exp-2", baseline="expansion")  # and the helper's command
    monkeypatch.setattr(ranking, "RANK_RESAMPLES", FAST)
    both = CliRunner().invoke(
        cli, ["leaderboard", "add", str(nudged), "--command", "x", "--baseline", "y", "--method", "z"]
    )
    assert both.exit_code == 2


def test_speed_is_measured_on_one_thread_and_recorded_by_add(
    board: Path, v1_data_dir: Path, v1_preds: dict[str, Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from odmd_bench.leaderboard import speed

    out = tmp_path / "speed.json"
    args = ["leaderboard", "speed", "box-ls", "--benchmark", "odmd-v1", "--data-dir", str(v1_data_dir)]
    # Without the thread variables the command runs itself again with them (a child process).
    env = {k: v for k, v in os.environ.items() if k not in speed.THREAD_VARIABLES}
    done = subprocess.run(
        [sys.executable, "-m", "odmd_bench", *args, "-o", str(out)], env=env, capture_output=True, text=True
    )
    assert done.returncode == 0, done.stderr
    measured = json.loads(out.read_text())
    assert set(measured) == {"examples_per_second", "device", "command"}
    assert measured["device"] == speed.cpu_model() and measured["examples_per_second"] > 1000
    assert measured["command"] == "odmd-bench leaderboard speed box-ls --benchmark odmd-v1 --split test"
    assert f"examples_per_second: {measured['examples_per_second']}" in done.stdout
    assert speed.read_speed(out) == measured
    # add records it as the entry's speed
    entry = _add(board, v1_data_dir, v1_preds["box_ls"], "box-ls", replace=True, speed=measured, parameters=0)
    assert entry.meta.speed == measured and entry.meta.parameters == 0
    # a file that is not a speed is named as such
    out.write_text(json.dumps({"examples_per_second": -1, "device": "x"}))
    with pytest.raises(ValidationError) as info:
        speed.read_speed(out)
    assert info.value.problems == [
        "speed: missing field 'command': the command that measured it (one line, at most 500 characters)",
        "speed: examples_per_second must be a number > 0, got '-1'",
    ]
    assert [speed.rounded_rate(x) for x in (837123.4, 658.49, 12.345)] == [837000, 658, 12.3]


def test_speed_refuses_an_option_the_method_does_not_take(
    v1_data_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from odmd_bench.leaderboard import speed

    for v in speed.THREAD_VARIABLES:
        monkeypatch.setenv(v, "1")
    args = ["leaderboard", "speed", "box-ls", "--benchmark", "odmd-v1", "--option", "weights=x.pt"]
    result = CliRunner().invoke(cli, [*args, "--data-dir", str(v1_data_dir)])
    assert result.exit_code == 2 and "method 'box-ls' takes no option weights" in result.output
