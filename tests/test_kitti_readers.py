"""The strict KITTI readers and the import command.

Every rule refuses with file, line and reason; the import writes nothing when refused;
sets that are not the pinned ones go only where --output says.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from conftest import kitti_dir

from odmd_bench.cli.main import cli
from odmd_bench.errors import ImportRefused
from odmd_bench.kitti.readers import read_camera, read_labels, read_poses

GOOD = "0 0 Car 0 0 -1.79 296.74 161.75 455.22 292.37 2.00 1.82 4.43 -4.55 1.85 13.41 -2.11"
DONTCARE = "0 -1 DontCare -1 -1 -10.000000 219.31 188.49 245.50 218.56 -1000 -1000 -1000 -10 -1 -1 -1"
IDENTITY = "1 0 0 0 0 1 0 0 0 0 1 0"


def _write(tmp_path: Path, name: str, text: str) -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def _refused(reader, path: Path, *args) -> str:  # type: ignore[no-untyped-def]
    with pytest.raises(ImportRefused) as info:
        reader(path, *args)
    text = info.value.render()
    assert str(path) in text
    return text


def test_a_good_label_file_is_read_and_dontcare_dropped(tmp_path: Path) -> None:
    second = GOOD.replace("0 0 Car", "1 0 Car", 1)
    labels = read_labels(_write(tmp_path, "l.txt", f"{DONTCARE}\n{GOOD}\n{second}\n"))
    assert labels.frame.tolist() == [0, 1] and labels.track.tolist() == [0, 0]
    assert labels.corners[0].tolist() == [296.74, 161.75, 455.22, 292.37]
    assert labels.bottom[0].tolist() == [-4.55, 1.85, 13.41] and labels.line.tolist() == [2, 3]


def test_the_clean_file_path_reads_what_the_line_by_line_path_reads(tmp_path: Path) -> None:
    from odmd_bench.kitti.readers.labels import _careful_label_rows, _fast_labels

    lines = [
        DONTCARE,
        GOOD,
        GOOD.replace("0 0 Car", "0 1 Person_sitting 1 2", 1).replace(" 0 0 -1.79", " -1.79", 1),
    ]
    lines.append(GOOD.replace("0 0 Car", "3 0 Car", 1).replace("13.41", "1.5e+01"))
    text = "\n".join(lines) + "\n"
    fast = _fast_labels(text)
    rows = _careful_label_rows(tmp_path / "l.txt", text)
    assert fast is not None and fast.line.tolist() == [r[6] for r in rows] == [2, 3, 4]
    assert fast.type.tolist() == [r[2] for r in rows] == ["Car", "Person_sitting", "Car"]
    assert fast.truncated.tolist() == [r[3] for r in rows] and fast.occluded.tolist() == [r[4] for r in rows]
    assert fast.frame.tolist() == [r[0] for r in rows] and fast.track.tolist() == [r[1] for r in rows]
    assert np.array_equal(np.hstack([fast.corners, fast.size, fast.bottom]), np.array([r[5] for r in rows]))
    assert fast.bottom[2, 2] == 15.0


@pytest.mark.parametrize(
    ("line", "reason"),
    [
        (GOOD.rsplit(" ", 1)[0], "expected 17 fields"),
        (GOOD.replace("13.41", "nan"), "Z: not a finite number"),
        (GOOD.replace("13.41", "inf"), "Z: not a finite number"),
        (GOOD.replace("13.41", "1_3"), "Z: not a number"),
        (GOOD.replace("13.41", "1e999"), "Z: a number too large"),
        (GOOD.replace("Car", "Bus"), "unknown type"),
        (GOOD.replace("Car 0 0", "Car 3 0"), "truncated: not a whole number from 0 to 2"),
        (GOOD.replace("Car 0 0", "Car 0 4"), "occluded: not a whole number from 0 to 3"),
        (GOOD.replace("0 0 Car", "0 -1 Car"), "track_id -1 is only for DontCare"),
        (GOOD.replace("0 0 Car", "0.5 0 Car"), "frame: not a whole number"),
        (GOOD.replace("455.22", "290.00"), "box with x2 <= x1"),
        (GOOD.replace("2.00 1.82", "0 1.82"), "3-D size h, w, l not all > 0"),
    ],
)
def test_a_bad_label_line_is_refused_with_its_line_and_reason(tmp_path: Path, line: str, reason: str) -> None:
    text = _refused(read_labels, _write(tmp_path, "l.txt", f"{GOOD}\n{line}\n"))
    assert reason in text and "line 2" in text


def test_a_track_twice_in_a_frame_or_changing_type_is_refused(tmp_path: Path) -> None:
    text = _refused(read_labels, _write(tmp_path, "l.txt", f"{GOOD}\n{GOOD}\n"))
    assert "a track labelled twice in one frame" in text and "line 2" in text
    changed = GOOD.replace("0 0 Car", "1 0 Van", 1)
    text = _refused(read_labels, _write(tmp_path, "m.txt", f"{GOOD}\n{changed}\n"))
    assert "a track changes type" in text and "line 2" in text


def test_every_problem_of_a_label_file_is_named_at_once(tmp_path: Path) -> None:
    bad = [GOOD.replace("13.41", "nan"), GOOD.replace("Car", "Bus"), "0 1 Car"]
    text = _refused(read_labels, _write(tmp_path, "l.txt", "\n".join([GOOD, *bad]) + "\n"))
    assert "line 2" in text and "line 3" in text and "line 4" in text


def test_an_empty_or_binary_label_file_is_refused(tmp_path: Path) -> None:
    assert "no object lines" in _refused(read_labels, _write(tmp_path, "l.txt", ""))
    p = tmp_path / "b.txt"
    p.write_bytes(b"\xff\xfe\x00garbage")
    assert "not text" in _refused(read_labels, p)


def test_a_good_pose_file_is_read(tmp_path: Path) -> None:
    c, s = np.cos(0.3), np.sin(0.3)
    turned = f"{c} 0 {s} 1.5 0 1 0 0 {-s} 0 {c} 2.0"
    poses = read_poses(_write(tmp_path, "p.txt", f"{IDENTITY}\n{turned}\n\n"))
    assert poses.shape == (2, 3, 4) and poses[1, 0, 3] == 1.5


@pytest.mark.parametrize(
    ("line", "reason"),
    [
        ("1 0 0 0 0 1 0 0 0 0 1", "expected 12 numbers"),
        ("1 0 0 nan 0 1 0 0 0 0 1 0", "not a finite number"),
        ("1 0 0 0 0 1 0 0 0 0 1 x", "not a number"),
        ("2 0 0 0 0 1 0 0 0 0 1 0", "R^T R differs from the identity by 3"),
        ("1 0 0 0 0 1 0 0 0 0 -1 0", "det R = -1"),
        ("0.7 0.7 0 0 0.7 0.7 0 0 0 0 1 0", "not a rotation"),
        ("", "expected 12 numbers"),
    ],
)
def test_a_bad_pose_line_is_refused_with_its_line_and_reason(tmp_path: Path, line: str, reason: str) -> None:
    text = _refused(read_poses, _write(tmp_path, "p.txt", f"{IDENTITY}\n{line}\n{IDENTITY}\n"))
    assert reason in text and "line 2" in text


YAML = "%YAML:1.0\nCamera.fx: 721.5\nCamera.fy: 721.5\nCamera.cx: 609.5\nCamera.cy: 172.8\nCamera.width: 1242\nCamera.height: 375\n"


def test_the_camera_files_are_read(tmp_path: Path) -> None:
    cam = read_camera(_write(tmp_path, "c.yaml", YAML))
    assert (cam.fx, cam.fy, cam.cx, cam.cy, cam.width, cam.height) == (721.5, 721.5, 609.5, 172.8, 1242, 375)
    p2 = "P0: 1 0 0 0 0 1 0 0 0 0 1 0\nP2: 7.215377e+02 0 6.095593e+02 44.85 0 7.215377e+02 1.72854e+02 0.2 0 0 1 0.003\n"
    cam = read_camera(_write(tmp_path, "c.txt", p2), (1242.0, 375.0))
    assert cam.k == (721.5377, 721.5377, 609.5593, 172.854) and cam.width == 1242.0
    assert "gives no image size" in _refused(read_camera, tmp_path / "c.txt")


@pytest.mark.parametrize(
    ("text", "reason"),
    [
        (YAML.replace("Camera.fy: 721.5\n", ""), "missing Camera.fy"),
        (YAML.replace("721.5\nCamera.fy", "nan\nCamera.fy"), "Camera.fx: not a finite number"),
        (YAML.replace("Camera.width: 1242", "Camera.width: -1242"), "width must be > 0"),
        (YAML + "Camera.cx: 600\n", "Camera.cx given twice"),
    ],
)
def test_a_bad_camera_file_is_refused(tmp_path: Path, text: str, reason: str) -> None:
    assert reason in _refused(read_camera, _write(tmp_path, "c.yaml", text))


def test_a_kitti_calibration_without_p2_is_refused(tmp_path: Path) -> None:
    text = _refused(read_camera, _write(tmp_path, "c.txt", "P0: 1 0 0 0 0 1 0 0 0 0 1 0\n"), (1242.0, 375.0))
    assert "no line P2" in text


# --- the import command ---------------------------------------------------------------


def _copy_kitti(tmp_path: Path) -> Path:

    src = kitti_dir()
    dst = tmp_path / "kitti"
    for sub in ("label_02", "poses", "calib"):
        (dst / sub).mkdir(parents=True)
        for f in (src / sub).iterdir():
            (dst / sub / f.name).symlink_to(f)
    return dst


def test_a_refused_import_exits_2_naming_the_file_and_line_and_writes_nothing(tmp_path: Path) -> None:
    kitti = _copy_kitti(tmp_path)
    pose = kitti / "poses" / "0012.txt"
    lines = pose.read_text().splitlines()
    pose.unlink()
    lines[4] = lines[4].replace(lines[4].split()[0], "nan", 1)
    pose.write_text("\n".join(lines) + "\n")
    data = tmp_path / "data"
    r = CliRunner().invoke(cli, ["import", "kitti-tracking", str(kitti), "--data-dir", str(data)])
    assert r.exit_code == 2
    assert (
        f"{pose}: not a pose file" in r.output and "line 5" in r.output and "not a finite number" in r.output
    )
    assert not data.exists() or not any(data.rglob("*.h5"))


@pytest.mark.parametrize("size", [("0", "375"), ("1242", "-375")])
def test_an_image_size_that_is_not_positive_is_refused_first(tmp_path: Path, size: tuple[str, str]) -> None:
    data = tmp_path / "data"
    args = ["import", "kitti-tracking", str(tmp_path / "nowhere"), "--image-size", *size]
    r = CliRunner().invoke(cli, [*args, "--data-dir", str(data)])
    assert (
        r.exit_code == 2 and "--image-size: WIDTH and HEIGHT must be positive numbers of pixels" in r.output
    )
    assert f"got {float(size[0]):g} {float(size[1]):g}" in r.output and not data.exists()


def test_sets_other_than_the_pinned_ones_go_only_to_output(tmp_path: Path) -> None:
    kitti = _copy_kitti(tmp_path)
    pose = kitti / "poses" / "0015.txt"
    lines = pose.read_text().splitlines()
    pose.unlink()
    cells = lines[-1].split()
    cells[11] = f"{float(cells[11]) + 0.25:.9f}"  # one's own odometry: the last pose differs
    pose.write_text("\n".join([*lines[:-1], " ".join(cells)]) + "\n")
    data = tmp_path / "data"
    r = CliRunner().invoke(cli, ["import", "kitti-tracking", str(kitti), "--data-dir", str(data)])
    assert r.exit_code == 2 and "not the pinned kitti-tracking sets" in r.output and "--output" in r.output
    assert not data.exists() or not any(data.rglob("*.h5"))
    out = tmp_path / "own"
    r = CliRunner().invoke(
        cli,
        [
            "import",
            "kitti-tracking",
            str(kitti / "label_02"),
            str(kitti / "poses"),
            str(kitti / "calib"),
            "--output",
            str(out),
        ],
    )
    assert r.exit_code == 0, r.output
    assert "NOT the pinned sets" in r.output
    assert sorted(p.name for p in out.iterdir()) == ["test.h5", "val.h5"]


@pytest.mark.parametrize(
    ("args", "reason"),
    [
        (["import", "kitti-tracking"], "takes one folder"),
        (["import", "kitti-tracking", "a", "b"], "takes one folder"),
        (["import", "kitti-tracking", "nowhere"], "no such folder"),
        (["import", "some.pk", "--output", "x"], "are for `odmd-bench import kitti-tracking`"),
    ],
)
def test_the_import_command_refuses_wrong_arguments(tmp_path: Path, args: list[str], reason: str) -> None:
    r = CliRunner().invoke(cli, args)
    assert r.exit_code == 2 and reason in r.output


def test_a_missing_sequence_file_is_named(tmp_path: Path) -> None:
    kitti = _copy_kitti(tmp_path)
    (kitti / "calib" / "0003.yaml").unlink()
    shutil.rmtree(kitti / "poses")
    (kitti / "poses").mkdir()
    r = CliRunner().invoke(cli, ["import", "kitti-tracking", str(kitti)])
    assert r.exit_code == 2
    assert "0003.txt: missing (the camera file" in r.output and "poses/0000.txt: missing" in r.output
