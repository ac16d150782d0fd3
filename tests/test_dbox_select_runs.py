"""``odmd-bench select-dbox``: the shipped weights chosen among several runs, on val only."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

torch = pytest.importorskip("torch")

from odmd_bench_baselines.dbox import load_model  # noqa: E402
from odmd_bench_baselines.dbox.model import checkpoint_shapes  # noqa: E402
from odmd_bench_baselines.dbox.recipe import validation_scores  # noqa: E402
from odmd_bench_baselines.dbox.select import select_runs, write_selection  # noqa: E402

import odmd_bench  # noqa: E402
from odmd_bench import DataError, UsageError  # noqa: E402
from odmd_bench.cli.main import cli  # noqa: E402
from odmd_bench.data.io import write_sets  # noqa: E402
from odmd_bench.data.registry import get_benchmark, set_file  # noqa: E402

SETS = ("normal", "perturb", "robot", "driving")


def _checkpoint(path: Path, seed: int, scores: dict[str, float], **record: object) -> None:
    rng = np.random.default_rng(seed)
    state = {
        k: torch.from_numpy(rng.normal(0.0, 0.1, s).astype(np.float32))
        for k, s in checkpoint_shapes().items()
    }
    torch.save(state, path)
    body = {
        "config": {"name": "p-z", "formulation": "rel"},
        "val_benchmark": "odms-detection",
        "val_sets": list(SETS),
        "generator_version": 1,
        "batch_size": 512,
        "command": f"odmd-bench train-dbox --config p-z --seed {seed} --out {path.parent}",
        "val_mean_percent_error": scores,
        "weights_sha256": hashlib.sha256(path.read_bytes()).hexdigest(),
        **record,
    }
    path.with_suffix(".json").write_text(json.dumps(body))


def _run(folder: Path, seed: int, overall: float, per_set: dict[str, float], **record: object) -> Path:
    """A finished train-dbox run: its overall checkpoint and one per set, with val scores."""
    folder.mkdir()
    _checkpoint(folder / "dbox_p-z.pt", seed, {"all": overall}, **record)
    for i, name in enumerate(SETS):
        _checkpoint(
            folder / f"dbox_p-z.{name}.pt", seed * 10 + i + 1, {name: per_set[name], "all": 99.0}, **record
        )
    return folder


@pytest.fixture
def two_runs(tmp_path: Path) -> tuple[Path, Path]:
    a = _run(tmp_path / "a", 1, 17.5, {"normal": 11.0, "perturb": 19.0, "robot": 10.0, "driving": 24.0})
    b = _run(tmp_path / "b", 2, 17.0, {"normal": 11.5, "perturb": 19.0, "robot": 9.0, "driving": 25.0})
    return a, b


def test_each_criterion_takes_the_run_with_the_best_val_score(two_runs: tuple[Path, Path]) -> None:
    a, b = two_runs
    sel = select_runs([a, b], "p-z")
    got = {key: cand.run.name for key, cand in sel.chosen.items()}
    # perturb is a tie: the run given first wins
    assert got == {"all": "b", "normal": "a", "perturb": "a", "robot": "b", "driving": "a"}
    assert select_runs([b, a], "p-z").chosen["perturb"].run.name == "b"


def test_the_chosen_files_are_copied_byte_for_byte_with_every_candidate_listed(
    two_runs: tuple[Path, Path], tmp_path: Path
) -> None:
    a, b = two_runs
    out = tmp_path / "weights"
    written = write_selection(select_runs([a, b], "p-z"), out, "the command")
    assert sorted(p.name for p in written) == sorted(
        [f"dbox_p-z{s}.{ext}" for s in ["", *(f".{n}" for n in SETS)] for ext in ("pt", "json")]
    )
    assert (out / "dbox_p-z.pt").read_bytes() == (b / "dbox_p-z.pt").read_bytes()
    assert (out / "dbox_p-z.robot.pt").read_bytes() == (b / "dbox_p-z.robot.pt").read_bytes()
    assert (out / "dbox_p-z.normal.pt").read_bytes() == (a / "dbox_p-z.normal.pt").read_bytes()
    record = json.loads((out / "dbox_p-z.robot.json").read_text())
    assert record["select_command"] == "the command"
    assert [(Path(c["run"]).name, c["val"]) for c in record["selected_from"]] == [("a", 10.0), ("b", 9.0)]
    assert record["command"].endswith(f"--out {b}")  # the chosen run's own training command
    # the copies pass the loader's hash check
    from odmd_bench_baselines import dbox

    dbox.verify_weights(out / "dbox_p-z.robot.pt", require_record=True)


def test_an_earlier_selection_is_a_candidate_whose_runs_stay_listed(
    two_runs: tuple[Path, Path], tmp_path: Path
) -> None:
    """New runs added to the shipped choice: the same files as choosing among all runs at once."""
    a, b = two_runs
    earlier = tmp_path / "earlier"
    write_selection(select_runs([a, b], "p-z"), earlier, "select a b")
    c = _run(tmp_path / "c", 3, 17.2, {"normal": 10.5, "perturb": 19.5, "robot": 9.5, "driving": 23.0})
    merged, at_once = tmp_path / "merged", tmp_path / "at-once"
    write_selection(select_runs([earlier, c], "p-z"), merged, "select earlier c")
    write_selection(select_runs([a, b, c], "p-z"), at_once, "select a b c")
    for key in ("", *(f".{n}" for n in SETS)):
        name = f"dbox_p-z{key}"
        assert (merged / f"{name}.pt").read_bytes() == (at_once / f"{name}.pt").read_bytes(), name
        got = json.loads((merged / f"{name}.json").read_text())
        want = json.loads((at_once / f"{name}.json").read_text())
        listed = [(Path(e["run"]).name, e["val"], e["on"]) for e in got["selected_from"]]
        assert listed == [(Path(e["run"]).name, e["val"], e["on"]) for e in want["selected_from"]], name
        assert [e.get("via_select_command") for e in got["selected_from"]] == ["select a b"] * 2 + [None]
        assert got["command"] == want["command"] and got["select_command"] == "select earlier c"
    # which is what the shipped-selection test checks on the committed weights
    record = json.loads((merged / "dbox_p-z.driving.json").read_text())
    assert record["val_mean_percent_error"]["driving"] == min(e["val"] for e in record["selected_from"])


def test_a_damaged_candidate_is_refused_before_anything_is_compared(
    two_runs: tuple[Path, Path], tmp_path: Path
) -> None:
    a, b = two_runs
    data = bytearray((a / "dbox_p-z.driving.pt").read_bytes())
    data[len(data) // 2] ^= 1
    (a / "dbox_p-z.driving.pt").write_bytes(bytes(data))
    (b / "dbox_p-z.robot.json").unlink()
    with pytest.raises(DataError) as err:
        select_runs([a, b], "p-z")
    text = str(err.value) + "\n".join(err.value.problems)
    assert "dbox_p-z.driving.pt do not match" in text and "dbox_p-z.robot.pt have no record" in text


def test_runs_that_are_not_comparable_are_refused_naming_the_difference(tmp_path: Path) -> None:
    sets = {"normal": 1.0, "perturb": 1.0, "robot": 1.0, "driving": 1.0}
    a = _run(tmp_path / "a", 1, 17.0, sets)
    b = _run(tmp_path / "b", 2, 16.0, sets, generator_version=2)
    with pytest.raises(DataError, match="not comparable") as err:
        select_runs([a, b], "p-z")
    assert any("generator_version 2 differs" in p for p in err.value.problems)


def test_usage_errors(two_runs: tuple[Path, Path], tmp_path: Path) -> None:
    a, b = two_runs
    with pytest.raises(UsageError, match="twice"):
        select_runs([a, a], "p-z")
    with pytest.raises(UsageError, match="unknown DBox configuration"):
        select_runs([a], "q")
    with pytest.raises(DataError, match="not a finished train-dbox run of ns-z"):
        select_runs([a], "ns-z")
    with pytest.raises(UsageError, match="is one of the candidate runs"):
        write_selection(select_runs([a, b], "p-z"), b)


@pytest.fixture
def tiny_val(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> dict[str, odmd_bench.Examples]:
    """A small odms-detection val split in its own data folder (written, so not the pinned one)."""
    sets = {s: odmd_bench.generate(30, "odms", "both", rng=i) for i, s in enumerate(SETS)}
    write_sets(set_file(get_benchmark("odms-detection"), "val", tmp_path / "data"), sets)
    monkeypatch.setenv("ODMD_BENCH_DATA", str(tmp_path / "data"))
    return odmd_bench.load_split("val", "odms-detection")


def _measured(run: Path, val: dict[str, odmd_bench.Examples]) -> Path:
    """``run`` with each record's val scores replaced by what its checkpoint gives on ``val``."""
    for weights in run.glob("dbox_p-z*.pt"):
        model, form = load_model(weights)
        record = json.loads(weights.with_suffix(".json").read_text())
        record["val_mean_percent_error"] = validation_scores(model, val, form, torch.device("cpu"))
        weights.with_suffix(".json").write_text(json.dumps(record))
    return run


