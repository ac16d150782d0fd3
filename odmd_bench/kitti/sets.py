"""The ``kitti-tracking`` sets: KITTI windows made into examples, and the import that writes them.

A window of a track (:mod:`odmd_bench.kitti.windows`) becomes one example the way
``odmd-bench predict`` makes one of a turning camera's sequence
(:mod:`odmd_bench.predict.orientation`, the same functions): the camera positions in the
last observation's axes (:func:`~odmd_bench.predict.orientation.positions_in_last`), the
boxes carried into the last observation's orientation by the rotation's homography
(:func:`~odmd_bench.predict.orientation.carry_boxes`, ``"plane"``, predict's default),
each with its own sequence's intrinsics. The carried boxes are then mapped into one
reference camera, :data:`REFERENCE` (the calibration of sequences 0000-0013), by the
exact affine map between two pinholes at the same place (``u' = cx' + fx'/fx (u - cx)``),
so that every example of a set shares the set's ``fx, fy, cx, cy`` and image size, as a
method expects (:meth:`~odmd_bench.data.examples.Examples.intrinsics`).

The poses' rotations are first made exactly orthonormal (:func:`orthonormal`), and each
observation's rotation relative to the last (:func:`relative_to_last`) is kept as predict's
quaternion (the ``orientation`` extra), from which the carry's rotations are made.

What is derived is rounded to a fixed grid (carried box corners to 1e-4 pixel, camera
positions to 1e-9 m, the quaternions to 1e-12): the carry's Newton steps use LAPACK, whose
last bits differ between processors, and the pinned content hashes must come out the same
on any machine. The grid is 100 times finer than the labels' own (0.01 pixel, 1e-6 m).
Where arithmetic could go through BLAS (a matrix product), it is written out by element.
"""

from __future__ import annotations

import hashlib
import logging
import os
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from odmd_bench.data.examples import Examples
from odmd_bench.data.hashing import file_sha256, group_attrs
from odmd_bench.data.io import write_sets
from odmd_bench.data.manifests import pin
from odmd_bench.data.registry import Benchmark, get_benchmark, set_file
from odmd_bench.errors import ImportRefused
from odmd_bench.kitti.readers import Camera, Labels, read_camera, read_labels, read_poses
from odmd_bench.kitti.windows import RULES, RULES_VERSION, WindowRules, box_centres, select_windows
from odmd_bench.outputs import clean_stale_temps, locked
from odmd_bench.predict.orientation import (
    Carry,
    carry_boxes,
    positions_in_last,
    quaternions,
    rotation_matrices,
)

log = logging.getLogger("odmd_bench")

#: The benchmark these sets make.
BENCHMARK = "kitti-tracking"

#: The KITTI sequences of each split.
SPLIT_SEQUENCES: dict[str, tuple[int, ...]] = {"val": tuple(range(10)), "test": tuple(range(10, 21))}

#: The camera every example's boxes are expressed in: KITTI's calibration of sequences
#: 0000-0013 (camera 2), the most common of the four.
REFERENCE = Camera(fx=721.5377, fy=721.5377, cx=609.5593, cy=172.854, width=1242.0, height=375.0)

#: How the boxes of the turning camera are carried (:mod:`odmd_bench.predict.orientation`).
CARRY: Carry = "plane"

#: Decimals kept of what is derived (module docstring).
CORNER_DECIMALS, CAMERA_DECIMALS, ROTATION_DECIMALS = 4, 9, 12


@dataclass(frozen=True)
class SequenceFiles:
    """The three files of one sequence."""

    sequence: int
    labels: Path
    poses: Path
    camera: Path


