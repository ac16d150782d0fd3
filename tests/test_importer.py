"""Import of the original release: bit-exact, and refusing hostile or unknown files."""

from __future__ import annotations

import pickle
from pathlib import Path

import numpy as np
import pytest

import odmd_bench
from odmd_bench import ImportRefused
from odmd_bench.data.importer import import_release, read_original, safe_unpickle

SETS = {"normal": "normal", "perturb_motion": "camera", "perturb_detection": "object", "robot": "robot"}


def _raw(path: Path) -> dict:
    # The test trusts these pinned files enough to read them with the plain unpickler,
    # so that it compares against an independent reading.
    with open(path, "rb") as fh:
        return pickle.load(fh)  # noqa: S301


@pytest.mark.parametrize("split", ["val", "test"])
@pytest.mark.parametrize("stem", sorted(SETS))
def test_import_is_bit_exact(split, stem, original_release, paper_data_dir) -> None:
    raw = _raw(original_release / "odmd" / split / f"{split}_{stem}.pk")
    ex = odmd_bench.load(split, SETS[stem], "odmd-paper", paper_data_dir)
    bb = raw["bb"]["bboxes"]
    assert np.array_equal(ex.boxes, bb[:, :4].transpose(2, 0, 1))
    assert np.array_equal(ex.depth, bb[-1, 4])
    assert np.array_equal(ex.camera[:, :-1], raw["bb_3D"]["camera_movement"].transpose(2, 0, 1))
    assert (ex.camera[:, -1] == 0).all()
    assert np.array_equal(ex.detected, bb[:, 2].T != 0)
    z = bb[:, 4].T
    known = z != 0
    assert np.array_equal(ex.observation_depth[known], z[known])
    assert np.isnan(ex.observation_depth[~known]).all()
    if "positions" in raw["bb_3D"]:
        assert np.array_equal(ex.extras["positions"], raw["bb_3D"]["positions"].transpose(2, 0, 1))
        assert np.array_equal(ex.extras["size"][:, 0], raw["bb_3D"]["sizes"][0])
    assert ex.attrs["source_known"] and len(ex.attrs["source_sha256"]) == 64
    assert ex.intrinsics() == (205.5, 205.5, 320.5, 240.5, 640.0, 480.0)


def test_robot_sets_have_missing_detections(paper_data_dir) -> None:
    ex = odmd_bench.load("test", "robot", "odmd-paper", paper_data_dir)
    assert (~ex.detected).sum() == 188
    assert (ex.detected.sum(axis=1) <= 1).sum() == 4


def test_odms_detection_sets_import_without_intrinsics(paper_data_dir) -> None:
    sets = odmd_bench.load_split("val", "odms-detection", paper_data_dir)
    assert {k: len(v) for k, v in sets.items()} == {
        "normal": 2000,
        "perturb": 2000,
        "robot": 1760,
        "driving": 500,
    }
    assert sets["driving"].attrs["image_width"] == 1280
    with pytest.raises(odmd_bench.DataError, match="no camera intrinsics"):
        sets["robot"].intrinsics()


class _Boom:
    def __reduce__(self):
        import os

        return (os.system, ("touch /tmp/odmd-hostile-pickle-ran",))


def test_hostile_pickle_is_refused_and_nothing_runs(tmp_path) -> None:
    marker = Path("/tmp/odmd-hostile-pickle-ran")
    marker.unlink(missing_ok=True)
    evil = pickle.dumps({"bb": {"bboxes": _Boom()}, "bb_3D": {}}, protocol=3)
    with pytest.raises(ImportRefused, match="posix.system|os.system"):
        safe_unpickle(evil, "evil.pk")
    assert not marker.exists()
    path = tmp_path / "test_normal.pk"
    path.write_bytes(evil)
    with pytest.raises(ImportRefused):
        read_original(path, allow_unknown=True)
    assert not marker.exists()


def test_unknown_or_altered_files_are_refused(original_release, tmp_path) -> None:
    data = bytearray((original_release / "odmd" / "test" / "test_robot.pk").read_bytes())
    data[-20] ^= 1  # one flipped bit inside the numbers
    path = tmp_path / "test_robot.pk"
    path.write_bytes(bytes(data))
    with pytest.raises(ImportRefused, match="unknown file"):
        import_release(path, tmp_path / "data")
    assert not (tmp_path / "data").exists()
    # Allowed explicitly, it imports and says it is not a known original.
    import_release(path, tmp_path / "data", allow_unknown=True)
    ex = odmd_bench.load("test", "robot", "odmd-paper", tmp_path / "data")
    assert ex.attrs["source_known"] is False or ex.attrs["source_known"] == 0
    # Under a name that is not the release's, the refusal says which names map to a set.
    other = tmp_path / "mine" / "robot_test_v2.pk"
    other.parent.mkdir()
    other.write_bytes(bytes(data))
    with pytest.raises(
        ImportRefused, match=r"name says neither split nor set.*SPLIT_SET\.pk .*test_robot\.pk"
    ):
        import_release(other, tmp_path / "data2", allow_unknown=True)


def test_garbage_and_wrong_layouts_are_refused(tmp_path) -> None:
    for name, payload in {
        "test_normal.pk": b"not a pickle at all",
        "test_camera.pk": pickle.dumps({"bb": {}, "bb_3D": {}}, protocol=3),
        "val_robot.pk": pickle.dumps([1, 2, 3], protocol=3),
    }.items():
        (tmp_path / name).write_bytes(payload)
    with pytest.raises(ImportRefused) as info:
        import_release(tmp_path, tmp_path / "data", allow_unknown=True)
    text = info.value.render()
    assert "nothing was written" in text and text.count("\n  - ") >= 2