def test_the_command_prints_the_choice_and_exits_2_on_bad_runs(
    two_runs: tuple[Path, Path], tmp_path: Path, tiny_val: dict[str, odmd_bench.Examples]
) -> None:
    a, b = (_measured(r, tiny_val) for r in two_runs)
    runner = CliRunner()
    result = runner.invoke(
        cli, ["select-dbox", str(a), str(b), "--config", "p-z", "--out", str(tmp_path / "w")]
    )
    assert result.exit_code == 0, result.output
    assert (
        "measured the val scores of 10 checkpoints again on odms-detection val: as recorded" in result.output
    )
    robot = sorted(
        json.loads((r / "dbox_p-z.robot.json").read_text())["val_mean_percent_error"]["robot"] for r in (a, b)
    )
    assert (
        f"candidates {robot[0]:.3f}, {robot[1]:.3f}" in result.output
        or f"{robot[1]:.3f}, {robot[0]:.3f}" in result.output
    )
    assert (tmp_path / "w" / "dbox_p-z.pt").is_file()
    bad = runner.invoke(
        cli, ["select-dbox", str(tmp_path / "w"), "--config", "ns-z", "--out", str(tmp_path / "x")]
    )
    assert bad.exit_code == 2 and "Traceback" not in bad.output, bad.output


