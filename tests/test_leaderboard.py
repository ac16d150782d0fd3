"""The leaderboard: metadata checks, re-scoring, rank groups, check's precise diffs, CLI."""

from __future__ import annotations

import gzip
import json
import os
import shutil
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from click.testing import CliRunner
from conftest import add_entry as _add
from conftest import recorded_plot

from odmd_bench import leaderboard as lb
from odmd_bench.cli.main import cli
from odmd_bench.errors import UsageError, ValidationError
from odmd_bench.leaderboard import ranking

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
    """``check`` of a board built without its plot (drawing it is slow); the CLI always requires it."""
    return lb.check(root, data_dir, n_resamples=FAST, plot=False)


def _bump_camera_digit(path: Path, row_start: str) -> tuple[int, str, str]:
    """Change the last digit of the Camera cell (4th) of the first row starting with ``row_start``.

    Returns (line index, old cell, new cell).
    """
    lines = path.read_text().splitlines(keepends=True)
    i = next(k for k, line in enumerate(lines) if line.startswith(row_start))
    cells = lines[i].split(" | ")
    old = cells[3]
    cells[3] = old[:-1] + str((int(old[-1]) + 1) % 10)
    lines[i] = " | ".join(cells)
    path.write_text("".join(lines))
    return i, old, cells[3]


def _rows(data: dict[str, Any]) -> list[dict[str, Any]]:
    """The rows of the one board with entries in a leaderboard.json."""
    (bd,) = [b for b in data["boards"] if b["rows"]]
    return list(bd["rows"])


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
    assert _check(board, v1_data_dir) == [
        "leaderboard.json: boards[odmd-v1 test].rows[box-ls].predictions_file: committed "
        "'predictions.csv.gz', build writes 'predictions.csv'",
        "leaderboard.json: boards[odmd-v1 test].rows[box-ls].metadata.predictions: committed "
        "'predictions.csv.gz', build writes 'predictions.csv'",
    ]
    after = _rows(json.loads(lb.build(board, v1_data_dir, n_resamples=FAST).json_text))[0]
    assert after["predictions_csv_sha256"] == before["predictions_csv_sha256"]
    assert after["sets"] == before["sets"]


def test_rescoring_matches_the_evaluator(board: Path, v1_data_dir: Path, v1_preds: dict[str, Path]) -> None:
    from odmd_bench.evaluation.scoring import evaluate

    direct = evaluate(v1_preds["box_ls"], benchmark="odmd-v1", data_dir=v1_data_dir)
    row = _rows(json.loads((board / lb.JSON_FILE).read_text()))[0]
    assert row["all"] == pytest.approx(direct.all_percent_error_mean, abs=1e-6)
    assert row["predictions_csv_sha256"] == direct.provenance["predictions_sha256"]


def test_changing_one_digit_of_the_table_fails_check_precisely(board: Path, v1_data_dir: Path) -> None:
    md = board / lb.MARKDOWN
    i, old, new = _bump_camera_digit(md, "| 1 | [BOX-LS]")
    problems = _check(board, v1_data_dir)
    assert problems == [
        f"LEADERBOARD.md line {i + 1}: table 'odmd-v1 test', row 'BOX-LS', column 'Camera': "
        f"committed {new!r}, build writes {old!r}"
    ]


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
    joined = "\n".join(problems)
    assert (
        "leaderboard.json: boards[odmd-v1 test].rows[expansion].predictions_csv_sha256: committed" in joined
    )
    assert "rows[expansion].sets.normal.percent_error.mean: committed 0.0, build writes" in joined
    assert all(p.startswith(("leaderboard.json", "LEADERBOARD.md")) for p in problems)


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


def test_missing_generated_file_fails_check(board: Path, v1_data_dir: Path) -> None:
    (board / lb.JSON_FILE).unlink()
    assert _check(board, v1_data_dir) == ["leaderboard.json is missing; run `odmd-bench leaderboard build`"]


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


def test_a_file_that_cannot_be_replaced_leaves_the_readme_and_the_plot_as_they_were(
    board: Path, v1_data_dir: Path
) -> None:
    """The README block, the tables, the JSON and the plot are replaced together or not at all."""
    pytest.importorskip("matplotlib")
    built = lb.build(board, v1_data_dir, n_resamples=FAST)
    readme = board.parent / lb.README
    readme.write_text(f"# project\n\n{lb.README_START}\nstale\n{lb.README_END}\n")
    (board / lb.PLOT).write_bytes(b"old plot")
    (board / lb.MARKDOWN).write_text("OLD\n")
    (board / lb.JSON_FILE).unlink()
    (board / lb.JSON_FILE).mkdir()  # a folder where the JSON belongs
    with pytest.raises(OSError, match="a folder stands where the file belongs"):
        lb.write(board, built)
    assert "stale" in readme.read_text()
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


