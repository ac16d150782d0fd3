"""DBox weights by configuration name, the per-set selection, and hash-checked checkpoints."""

from __future__ import annotations

import dataclasses
import hashlib
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from odmd_bench_baselines import dbox  # noqa: E402
from odmd_bench_baselines.dbox.model import checkpoint_shapes  # noqa: E402
from odmd_bench_baselines.dbox.select import SCORE_TOLERANCE  # noqa: E402

import odmd_bench  # noqa: E402
from odmd_bench import DataError, Examples, UsageError  # noqa: E402


@pytest.fixture(autouse=True)
def _one_thread() -> None:
    torch.set_num_threads(1)


def _examples(n: int, preset: str, seed: int, **attrs: str) -> Examples:
    ex = odmd_bench.generate(n, preset, "normal", np.random.default_rng(seed))
    return dataclasses.replace(ex, attrs={**ex.attrs, **attrs})


def _write_checkpoint(path: Path, seed: int, config: str = "p-z", record: bool = True) -> Path:
    rng = np.random.default_rng(seed)
    state = {
        k: torch.from_numpy(rng.normal(0.0, 0.3 / np.sqrt(s[-1]), s).astype(np.float32))
        for k, s in checkpoint_shapes().items()
    }
    torch.save(state, path)
    if record:
        sha = hashlib.sha256(path.read_bytes()).hexdigest()
        body = {"config": {"name": config, "formulation": "rel"}, "weights_sha256": sha}
        path.with_suffix(".json").write_text(json.dumps(body))
    return path