def find_sequences(
    labels: str | os.PathLike[str],
    poses: str | os.PathLike[str] | None = None,
    calib: str | os.PathLike[str] | None = None,
    sequences: tuple[int, ...] = tuple(range(21)),
) -> list[SequenceFiles]:
    """The files of ``sequences``: in three folders, or in one laid out as ``label_02/``, ``poses/``, ``calib/``.

    The camera file of a sequence is ``NNNN.yaml`` (ORB-SLAM3) or else ``NNNN.txt`` (KITTI).

    Raises:
        ImportRefused: a folder or a file missing (every one named).
    """
    if poses is None and calib is None:
        root = Path(labels)
        label_dir, pose_dir, calib_dir = root / "label_02", root / "poses", root / "calib"
    elif poses is not None and calib is not None:
        label_dir, pose_dir, calib_dir = Path(labels), Path(poses), Path(calib)
    else:
        raise ImportRefused(
            "give one folder (with label_02/, poses/, calib/) or three: LABEL_DIR POSE_DIR CALIB_DIR"
        )
    problems = [f"{d}: no such folder" for d in (label_dir, pose_dir, calib_dir) if not d.is_dir()]
    if problems:
        raise ImportRefused("the KITTI tracking files are not all there", problems)
    out = []
    for s in sequences:
        name = f"{s:04d}"
        cam = calib_dir / f"{name}.yaml"
        if not cam.is_file():
            cam = calib_dir / f"{name}.txt"
        files = SequenceFiles(s, label_dir / f"{name}.txt", pose_dir / f"{name}.txt", cam)
        for f, what in (
            (files.labels, "labels"),
            (files.poses, "poses"),
            (files.camera, "camera file (.yaml or .txt)"),
        ):
            if not f.is_file():
                problems.append(f"{f}: missing (the {what} of sequence {name})")
        out.append(files)
    if problems:
        raise ImportRefused("the KITTI tracking files are not all there", problems)
    return out


def orthonormal(r: np.ndarray) -> np.ndarray:
    """The rotations (..., 3, 3) nearest ``r`` by Gram-Schmidt on its columns.

    A pose file's rotations are orthonormal only to its printed digits (ORB-SLAM3's, from
    float32: within about 4e-7); predict's quaternion conversion
    (:func:`~odmd_bench.predict.orientation.quaternions`) reads small turns from the
    diagonal, where such an error is a 1 % error of the turn. Elementwise arithmetic only,
    so the result is the same on every processor.
    """
    a, b = r[..., :, 0], r[..., :, 1]
    a = a / np.sqrt((a * a).sum(axis=-1, keepdims=True))
    b = b - (a * b).sum(axis=-1, keepdims=True) * a
    b = b / np.sqrt((b * b).sum(axis=-1, keepdims=True))
    c = np.stack(
        [
            a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1],
            a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2],
            a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0],
        ],
        axis=-1,
    )
    return np.stack([a, b, c], axis=-1)


def relative_to_last(r: np.ndarray) -> np.ndarray:
    """``R_last^T R_k`` of rotations (N, n_obs, 3, 3), as :func:`~odmd_bench.predict.orientation.relative_rotations`.

    Written out by element: a matrix product may run through BLAS, whose last bits differ
    between processors, and the pinned hashes must not.
    """
    last = r[:, -1:]
    return (last[..., :, :, None] * r[..., :, None, :]).sum(axis=-3)


def _to_reference(corners: np.ndarray, cam: Camera) -> np.ndarray:
    """Pixel corners (..., 4) of camera ``cam`` as those of :data:`REFERENCE` at the same place."""
    if cam.k == REFERENCE.k:
        return corners.copy()
    sx, sy = REFERENCE.fx / cam.fx, REFERENCE.fy / cam.fy
    out = np.empty_like(corners)
    out[..., 0::2] = REFERENCE.cx + sx * (corners[..., 0::2] - cam.cx)
    out[..., 1::2] = REFERENCE.cy + sy * (corners[..., 1::2] - cam.cy)
    return out


@dataclass(frozen=True, eq=False)
class Sequence:
    """One sequence read: its labels, poses and camera."""

    files: SequenceFiles
    labels: Labels
    poses: np.ndarray
    camera: Camera


def read_sequence(files: SequenceFiles, image_size: tuple[float, float] | None = None) -> Sequence:
    """Read the three files of a sequence (each refused with its problems located)."""
    return Sequence(
        files, read_labels(files.labels), read_poses(files.poses), read_camera(files.camera, image_size)
    )