def test_check_finds_a_plot_left_from_another_board(board: Path, v1_data_dir: Path) -> None:
    pytest.importorskip("matplotlib")
    from odmd_bench.leaderboard.plot import plot_boards

    built = lb.build(board, v1_data_dir, n_resamples=FAST)
    lb.write(board, built)
    png = board / lb.PLOT
    assert lb.plot_source(png) == lb.board_digest((board / lb.JSON_FILE).read_text(encoding="utf-8"))
    assert lb.check(board, v1_data_dir, n_resamples=FAST) == []
    # Drawn from another leaderboard.json: out of date.
    plot_boards(built.boards, png, source="0" * 64)
    (problem,) = lb.check(board, v1_data_dir, n_resamples=FAST)
    assert problem.startswith("leaderboard.png was drawn from another board") and "[plot]" in problem
    # Building without the plot leaves it, and says it is stale.
    said = lb.write(board, built, plot=False)
    assert any(s.startswith("warning: leaderboard.png was drawn from another board") for s in said)
    # A plot that records nothing (drawn by hand, or by an older odmd-bench).
    plot_boards(built.boards, png)
    assert lb.plot_source(png) is None
    assert [p.split(";")[0] for p in lb.check(board, v1_data_dir, n_resamples=FAST)] == [
        "leaderboard.png does not record the board it was drawn from"
    ]
    png.write_bytes(b"not a png")
    assert len(lb.check(board, v1_data_dir, n_resamples=FAST)) == 1
    png.unlink()
    os.mkfifo(png)  # read, it would wait for a writer forever
    (problem,) = lb.check(board, v1_data_dir, n_resamples=FAST)
    assert problem.startswith("leaderboard.png is not a regular file")
    # No plot is a problem (the board is its tables, its JSON and its plot), unless not asked for.
    png.unlink()
    (problem,) = lb.check(board, v1_data_dir, n_resamples=FAST)
    assert problem.startswith("leaderboard.png is missing; run `odmd-bench leaderboard build`")
    assert lb.check(board, v1_data_dir, n_resamples=FAST, plot=False) == []
    assert any(
        s.startswith("warning: leaderboard.png is missing") for s in lb.write(board, built, plot=False)
    )
    lb.write(board, built)
    assert lb.check(board, v1_data_dir, n_resamples=FAST) == []


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
    """The gate (a committed table that differs from a fresh build) exits 1, bad input 2."""
    monkeypatch.setattr(ranking, "RANK_RESAMPLES", FAST)
    runner = CliRunner()
    args = ["leaderboard", "check", "--root", str(board), "--data-dir", str(v1_data_dir)]
    # The fixture built with FAST resamples, and the CLI's default is patched to match.
    missing = runner.invoke(cli, args)  # the fixture draws no plot: the CLI requires one
    assert missing.exit_code == 1 and "leaderboard.png is missing" in missing.output
    recorded_plot(board)
    ok = runner.invoke(cli, args)
    assert ok.exit_code == 0, ok.output
    assert ok.stdout.startswith("leaderboard check passed: ")
    progress = [line for line in ok.stderr.splitlines() if "up to date" not in line]  # the data's log
    assert [line.split(":")[0] for line in progress] == [spec.key for spec in lb.BOARDS]
    assert "odmd-v1 test: 2 entries re-scored and ranked (" in ok.stderr
    assert "odmd-paper test: no entries" in progress
    md = board / lb.MARKDOWN
    md.write_text(md.read_text().replace("| 1 | [BOX-LS]", "| 2 | [BOX-LS]"))
    bad = runner.invoke(cli, args)
    assert bad.exit_code == 1, bad.output
    assert "fail: leaderboard check (" in bad.stderr and "1 difference from what build writes" in bad.stderr
    assert "row 'BOX-LS', column 'Group': committed '2', build writes '1'" in bad.stderr
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
    # the fixture draws no plot (plot=False: not required here)
    assert lb.check_report(board, v1_data_dir, n_resamples=FAST, plot=False) == lb.CheckReport([], [])
    (board / lb.JSON_FILE).unlink()
    report = lb.check_report(board, v1_data_dir, n_resamples=FAST, plot=False)
    assert report.invalid == [] and report.differences == [
        "leaderboard.json is missing; run `odmd-bench leaderboard build`"
    ]
    gz = board / lb.ENTRIES / "box-ls" / "odmd-v1-test" / "predictions.csv.gz"
    _rewrite_gz(gz, lambda t: "".join(t.splitlines(keepends=True)[:-1]))
    lines: list[str] = []
    report = lb.check_report(board, v1_data_dir, n_resamples=FAST, progress=lines.append)
    assert report.differences == [] and len(report.invalid) == 1
    assert "of set 'robot' have no row" in report.invalid[0]
    assert lines[1].startswith("odmd-v1 test: 2 entries re-scored, 1 problem (")