def _flip_a_bit_inside_tensor_w(path: Path) -> None:
    """Flip one bit in the middle of the stored values of ``W`` (not in a header)."""
    data = bytearray(path.read_bytes())
    values = torch.load(path, weights_only=True)["W"].numpy().tobytes()
    start = bytes(data).find(values)
    assert start > 0 and bytes(data).find(values, start + 1) == -1
    data[start + len(values) // 2] ^= 0x10
    path.write_bytes(bytes(data))


# --- the default follows the data ------------------------------------------------------------


def test_the_default_configuration_follows_the_benchmark_then_the_camera_motion() -> None:
    xyz = _examples(20, "odmd", 1)
    z_only = _examples(20, "odms", 2)
    z_only = dataclasses.replace(z_only, camera=z_only.camera * np.array([0.0, 0.0, 1.0]))
    assert dbox.default_config(xyz) == "p" and not dbox.is_z_only(xyz)
    assert dbox.default_config(z_only) == "p-z" and dbox.is_z_only(z_only)
    # the benchmark named in the data decides before the motion does
    assert dbox.default_config(dataclasses.replace(xyz, attrs={"benchmark": "odms-detection"})) == "p-z"
    assert dbox.default_config(dataclasses.replace(z_only, attrs={"benchmark": "odmd-v1"})) == "p"


def test_odms_detection_data_runs_the_z_only_weights_by_default(paper_data_dir: Path) -> None:
    ex = odmd_bench.load("val", "driving", "odms-detection", paper_data_dir).subset(slice(0, 50))
    depths = dbox.predict(ex)
    report = dbox.provenance(ex)
    assert report["config"] == "p-z" and report["weights"] == "dbox_p-z.pt"
    np.testing.assert_array_equal(depths, dbox.predict(ex, weights=dbox.weights_path("p-z")))
    assert not np.array_equal(depths, dbox.predict(ex, config="p"))


def test_every_shipped_configuration_runs_by_name_and_says_so() -> None:
    ex = _examples(30, "odms", 3)
    for config in dbox.shipped():
        depths = dbox.predict(ex, config=config)
        report = dbox.provenance(ex, config=config)
        assert report["config"] == config and report["selection"] == "overall"
        assert (
            report["weights_sha256"]
            == json.loads(dbox.weights_path(config).with_suffix(".json").read_text())["weights_sha256"]
        )
        assert depths.shape == (30,) and np.isfinite(depths).all()


def test_unknown_and_unshipped_configurations_are_clear_errors(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    ex = _examples(5, "odmd", 4)
    with pytest.raises(UsageError, match="unknown DBox configuration 'q'.*p, abs, ns, p-z, ns-z, abs-z"):
        dbox.predict(ex, config="q")
    with pytest.raises(UsageError, match="unknown DBox selection"):
        dbox.predict(ex, selection="best")
    with pytest.raises(UsageError, match="not both"):
        dbox.predict(ex, config="p", weights=dbox.weights_path("p"))
    monkeypatch.setattr(dbox.weights, "WEIGHTS_DIR", tmp_path)
    _write_checkpoint(tmp_path / "dbox_p.pt", 1, "p")
    with pytest.raises(DataError, match=r"no shipped weights for DBox configuration 'abs' \(shipped: p\)"):
        dbox.predict(ex, config="abs")


# --- the per-set selection ----------------------------------------------------------------


def test_per_set_selection_runs_the_checkpoint_chosen_for_that_set(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(dbox.weights, "WEIGHTS_DIR", tmp_path)
    _write_checkpoint(tmp_path / "dbox_p-z.pt", 1)
    _write_checkpoint(tmp_path / "dbox_p-z.normal.pt", 2)
    _write_checkpoint(tmp_path / "dbox_p-z.robot.pt", 3)
    assert dbox.shipped() == {"p-z": ["normal", "robot"]}
    normal = _examples(40, "odms", 5, set="normal")
    depths = dbox.predict(normal, config="p-z", selection="per-set")
    report = dbox.provenance(normal, config="p-z", selection="per-set")
    assert report["selection"] == "per-set" and report["weights"] == "dbox_p-z.normal.pt"
    np.testing.assert_array_equal(depths, dbox.predict(normal, weights=tmp_path / "dbox_p-z.normal.pt"))
    assert not np.array_equal(depths, dbox.predict(normal, config="p-z"))
    # a run folder's own per-set files are found beside its overall file
    np.testing.assert_array_equal(
        dbox.predict(normal, weights=tmp_path / "dbox_p-z.pt", selection="per-set"), depths
    )
    with pytest.raises(DataError, match="no per-set checkpoint for set 'driving'.*normal, robot"):
        dbox.predict(_examples(5, "odms", 6, set="driving"), config="p-z", selection="per-set")
    with pytest.raises(UsageError, match="which set"):
        dbox.predict(_examples(5, "odms", 7), config="p-z", selection="per-set")


# --- weights selected on the data's benchmark -----------------------------------------------


def test_weights_selected_on_the_datas_benchmark_run_on_that_benchmark(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """p-z selected on ODMD val runs on ODMD data; ODMS data and unnamed data keep the ODMS one."""
    monkeypatch.setattr(dbox.weights, "WEIGHTS_DIR", tmp_path)
    _write_checkpoint(tmp_path / "dbox_p-z.pt", 1)
    _write_checkpoint(tmp_path / "dbox_p-z.robot.pt", 3)
    (tmp_path / "selected-on-odmd-v1").mkdir()
    odmd_file = _write_checkpoint(tmp_path / "selected-on-odmd-v1" / "dbox_p-z.pt", 2)
    assert dbox.shipped() == {"p-z": ["robot"]}
    assert dbox.weights_path("p-z", selected_on="odmd-v1") == odmd_file
    assert dbox.weights_path("p-z", selected_on="odms-detection") == tmp_path / "dbox_p-z.pt"
    for benchmark in ("odmd-paper", "odmd-v1"):
        ex = _examples(30, "odmd", 8, benchmark=benchmark, set="robot")
        assert dbox.selection_benchmark(ex) == "odmd-v1"
        report = dbox.provenance(ex, config="p-z")
        assert report["weights"] == "selected-on-odmd-v1/dbox_p-z.pt", report
        np.testing.assert_array_equal(dbox.predict(ex, config="p-z"), dbox.predict(ex, weights=odmd_file))
        # per-set files are those beside the overall file the data select: none here, and
        # the ODMS-selected file of a set with the same name is not run in their place
        with pytest.raises(
            DataError,
            match=r"no per-set checkpoint for set 'robot' \(per-set checkpoints in selected-on-odmd-v1/: none\)",
        ):
            dbox.predict(ex, config="p-z", selection="per-set")
    odmd_robot = _write_checkpoint(tmp_path / "selected-on-odmd-v1" / "dbox_p-z.robot.pt", 5)
    assert dbox.shipped() == {"p-z": ["robot"]}  # the configuration's own val selects shipped()
    for benchmark in ("odmd-paper", "odmd-v1"):
        ex = _examples(30, "odmd", 8, benchmark=benchmark, set="robot")
        report = dbox.provenance(ex, config="p-z", selection="per-set")
        assert report["weights"] == "selected-on-odmd-v1/dbox_p-z.robot.pt", report
        np.testing.assert_array_equal(
            dbox.predict(ex, config="p-z", selection="per-set"), dbox.predict(ex, weights=odmd_robot)
        )
        with pytest.raises(
            DataError, match=r"set 'camera' \(per-set checkpoints in selected-on-odmd-v1/: robot\)"
        ):
            dbox.predict(
                _examples(5, "odmd", 12, benchmark=benchmark, set="camera"), config="p-z", selection="per-set"
            )
    # ODMS data keep the ODMS-selected per-set file
    ex = _examples(30, "odms", 9, benchmark="odms-detection", set="robot")
    assert dbox.provenance(ex, config="p-z", selection="per-set")["weights"] == "dbox_p-z.robot.pt"
    for attrs in ({"benchmark": "odms-detection"}, {}):
        ex = _examples(30, "odms", 9, **attrs)
        assert dbox.provenance(ex, config="p-z")["weights"] == "dbox_p-z.pt"
    # p has no ODMS-selected file: ODMS data run its own (the name says which)
    _write_checkpoint(tmp_path / "dbox_p.pt", 4, "p")
    ex = _examples(10, "odms", 10, benchmark="odms-detection")
    assert dbox.provenance(ex, config="p")["weights"] == "dbox_p.pt"
    # a damaged file in the subfolder is a shipped file: reinstall
    _flip_a_bit_inside_tensor_w(odmd_file)
    with pytest.raises(DataError, match="reinstall odmd-bench"):
        dbox.predict(_examples(5, "odmd", 11, benchmark="odmd-paper"), config="p-z")


# --- hash-checked weights -----------------------------------------------------------------


def test_one_flipped_bit_in_a_copy_of_the_shipped_weights_is_refused(tmp_path: Path) -> None:
    copy = tmp_path / "dbox_p.pt"
    shutil.copyfile(dbox.weights_path("p"), copy)
    shutil.copyfile(dbox.weights_path("p").with_suffix(".json"), copy.with_suffix(".json"))
    expected = json.loads(copy.with_suffix(".json").read_text())["weights_sha256"]
    _flip_a_bit_inside_tensor_w(copy)
    actual = hashlib.sha256(copy.read_bytes()).hexdigest()
    ex = _examples(50, "odmd", 8)
    with pytest.raises(DataError) as info:
        dbox.predict(ex, weights=copy)
    text = info.value.render()
    assert str(copy) in text and expected in text and actual in text and "fix:" in text
    # torch alone reads the damaged file without complaint: the hash is what catches it
    copy.with_suffix(".json").unlink()
    damaged = dbox.predict(ex, weights=copy)
    assert not np.array_equal(damaged, dbox.predict(ex, config="p"))


def test_the_shipped_weights_are_checked_before_they_are_read(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    for suffix in (".pt", ".json"):
        shutil.copyfile(dbox.weights_path("p").with_suffix(suffix), (tmp_path / "dbox_p").with_suffix(suffix))
    monkeypatch.setattr(dbox.weights, "WEIGHTS_DIR", tmp_path)
    _flip_a_bit_inside_tensor_w(tmp_path / "dbox_p.pt")
    with pytest.raises(DataError, match="do not match its record"):
        dbox.predict(_examples(5, "odmd", 9), config="p")
    (tmp_path / "dbox_p.json").unlink()  # a shipped file without its record is refused too
    with pytest.raises(DataError, match="no record"):
        dbox.predict(_examples(5, "odmd", 9), config="p")


def test_a_users_weights_are_checked_against_a_given_hash_and_the_hash_is_reported(tmp_path: Path) -> None:
    path = _write_checkpoint(tmp_path / "mine.pt", 10, record=False)
    sha = hashlib.sha256(path.read_bytes()).hexdigest()
    ex = _examples(5, "odmd", 11)
    depths, counts = dbox.predict_report(ex, weights=path)
    report = dbox.provenance(ex, weights=path)
    assert counts == {"n": 5, "no_detection": 0, **report, "formulation": "rel"}  # which weights ran, and how
    assert report["weights_sha256"] == sha and report["config"] == "custom"
    assert report["weights"] == str(path)
    np.testing.assert_array_equal(dbox.predict(ex, weights=path, weights_sha256=sha.upper()), depths)
    with pytest.raises(DataError, match="do not match the given weights_sha256"):
        dbox.predict(ex, weights=path, weights_sha256="0" * 64)
    with pytest.raises(UsageError, match="64 hex digits"):
        dbox.predict(ex, weights=path, weights_sha256="abc")


def test_a_broken_record_is_a_clear_error(tmp_path: Path) -> None:
    path = _write_checkpoint(tmp_path / "w.pt", 12)
    path.with_suffix(".json").write_text("{not json")
    with pytest.raises(DataError, match="cannot read the weights record"):
        dbox.load_model(path)
    path.with_suffix(".json").write_text(json.dumps({"weights_sha256": "xyz"}))
    with pytest.raises(DataError, match="no valid weights_sha256"):
        dbox.load_model(path)


def test_a_record_that_is_not_a_file_is_refused_not_passed_over(tmp_path: Path) -> None:
    """A folder or a dangling link in the record's place would otherwise leave the weights unchecked."""
    path = _write_checkpoint(tmp_path / "w.pt", 12, record=False)
    record = path.with_suffix(".json")
    record.mkdir()
    with pytest.raises(
        DataError, match=r"the record .*w\.json beside the DBox weights .* is not a regular file"
    ):
        dbox.load_model(path)
    record.rmdir()
    record.symlink_to(tmp_path / "nowhere.json")
    with pytest.raises(DataError, match="is not a regular file"):
        dbox.load_model(path)
    record.unlink()
    dbox.load_model(path)  # no record: a file of one's own, run as it is (its hash is reported)


def test_observations_constant_is_the_networks_input_length() -> None:
    assert checkpoint_shapes()["linears.0.weight"][1] == 128 + dbox.OBSERVATIONS * 7


# --- training keeps both selections ---------------------------------------------------------


def test_training_keeps_the_best_model_overall_and_per_set(tmp_path: Path) -> None:
    from odmd_bench_baselines.dbox.train import train

    val = {"normal": _examples(48, "odms", 20), "far": _examples(48, "odmd", 21)}
    result = train("p-z", 12, tmp_path, val_sets=val, val_every=2, progress=None, batch_size=32)
    log = [json.loads(line) for line in (tmp_path / "log.jsonl").read_text().splitlines()]
    assert [e["step"] for e in log] == [2, 4, 6, 8, 10, 12]
    overall = json.loads((tmp_path / "dbox_p-z.json").read_text())
    assert overall["best_step"] == min(log, key=lambda e: e["all"])["step"] == result.best_step
    assert overall["selection"]["kind"] == "overall"
    assert overall["cpu_time_s"] > 0 and overall["cpu_kernels"] in ("onednn", "plain")
    for name in val:
        record = json.loads((tmp_path / f"dbox_p-z.{name}.json").read_text())
        best = min(log, key=lambda e: e[name])
        assert record["selection"] == {"kind": "per-set", "on": name, "run_on": name}
        assert record["best_step"] == best["step"] == overall["selection"]["per_set_steps"][name]
        assert record["val_mean_percent_error"][name] == pytest.approx(best[name])
        # the file is that step's model, and the run folder's per-set selection finds it
        named = dataclasses.replace(val[name], attrs={**val[name].attrs, "set": name})
        pred = dbox.predict(named, weights=tmp_path / "dbox_p-z.pt", selection="per-set")
        got = float(np.mean(np.abs(pred - named.depth) / named.depth * 100))
        assert got == pytest.approx(best[name], rel=1e-5)


@pytest.mark.usefixtures("dbox_depths_made_once")
def test_every_shipped_checkpoint_scores_the_val_numbers_its_record_states(paper_data_dir: Path) -> None:
    """Each z-axis checkpoint reproduces its recorded val numbers.

    Overall and per-set, each gives on ODMS-detection val what its training run measured when it kept it (so the records, and docs/dbox.md, hold).
    """
    val = odmd_bench.load_split("val", "odms-detection", paper_data_dir)
    checked = 0
    for config, sets in dbox.shipped().items():
        record = json.loads(dbox.weights_path(config).with_suffix(".json").read_text())
        if record["config"]["val_benchmark"] != "odms-detection":
            continue
        assert sorted(sets) == sorted(val) and record["selection"]["kind"] == "overall"
        for selection in ("overall", "per-set"):
            for name, ex in val.items():
                path = dbox.weights_path(config, None if selection == "overall" else name)
                stated = json.loads(path.with_suffix(".json").read_text())["val_mean_percent_error"][name]
                pred = dbox.predict(ex, config=config, selection=selection)
                got = float(np.mean(np.abs(pred - ex.depth) / ex.depth * 100))
                assert got == pytest.approx(stated, abs=SCORE_TOLERANCE), (config, selection, name)
                checked += 1
    assert checked >= 8


def test_docs_state_how_many_runs_each_z_selection_chose_among() -> None:
    """docs/dbox.md's count of runs per z configuration is the count in the shipped records.

    The per-set search is wider than the paper's (one run), and how much wider is part of
    reading the numbers: the statement must not go stale when runs are added.
    """
    import re

    docs = (Path(__file__).resolve().parents[1] / "docs" / "dbox.md").read_text(encoding="utf-8")
    text = " ".join(docs.split())
    m = re.search(r"\((\d+) runs for `p-z`, (\d+) for `abs-z`, (\d+) for `ns-z`;", text)
    assert m, "docs/dbox.md no longer states the run counts of the z selections"
    stated = dict(zip(("p-z", "abs-z", "ns-z"), map(int, m.groups()), strict=True))
    for config, n in stated.items():
        for name in [None, *dbox.shipped()[config]]:
            record = json.loads(dbox.weights_path(config, name).with_suffix(".json").read_text())
            assert len(record["selected_from"]) == n, (config, name)
