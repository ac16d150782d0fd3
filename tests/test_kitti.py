"""The kitti-tracking benchmark: the import, the sets, the board.

The import reproduces the pins, an independent re-derivation agrees with the sets, the
shipped sets load and score without the raw files, and the board's commands reproduce
its entries.

Tests that need the raw files read ``../shared/kitti-tracking`` (or ``$ODMD_KITTI_TRACKING``):
they skip when it is missing on a developer's machine and fail in CI (``CI`` set).
"""

from __future__ import annotations

import gzip
import io
import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner
from conftest import kitti_dir

from odmd_bench.cli.main import cli
from odmd_bench.data.io import read_set
from odmd_bench.data.manifests import read_manifest, splits_dir
from odmd_bench.data.store import load_split

ROOT = Path(__file__).resolve().parents[1]
SETS = ("vehicle", "person")


@pytest.fixture(scope="module")
def imported(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    """A data folder after ``odmd-bench import kitti-tracking KITTI``, and the command's output."""
    src = kitti_dir()
    data = tmp_path_factory.mktemp("kitti-data")
    r = CliRunner().invoke(cli, ["import", "kitti-tracking", str(src), "--data-dir", str(data)])
    assert r.exit_code == 0, r.output
    return data, r.output


def test_the_import_reproduces_every_pinned_hash(imported: tuple[Path, str]) -> None:
    data, output = imported
    pins = read_manifest("kitti-tracking")["splits"]
    for split in ("val", "test"):
        assert f"kitti-tracking {split}: " in output and "(the pinned sets;" in output
        for s in SETS:
            ex = read_set(data / "kitti-tracking" / f"{split}.h5", s)
            assert ex.attrs["content_sha256"] == pins[split][s]["sha256"]
            assert ex.attrs["meta_sha256"] == pins[split][s]["meta_sha256"]
            assert len(ex) == pins[split][s]["n"]
            shipped = read_set(splits_dir() / pins[split][s]["file"], s)
            assert shipped.attrs["content_sha256"] == ex.attrs["content_sha256"]


def test_the_import_output_counts_the_windows_each_rule_removes(imported: tuple[Path, str]) -> None:
    line = next(x for x in imported[1].splitlines() if x.startswith("kitti-tracking test"))
    counts = dict(part.rsplit(" ", 1) for part in line.split("windows: ")[1].split(", "))
    removed = sum(
        int(counts[k]) for k in ("static", "truncated", "occluded", "box_height", "travel", "depth")
    )
    assert int(counts["candidates"]) == removed + int(counts["taken"])
    assert int(counts["taken"]) == sum(
        read_manifest("kitti-tracking")["splits"]["test"][s]["n"] for s in SETS
    )


# --- an independent re-derivation, with its own small parsers -------------------------------

KEPT = {"Car", "Van", "Truck", "Tram", "Pedestrian", "Person", "Person_sitting", "Cyclist"}


def _labels(path: Path) -> dict[tuple[int, int], list[str]]:
    """``{(track, frame): fields}`` of a label file, DontCare dropped."""
    out = {}
    for line in path.read_text().splitlines():
        f = line.split()
        if f and f[2] != "DontCare":
            out[(int(f[1]), int(f[0]))] = f
    return out


def _poses(path: Path) -> list[np.ndarray]:
    return [
        np.array([float(v) for v in line.split()]).reshape(3, 4) for line in path.read_text().splitlines()
    ]


def _matrix(q: np.ndarray) -> np.ndarray:
    """The rotation of a unit quaternion ``x, y, z, w``, through the axis and angle it encodes."""
    x, y, z, w = q / np.linalg.norm(q)
    angle = 2 * np.arctan2(np.linalg.norm([x, y, z]), w)
    axis = np.array([x, y, z]) / (np.linalg.norm([x, y, z]) or 1.0)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k  # Rodrigues


def _windows(labels: dict[tuple[int, int], list[str]], poses: list[np.ndarray]) -> list[tuple[int, int, str]]:
    """(track, last frame, type) of every window taken, by the rules as docs/kitti.md states them."""
    taken = []
    for track in sorted({t for t, _ in labels}):
        frames = sorted(f for t, f in labels if t == track)
        if labels[(track, frames[0])][2] not in KEPT:
            continue
        last = None
        for f in frames:
            if last is not None and f - last < 18:
                continue
            window = list(range(f - 18, f + 1, 2))
            if window[0] < 0 or any((track, g) not in labels or g >= len(poses) for g in window):
                continue
            rows = [labels[(track, g)] for g in window]
            world = []
            for g, r in zip(window, rows, strict=True):
                h, x, y, z = float(r[10]), float(r[13]), float(r[14]), float(r[15])
                world.append(poses[g][:, :3] @ np.array([x, y - h / 2, z]) + poses[g][:, 3])
            world = np.array(world)
            static = np.linalg.norm(world - world.mean(axis=0), axis=1).max() <= 0.5
            end = rows[-1]
            ok = (
                static
                and int(end[3]) == 0
                and int(end[4]) <= 1
                and all(float(r[9]) - float(r[7]) >= 20 for r in rows)
                and np.linalg.norm(poses[window[-1]][:, 3] - poses[window[0]][:, 3]) >= 1
                and 2 < float(end[15]) < 60
            )
            if ok:
                taken.append((track, f, rows[0][2]))
                last = f
    return taken


@pytest.mark.parametrize("sequence", [1, 11, 19])
def test_an_independent_rederivation_agrees_with_the_shipped_sets(sequence: int) -> None:
    src = kitti_dir()
    labels = _labels(src / "label_02" / f"{sequence:04d}.txt")
    poses = _poses(src / "poses" / f"{sequence:04d}.txt")
    split = "val" if sequence < 10 else "test"
    expected = _windows(labels, poses)
    got = []
    for s in SETS:
        ex = read_set(splits_dir() / "kitti-tracking" / f"{split}.h5", s)
        mine = np.flatnonzero(ex.extras["sequence"] == sequence)
        for i in mine:
            track, frames = int(ex.extras["track"][i]), ex.extras["frames"][i]
            rows = [labels[(track, int(g))] for g in frames]
            got.append((track, int(frames[-1]), rows[0][2]))
            assert s == ("vehicle" if rows[0][2] in {"Car", "Van", "Truck", "Tram"} else "person")
            # the true depths: Z of the labels
            assert ex.depth[i] == float(rows[-1][15])
            assert ex.observation_depth[i].tolist() == [float(r[15]) for r in rows]
            # the boxes as labelled
            assert ex.extras["label_corners"][i].tolist() == [[float(v) for v in r[6:10]] for r in rows]
            # the camera positions in the last camera's axes, from the poses; the sets make the
            # poses' rotations orthonormal (they are so only to about 4e-7): 1e-5 of up to 30 m
            last = poses[int(frames[-1])]
            for k, g in enumerate(frames):
                want = last[:, :3].T @ (poses[int(g)][:, 3] - last[:, 3])
                np.testing.assert_allclose(ex.camera[i, k], want, rtol=0, atol=3e-4)
                rel = last[:, :3].T @ poses[int(g)][:, :3]
                turned = _matrix(ex.extras["orientation"][i, k])
                np.testing.assert_allclose(turned, rel, rtol=0, atol=2e-6)
    assert sorted(got) == sorted(expected) and expected


def test_the_carried_boxes_warped_back_bound_the_labelled_boxes() -> None:
    """The plane carry's definition, checked with the test's own geometry.

    Each carried box's corners, taken back to the observation's orientation and camera,
    have the labelled box as their bounding box.
    """
    ex = read_set(splits_dir() / "kitti-tracking" / "test.h5", "vehicle")
    ref = np.array([[ex.attrs["fx"], 0, ex.attrs["cx"]], [0, ex.attrs["fy"], ex.attrs["cy"]], [0, 0, 1]])
    w, h = ex.attrs["image_width"], ex.attrs["image_height"]
    worst = 0.0
    for i in range(0, len(ex), 7):
        fx, fy, cx, cy = ex.extras["intrinsics"][i]
        own = np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1]])
        for k in range(ex.n_obs):
            x, y, bw, bh = ex.boxes[i, k]
            corners = [(x - bw / 2) * w, (y - bh / 2) * h, (x + bw / 2) * w, (y + bh / 2) * h]
            rel = _matrix(ex.extras["orientation"][i, k])
            back = own @ rel.T @ np.linalg.inv(ref)
            pts = np.array([[u, v, 1.0] for u in corners[0::2] for v in corners[1::2]]) @ back.T
            pts = pts[:, :2] / pts[:, 2:]
            bound = [pts[:, 0].min(), pts[:, 1].min(), pts[:, 0].max(), pts[:, 1].max()]
            worst = max(worst, float(np.abs(np.array(bound) - ex.extras["label_corners"][i, k]).max()))
    assert worst < 1e-3  # the carried corners are kept to 1e-4 pixel