def test_cli_build_writes_the_files(board: Path, v1_data_dir: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(ranking, "RANK_RESAMPLES", FAST)
    (board / lb.MARKDOWN).unlink()
    result = CliRunner().invoke(
        cli, ["leaderboard", "build", "--root", str(board), "--data-dir", str(v1_data_dir), "--no-plot"]
    )
    assert result.exit_code == 0, result.output
    assert f"2 entries on {len(lb.BOARDS)} boards" in result.output and (board / lb.MARKDOWN).is_file()


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


def test_committed_leaderboard_is_what_build_writes(both_data_dir: Path) -> None:
    assert lb.check(REPO / "leaderboard", both_data_dir) == []


def test_committed_leaderboard_reproduces_the_paper_box_ls() -> None:
    data = json.loads((REPO / "leaderboard" / lb.JSON_FILE).read_text())
    paper = next(b for b in data["boards"] if b["benchmark"] == "odmd-paper")
    box = next(r for r in paper["rows"] if r["method"] == "box-ls")
    means = [
        round(box["sets"][s]["percent_error"]["mean"], 2) for s in ("normal", "camera", "object", "robot")
    ]
    assert means == [0.0, 4.47, 21.60, 21.23]


def test_a_copy_of_the_committed_leaderboard_with_one_changed_digit_fails(
    both_data_dir: Path, tmp_path: Path
) -> None:
    root = tmp_path / "leaderboard"
    shutil.copytree(REPO / "leaderboard", root)
    # Entries name their code by repository path, resolved inside the repository: copy it.
    shutil.copytree(
        REPO / "baselines", tmp_path / "baselines", ignore=shutil.ignore_patterns("*.pt", "__pycache__")
    )
    md = root / lb.MARKDOWN
    md.write_text(md.read_text().replace("| **11.83** |", "| **11.84** |", 1))
    problems = lb.check(root, both_data_dir)
    assert (
        len(problems) == 1 and "column 'All': committed '**11.84**', build writes '**11.83**'" in problems[0]
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
    args += [
        "--command",
        "odmd-bench baseline expansion",
        "--benchmark",
        "odmd-v1",
        "--uncalibrated",
        *common,
    ]
    added = runner.invoke(cli, args)
    assert added.exit_code == 0, added.output
    meta = yaml.safe_load((board / lb.ENTRIES / "exp2" / "odmd-v1-test" / "entry.yaml").read_text())
    assert meta["calibrated"] is False and meta["split"] == "test" and len(meta["sets_content_sha256"]) == 4
    stale = runner.invoke(cli, ["leaderboard", "check", *common])
    assert stale.exit_code == 1 and "build writes '| 2 | [Exp 2](entries/exp2/odmd-v1-test/)" in stale.output
    assert runner.invoke(cli, ["leaderboard", "build", "--no-plot", *common]).exit_code == 0
    recorded_plot(board)
    assert runner.invoke(cli, ["leaderboard", "check", *common]).exit_code == 0


def test_the_readme_summary_is_generated_and_checked(board: Path, v1_data_dir: Path) -> None:
    """A README beside the folder with the two markers gets the summary; a changed digit fails."""
    readme = board.parent / lb.README
    readme.write_text(f"# Project\n\nintro\n\n{lb.README_START}\nstale\n{lb.README_END}\n\nafter\n")
    assert any("stale" in p for p in _check(board, v1_data_dir))
    said = lb.write(board, lb.build(board, v1_data_dir, n_resamples=FAST), plot=False)
    assert any("README.md" in line for line in said)
    text = readme.read_text()
    assert text.startswith("# Project\n\nintro\n\n") and text.endswith(f"{lb.README_END}\n\nafter\n")
    assert "### odmd-v1 test" in text and "| BOX-LS |" in text
    assert _check(board, v1_data_dir) == []

    i, old, new = _bump_camera_digit(readme, "| 1 | BOX-LS |")
    assert _check(board, v1_data_dir) == [
        f"README.md line {i + 1}: table 'odmd-v1 test (generator v1 + imported robot)', row 'BOX-LS', "
        f"column 'Camera': committed {new!r}, build writes {old!r}"
    ]


def test_a_readme_without_the_markers_is_left_alone(board: Path, v1_data_dir: Path) -> None:
    readme = board.parent / lb.README
    readme.write_text("# Project\n")
    lb.write(board, lb.build(board, v1_data_dir, n_resamples=FAST), plot=False)
    assert readme.read_text() == "# Project\n"
    assert _check(board, v1_data_dir) == []


# ----------------------------------------------------------------------------- boards, hardening, frame


def test_every_board_is_shown_and_an_empty_one_says_so(board: Path, v1_data_dir: Path) -> None:
    built = lb.build(board, v1_data_dir, n_resamples=FAST)
    assert [b.spec for b in built.boards] == list(lb.BOARDS)
    empty = [b for b in built.boards if not b.rows]
    assert {b.benchmark for b in empty} == {"odmd-paper", "odms-detection", "kitti-tracking"}
    for text in (built.markdown, built.readme_block):
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

    from odmd_bench.data.registry import set_file
    from odmd_bench.leaderboard.board import load_board_data

    for benchmark in ("odmd-v1", "odmd-paper"):
        first = load_board_data(benchmark, "test", tmp_path, original_release)
        with h5py.File(set_file(benchmark, "test", tmp_path), "r+") as f:
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