def test_a_record_whose_score_its_weights_do_not_give_is_refused(
    two_runs: tuple[Path, Path], tmp_path: Path, tiny_val: dict[str, odmd_bench.Examples]
) -> None:
    a, b = (_measured(r, tiny_val) for r in two_runs)
    record = json.loads((b / "dbox_p-z.json").read_text())
    record["val_mean_percent_error"]["all"] = 0.5  # a forged best score
    (b / "dbox_p-z.json").write_text(json.dumps(record))
    result = CliRunner().invoke(
        cli, ["select-dbox", str(a), str(b), "--config", "p-z", "--out", str(tmp_path / "w")]
    )
    assert result.exit_code == 2, result.output
    assert "records state val scores their weights do not give" in result.output
    assert f"{b / 'dbox_p-z.json'}: val all 0.5000 recorded" in result.output
    assert not (tmp_path / "w").exists()


def test_every_shipped_selection_follows_the_rule_on_its_recorded_candidates() -> None:
    """A shipped file chosen by select-dbox is the first candidate with the lowest val score."""
    from odmd_bench_baselines import dbox

    records = sorted(dbox.WEIGHTS_DIR.rglob("dbox_*.json"))
    checked = 0
    for path in records:
        record = json.loads(path.read_text())
        candidates = record.get("selected_from")
        if candidates is None:
            continue
        checked += 1
        key = candidates[0]["on"]
        assert all(c["on"] == key for c in candidates), path.name
        assert (key == "all") == (path.name.count(".") == 1), path.name  # the overall file or a set's
        best = min(c["val"] for c in candidates)
        first = next(c for c in candidates if c["val"] == best)
        assert record["val_mean_percent_error"][key] == best, path.name
        assert record["command"] == first["command"], path.name
        assert record["select_command"].startswith("odmd-bench select-dbox "), path.name
    assert checked >= 15  # the three z configurations: overall and four sets each


def test_a_run_that_stopped_early_or_names_odd_sets_is_refused(tmp_path: Path) -> None:
    sets = {"normal": 11.0, "perturb": 19.0, "robot": 10.0, "driving": 24.0}
    done = _run(tmp_path / "done", 1, 17.5, sets, steps=200, steps_done=200)
    killed = _run(tmp_path / "killed", 2, 12.0, sets, steps=200, steps_done=40)
    with pytest.raises(DataError, match=r"stopped at step 40 of 200 \(killed\?\)"):
        select_runs([done, killed], "p-z")
    odd = _run(tmp_path / "odd", 3, 17.0, sets, val_sets=["normal", "../../evil"])
    with pytest.raises(DataError, match="has no list of val_sets"):
        select_runs([odd], "p-z")