def window_arrays(
    seq: Sequence, rules: WindowRules = RULES
) -> tuple[dict[str, dict[str, np.ndarray]], dict[str, int]]:
    """The examples' arrays of one sequence by set, and how many windows each rule removed.

    Returns:
        ``({set: {array: values}}, counts)``; the arrays are ``corners`` (carried, in
        :data:`REFERENCE`), ``camera``, ``depth``, ``observation_depth`` and the extras
        (docs/kitti.md#arrays).
    """
    windows, counts = select_windows(seq.labels, seq.poses, rules)
    by_set: dict[str, list[int]] = {}
    for i, w in enumerate(windows):
        by_set.setdefault(rules.classes[str(seq.labels.type[w.rows[0]])], []).append(i)
    out: dict[str, dict[str, np.ndarray]] = {}
    for set_name, index in by_set.items():
        rows = np.stack([windows[i].rows for i in index])
        frames = np.stack([windows[i].frames for i in index])
        r = orthonormal(seq.poses[frames, :, :3])
        # Each observation's axes in the last one's, as predict's quaternions (a matrix per
        # observation would be larger than a set's boxes, which a set file may not hold).
        turn = np.round(quaternions(relative_to_last(r)), ROTATION_DECIMALS) + 0.0
        rel = rotation_matrices(turn)
        camera = np.round(positions_in_last(seq.poses[frames, :, 3], r), CAMERA_DECIMALS) + 0.0
        seen = seq.labels.corners[rows]
        carried = carry_boxes(seen, rel, seq.camera.k, CARRY)
        corners = np.round(_to_reference(carried, seq.camera), CORNER_DECIMALS)
        n = len(index)
        out[set_name] = {
            "corners": corners,
            "camera": camera,
            "depth": seq.labels.bottom[rows[:, -1], 2].copy(),
            "observation_depth": seq.labels.bottom[rows, 2].copy(),
            "orientation": turn,
            "label_corners": seen,
            "positions": box_centres(seq.labels, rows),
            "object_size": seq.labels.size[rows[:, -1]].copy(),
            "intrinsics": np.tile(np.array(seq.camera.k), (n, 1)),
            "image_size": np.tile(np.array([seq.camera.width, seq.camera.height]), (n, 1)),
            "sequence": np.full(n, seq.files.sequence, dtype=np.int64),
            "track": np.array([windows[i].track for i in index], dtype=np.int64),
            "frames": frames,
        }
    return out, counts


#: The extras of every set (docs/kitti.md#arrays).
EXTRAS = (
    "orientation",
    "label_corners",
    "positions",
    "object_size",
    "intrinsics",
    "image_size",
    "sequence",
    "track",
    "frames",
)


def source_digest(files: list[SequenceFiles]) -> str:
    """SHA-256 of the input files of a split: of one line ``NNNN kind sha256`` per file, in order."""
    lines = []
    for f in files:
        for kind, path in (("labels", f.labels), ("poses", f.poses), ("camera", f.camera)):
            lines.append(f"{f.sequence:04d} {kind}{path.suffix} {file_sha256(path)}\n")
    return hashlib.sha256("".join(lines).encode()).hexdigest()


def make_split(
    split: str,
    sequences: Mapping[int, Sequence],
    benchmark: Benchmark,
    rules: WindowRules = RULES,
) -> tuple[dict[str, Examples], dict[str, int]]:
    """The sets of one split from its sequences, and the rule counts summed over them.

    Raises:
        ImportRefused: a set would be empty.
    """
    parts: dict[str, list[dict[str, np.ndarray]]] = {s: [] for s in benchmark.sets}
    counts: dict[str, int] = {}
    for s in SPLIT_SEQUENCES[split]:
        arrays, c = window_arrays(sequences[s], rules)
        for k, v in c.items():
            counts[k] = counts.get(k, 0) + v
        for set_name, a in arrays.items():
            parts[set_name].append(a)
    digest = source_digest([sequences[s].files for s in SPLIT_SEQUENCES[split]])
    out: dict[str, Examples] = {}
    empty = [s for s, p in parts.items() if not p]
    if empty:
        raise ImportRefused(f"{benchmark.name} {split}: no windows of {', '.join(empty)} pass the rules")
    for set_name, p in parts.items():
        a = {k: np.concatenate([x[k] for x in p]) for k in p[0]}
        ex = Examples.from_pixels(
            a["corners"],
            a["camera"],
            (REFERENCE.width, REFERENCE.height),
            a["depth"],
            intrinsics=REFERENCE.k,
            observation_depth=a["observation_depth"],
            attrs={
                "benchmark": benchmark.name,
                "split": split,
                "set": set_name,
                "source": "kitti-tracking import",
                "source_sha256": digest,
                "sequences": ",".join(f"{s:04d}" for s in SPLIT_SEQUENCES[split]),
                "rules_version": RULES_VERSION,
                "rules": rules.as_dict(),
                "carry": CARRY,
            },
        )
        ex.extras.update({k: a[k] for k in EXTRAS})
        out[set_name] = ex
    return out, counts