# --- the shipped sets, without the raw files ---------------------------------------------


def test_the_shipped_sets_load_and_score_without_the_raw_files(tmp_path: Path) -> None:
    data = load_split("test", "kitti-tracking", data_dir=tmp_path / "data")
    assert list(data) == list(SETS)
    for s, ex in data.items():
        assert ex.attrs["rules_version"] == 1 and ex.attrs["carry"] == "plane"
        assert ex.intrinsics() == (721.5377, 721.5377, 609.5593, 172.854, 1242.0, 375.0)
        assert ((ex.depth > 2) & (ex.depth < 60)).all() and ex.detected.all()
        assert set(np.unique(ex.extras["sequence"])) <= set(range(10, 21))
        assert len(ex) == read_manifest("kitti-tracking")["splits"]["test"][s]["n"]
    gz = ROOT / "leaderboard" / "entries" / "box-ls" / "kitti-tracking-test" / "predictions.csv.gz"
    preds = tmp_path / "preds.csv"
    preds.write_bytes(gzip.decompress(gz.read_bytes()))
    r = CliRunner().invoke(
        cli,
        [
            "evaluate",
            str(preds),
            "--benchmark",
            "kitti-tracking",
            "--format",
            "json",
            "--data-dir",
            str(tmp_path / "data"),
        ],
    )
    assert r.exit_code == 0, r.output
    result = json.loads(r.stdout)
    assert set(result["sets"]) == set(SETS)


