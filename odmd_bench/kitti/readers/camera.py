"""A sequence's intrinsics read strictly: ORB-SLAM3's camera file (``.yaml``) or KITTI's ``calib/NNNN.txt``."""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

from odmd_bench.errors import ImportRefused
from odmd_bench.inputs.problems import Problems
from odmd_bench.kitti.readers.text import number, read_text, refuse


@dataclass(frozen=True)
class Camera:
    """A sequence's pinhole camera: ``fx, fy, cx, cy`` in pixels and the image size."""

    fx: float
    fy: float
    cx: float
    cy: float
    width: float
    height: float

    @property
    def k(self) -> tuple[float, float, float, float]:
        """``(fx, fy, cx, cy)``."""
        return (self.fx, self.fy, self.cx, self.cy)


_YAML_KEYS = ("Camera.fx", "Camera.fy", "Camera.cx", "Camera.cy", "Camera.width", "Camera.height")


def read_camera(path: str | os.PathLike[str], image_size: tuple[float, float] | None = None) -> Camera:
    """Read a sequence's intrinsics: ORB-SLAM3's ``.yaml`` camera file or KITTI's ``calib/NNNN.txt``.

    From the ``.yaml`` file, the six keys ``Camera.fx, fy, cx, cy, width, height``
    (each once, positive, finite). From KITTI's ``.txt`` file, ``P2`` (12 numbers:
    ``fx = P2[0]``, ``cx = P2[2]``, ``fy = P2[5]``, ``cy = P2[6]``); it gives no image
    size, so ``image_size`` ``(width, height)`` must be given.

    Raises:
        ImportRefused: a key missing, repeated or not a positive finite number (located).
    """
    p = Path(path)
    text = read_text(p)
    problems = Problems()
    values: dict[str, float]
    where: dict[str, str]
    if p.suffix == ".txt":
        found: dict[str, tuple[list[str], int]] = {}
        for n, raw in enumerate(text.splitlines(), start=1):
            cells = raw.replace(":", " ", 1).split()
            if cells and cells[0] == "P2":
                if "P2" in found:
                    problems.add("P2 given twice", f"line {n} (first on line {found['P2'][1]})", at=n)
                found["P2"] = (cells[1:], n)
        if "P2" not in found:
            raise ImportRefused(
                f"{p}: not a KITTI calibration file", ["no line P2: (camera 2's projection matrix)"]
            )
        cells, n = found["P2"]
        if len(cells) != 12:
            problems.add("P2: expected 12 numbers", f"line {n} ({len(cells)})", at=n)
            refuse(p, problems, "KITTI calibration file")
        p2 = [number(c, problems, f"line {n}", "P2") for c in cells]
        refuse(p, problems, "KITTI calibration file")
        if image_size is None:
            raise ImportRefused(
                f"{p}: a KITTI calibration file gives no image size; give it (--image-size WIDTH HEIGHT)"
            )
        values = {
            "fx": p2[0],
            "fy": p2[5],
            "cx": p2[2],
            "cy": p2[6],
            "width": image_size[0],
            "height": image_size[1],
        }
        where = {k: f"line {n}" for k in values}
    else:
        values, where = {}, {}
        for n, raw in enumerate(text.splitlines(), start=1):
            line = raw.split("#", 1)[0]
            key, sep, rest = line.partition(":")
            key = key.strip()
            if not sep or key not in _YAML_KEYS:
                continue
            short = key.split(".", 1)[1]
            if short in values:
                problems.add(f"{key} given twice", f"line {n} (first on {where[short]})", at=n)
                continue
            values[short] = number(rest.strip(), problems, f"line {n}", key)
            where[short] = f"line {n}"
        missing = [k for k in _YAML_KEYS if k.split(".", 1)[1] not in values]
        if missing:
            problems.add(f"missing {', '.join(missing)} (an ORB-SLAM3 camera file has them)")
    for k, v in values.items():
        if not math.isnan(v) and not v > 0 and k not in ("cx", "cy"):
            problems.add(f"{k} must be > 0", f"{where[k]} ({v:g})")
    refuse(p, problems, "camera file (ORB-SLAM3 .yaml or KITTI calib .txt)")
    return Camera(values["fx"], values["fy"], values["cx"], values["cy"], values["width"], values["height"])