def test_reimport_keeps_other_sets(original_release, tmp_path) -> None:
    import_release(original_release / "odmd" / "test" / "test_normal.pk", tmp_path)
    import_release(original_release / "odmd" / "test" / "test_robot.pk", tmp_path)
    sets = odmd_bench.load_split("test", "odmd-paper", tmp_path, sets=["normal", "robot"])
    assert set(sets) == {"normal", "robot"}


@pytest.mark.parametrize(
    ("key", "value", "words"),
    [
        ("fx_norm", "x", "fx_norm = 'x' does not match the HSR camera"),
        ("fx_norm", [1, 2], "fx_norm = [1, 2] does not match the HSR camera"),
        ("image_dim", ["abc", 640], "image_dim = ['abc', 640] is not two positive whole numbers"),
        ("image_dim", [float("nan"), 640], "image_dim = [nan, 640] is not two positive whole numbers"),
        # integers too large for a float, and too long to print
        ("image_dim", [10**5000, 640], "image_dim = a list too large to print is not two positive"),
        ("fx_norm", 10**5000, "fx_norm = an int too large to print does not match the HSR camera"),
    ],
    ids=["fx-text", "fx-list", "dim-text", "dim-nan", "dim-huge-int", "fx-huge-int"],
)
def test_malformed_metadata_of_an_unknown_file_is_refused(
    original_release, tmp_path, key: str, value: object, words: str
) -> None:
    obj = safe_unpickle(
        (original_release / "odmd" / "test" / "test_normal.pk").read_bytes(), "test_normal.pk"
    )
    obj["bb"][key] = value
    path = tmp_path / "test_normal.pk"
    path.write_bytes(pickle.dumps(obj, protocol=3))
    with pytest.raises(ImportRefused, match="nothing was written") as info:
        import_release(path, tmp_path / "data", allow_unknown=True)
    assert words in info.value.render()
    assert not (tmp_path / "data").exists()


def test_a_pipe_named_like_an_original_is_refused_not_read(tmp_path) -> None:
    import os

    fifo = tmp_path / "test_normal.pk"
    os.mkfifo(fifo)
    with pytest.raises(ImportRefused, match="not a regular file nor a folder"):
        import_release(fifo, tmp_path / "data")


def _set_last_depth(o: dict, v: float) -> None:
    o["bb"]["bboxes"][-1, 4, 0] = v


def _nan_camera(o: dict) -> None:
    o["bb_3D"]["camera_movement"][3, 1, 7] = np.nan


def _inf_box(o: dict) -> None:
    o["bb"]["bboxes"][2, 0, 5] = np.inf


def _never_detected(o: dict) -> None:
    o["bb"]["bboxes"][:, 2, 9] = 0.0


def _one_observation(o: dict) -> None:
    o["bb"]["bboxes"] = o["bb"]["bboxes"][:1]
    o["bb_3D"]["camera_movement"] = o["bb_3D"]["camera_movement"][:0]
    del o["bb_3D"]["positions"]


@pytest.mark.parametrize(
    ("alter", "words"),
    [
        (
            lambda o: _set_last_depth(o, 0.0),
            "1 example(s) with a true depth that is not finite and > 0 (first: [0])",
        ),
        (
            lambda o: _set_last_depth(o, -1.0),
            "1 example(s) with a true depth that is not finite and > 0 (first: [0])",
        ),
        (
            lambda o: _set_last_depth(o, np.nan),
            "1 example(s) with a true depth that is not finite and > 0 (first: [0])",
        ),
        (_nan_camera, "1 example(s) with a camera position that is not finite (first: [7])"),
        (_inf_box, "1 example(s) with a detected box that is not finite (first: [5])"),
        (_never_detected, "1 example(s) with no detection at any observation (first: [9])"),
        (_one_observation, "every example needs at least two observations, these have 1"),
    ],
    ids=[
        "zero-depth",
        "negative-depth",
        "nan-depth",
        "nan-camera",
        "inf-box",
        "no-detection",
        "one-observation",
    ],
)
def test_an_altered_file_that_cannot_be_scored_against_is_refused(
    original_release, tmp_path, alter, words: str
) -> None:
    """--allow-unknown admits altered numbers, never a set on which percent error is undefined."""
    obj = safe_unpickle(
        (original_release / "odmd" / "test" / "test_normal.pk").read_bytes(), "test_normal.pk"
    )
    alter(obj)
    path = tmp_path / "test_normal.pk"
    path.write_bytes(pickle.dumps(obj, protocol=3))
    with pytest.raises(ImportRefused, match="nothing was written") as info:
        import_release(path, tmp_path / "data", allow_unknown=True)
    assert f"{path}: not usable as a benchmark set" in info.value.render()
    assert f"\n  - {words}" in info.value.render()
    assert not (tmp_path / "data").exists()


def test_every_pinned_set_is_usable(paper_data_dir, v1_data_dir) -> None:
    """The checks the importer applies hold for every set odmd-bench makes or imports.

    Some detections of the release have a zero or negative width or height (they are
    kept, as the release has them); the checks do not refuse those.
    """
    from odmd_bench.data.examples import set_problems

    for benchmark, data in (
        ("odmd-paper", paper_data_dir),
        ("odms-detection", paper_data_dir),
        ("odmd-v1", v1_data_dir),
    ):
        for split in ("val", "test"):
            for s, ex in odmd_bench.load_split(split, benchmark, data).items():
                assert set_problems(ex) == [], (benchmark, split, s)