def test_the_box_ls_entry_is_what_its_command_gives(tmp_path: Path) -> None:
    import yaml

    folder = ROOT / "leaderboard" / "entries" / "box-ls" / "kitti-tracking-test"
    entry = yaml.safe_load((folder / "entry.yaml").read_text())
    args = entry["command"].split()
    assert args[:2] == ["odmd-bench", "baseline"] and args[-2:] == ["-o", "predictions.csv"]
    out = tmp_path / "predictions.csv"
    r = CliRunner().invoke(cli, [*args[1:-1], str(out), "--data-dir", str(tmp_path / "data")])
    assert r.exit_code == 0, r.output
    committed = pd.read_csv(io.BytesIO(gzip.decompress((folder / "predictions.csv.gz").read_bytes())))
    rerun = pd.read_csv(out)
    assert committed.drop(columns="depth").equals(rerun.drop(columns="depth"))
    # float64 numpy on another processor may differ in the last bits: 1e-12 relative
    np.testing.assert_allclose(rerun["depth"], committed["depth"], rtol=1e-12, atol=0)


def test_the_board_is_a_board_of_the_leaderboard() -> None:
    from odmd_bench.leaderboard.specs import board_spec

    spec = board_spec("kitti-tracking", "test")
    assert spec.sets == SETS and spec.folder == "kitti-tracking-test"
    methods = {p.parent.name for p in (ROOT / "leaderboard" / "entries").glob("*/kitti-tracking-test")}
    assert {"box-ls", "parallax", "expansion", "robust", "dbox", "dbox-guard"} <= methods