def build_sets(
    labels: str | os.PathLike[str],
    poses: str | os.PathLike[str] | None = None,
    calib: str | os.PathLike[str] | None = None,
    *,
    image_size: tuple[float, float] | None = None,
) -> tuple[dict[str, dict[str, Examples]], dict[str, dict[str, int]]]:
    """Every split's sets from the KITTI files, and per split how many windows each rule removed.

    Every file is read (and refused with its problems) before anything is made.

    Raises:
        ImportRefused: a file missing or refused (every problem of every file named).
    """
    b = get_benchmark(BENCHMARK)
    files = find_sequences(labels, poses, calib)
    sequences: dict[int, Sequence] = {}
    problems: list[str] = []
    for f in files:
        try:
            sequences[f.sequence] = read_sequence(f, image_size)
        except ImportRefused as e:
            problems.append(e.render())
    if problems:
        raise ImportRefused("import refused; nothing was written", problems)
    out: dict[str, dict[str, Examples]] = {}
    counts: dict[str, dict[str, int]] = {}
    for split in b.splits:
        out[split], counts[split] = make_split(split, sequences, b)
    return out, counts


def import_kitti(
    labels: str | os.PathLike[str],
    poses: str | os.PathLike[str] | None = None,
    calib: str | os.PathLike[str] | None = None,
    *,
    data_dir: str | os.PathLike[str] | None = None,
    output: str | os.PathLike[str] | None = None,
    image_size: tuple[float, float] | None = None,
    progress: Callable[[str], None] | None = None,
) -> dict[str, dict[str, Any]]:
    """Import the KITTI tracking files as the ``kitti-tracking`` val and test sets.

    Without ``output`` the sets must be the pinned ones (``splits/kitti-tracking.json``)
    and are written to the data folder (``DATA/kitti-tracking/<split>.h5``); sets made
    from other files (one's own odometry, say) are refused there, naming the hashes, and
    written with ``output`` to ``OUTPUT/val.h5`` and ``OUTPUT/test.h5`` instead. Each file
    is written atomically, under its lock.

    Returns:
        ``{split: {"path": Path, "sets": {set: content hash}, "counts": {rule: windows},
        "pinned": bool}}``.

    Raises:
        ImportRefused: a file refused, or the sets are not the pinned ones without ``output``.
        StorageError: a file cannot be written.
    """
    say = progress or log.warning
    b = get_benchmark(BENCHMARK)
    sets, counts = build_sets(labels, poses, calib, image_size=image_size)
    attrs = {split: {s: group_attrs(ex, s) for s, ex in by_set.items()} for split, by_set in sets.items()}
    differ = []
    for split, hashed in attrs.items():
        for s, a in hashed.items():
            entry = pin(b, split, s)
            for key, what in (("n", "n"), ("sha256", "content_sha256"), ("meta_sha256", "meta_sha256")):
                if str(a[what]) != str(entry[key]):
                    differ.append(
                        f"{split} {s}: {what} {str(a[what])[:16]} differs from the pinned {str(entry[key])[:16]}"
                    )
    if differ and output is None:
        raise ImportRefused(
            "these are not the pinned kitti-tracking sets (other labels, poses or intrinsics than "
            "../shared/kitti-tracking, or another odmd-bench); nothing was written. Give --output DIR "
            "to write them as sets of their own",
            differ,
        )
    out: dict[str, dict[str, Any]] = {}
    for split, by_set in sets.items():
        path = Path(output) / f"{split}.h5" if output is not None else set_file(b, split, data_dir)
        for p in clean_stale_temps(path):
            say(f"removed a dead writer's temporary file {p}")
        with locked(path):
            hashes = write_sets(
                path,
                by_set,
                file_attrs={"benchmark": b.name, "split": split},
                digests={s: attrs[split][s]["content_sha256"] for s in by_set},
            )
        out[split] = {"path": path, "sets": hashes, "counts": counts[split], "pinned": not differ}
    return out


__all__ = [
    "BENCHMARK",
    "CARRY",
    "EXTRAS",
    "REFERENCE",
    "SPLIT_SEQUENCES",
    "Sequence",
    "SequenceFiles",
    "build_sets",
    "find_sequences",
    "import_kitti",
    "make_split",
    "read_sequence",
    "source_digest",
    "window_arrays",
]
