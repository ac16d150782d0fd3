"""Realistic metre-scale scenes for the own-data path: what a new user's data look like.

Cars, people and signs seen from 3 to 30 m by a 640 x 480 camera with ``fx = fy = 500``
(principal point at the centre), ten observations per sequence, as a sequences CSV
(:mod:`odmd_bench.predict.sequences`) with the truth. The tests pin each method's error
on them (``tests/test_own_scenes.py``) and ``python -m odmd_bench.predict.scenes``
prints the accuracy table of ``docs/own-data.md``.

Each object (``shape``) is fixed in the scene:

``"plane"`` (the default)
    a flat rectangle of the object's width and height facing the last observation
    (parallel to its image plane); its box is the bounding box of its four projected
    corners. Without a turn this is the model of the generator and of every method: a
    box centred on the projection of the object's centre, of its width and height times
    ``f`` over its depth.
``"ellipsoid"``
    a round object: an ellipsoid with semi-axes of half the width, half the height and
    half the width, along the last observation's axes; its box is bounded by the tangents
    of its outline. Its box is not that model even without a turn (off the optical axis
    its outline is stretched away from the image centre).
``"billboard"``
    the model itself at every observation, with the depth along the observation's own
    optical axis: with a turn, an object that turns with the camera, which no fixed
    object does (:mod:`odmd_bench.predict.orientation`); kept to show that.

The camera moves on a straight line to its last
position, ``motion``:

``"ground"``
    forward and sideways, never up or down (a robot base, a car): forward travel 20 to
    60 % of the last depth, sideways 10 to 30 % (either way). Lateral motion on one axis.
``"forward"``
    straight ahead only (a walk towards the object).
``"free"``
    forward, sideways and up or down (a hand-held phone): the vertical travel 5 to 20 %.
``"sideways"``
    sideways only, as ``"ground"`` without its forward travel (a camera on a rail, a
    car passing a sign): what the methods that read depth from the boxes' growth
    cannot solve.

``forward_travel`` sets the range of the forward travel (a share of the last depth;
default 20 to 60 %).

With ``turn`` (degrees) the camera also turns while moving: by ``turn`` at the first
observation relative to the last, shrinking linearly to 0, about an axis near the
vertical (a car on a bend, a phone panned), and its orientation is written in the
quaternion columns. The last orientation is random in the fixed frame.

``noise=True`` adds what real data have: 1 px Gaussian noise on each box corner, one in
ten observations missed (never the last), odometry drift (a random walk of 2 % of each
step, per axis) and 0.2 degrees of orientation noise per observation.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Literal

import numpy as np

from odmd_bench.data.generator import as_rng
from odmd_bench.errors import UsageError
from odmd_bench.predict.orientation import quaternions, rotation_matrices

Motion = Literal["ground", "forward", "free", "sideways"]
Shape = Literal["billboard", "plane", "ellipsoid"]
MOTIONS: tuple[str, ...] = ("ground", "forward", "free", "sideways")
#: Object kinds: (width, height) in metres.
OBJECTS: dict[str, tuple[float, float]] = {"car": (1.8, 1.5), "person": (0.5, 1.75), "sign": (0.6, 0.6)}
IMAGE_SIZE = (640.0, 480.0)
INTRINSICS = (500.0, 500.0, 320.0, 240.0)
N_OBS = 10
DEPTH_RANGE = (3.0, 30.0)


@dataclass(frozen=True)
class Scenes:
    """Sequences of one kind, as a user would record them.

    Attributes:
        names: (N,) sequence names (``car-0``, ...).
        corners: (N, n_obs, 4) boxes ``x1, y1, x2, y2`` in pixels, NaN where missed.
        positions: (N, n_obs, 3) camera centres in the fixed frame, metres.
        orientation: (N, n_obs, 4) quaternions ``x, y, z, w`` (camera to fixed frame).
        depth: (N,) the true depth at the last observation, along its optical axis.
        turn: the turn (degrees) the scenes were made with.
        oriented: whether the orientation is part of the data (else the fixed frame
            has the camera's axes, and the CSV has no quaternion columns).
    """

    names: tuple[str, ...]
    corners: np.ndarray
    positions: np.ndarray
    orientation: np.ndarray
    depth: np.ndarray
    turn: float
    oriented: bool = True

    def csv(self, orientation: bool | None = None) -> str:
        """The sequences CSV, the truth on each last row.

        Args:
            orientation: write the quaternion columns (default: :attr:`oriented`).
        """
        if orientation is None:
            orientation = self.oriented
        header = "sequence,observation,x1,y1,x2,y2,cam_x,cam_y,cam_z"
        if orientation:
            header += ",cam_qx,cam_qy,cam_qz,cam_qw"
        lines = [header + ",depth"]
        n, n_obs = self.corners.shape[:2]

        def cell(v: float) -> str:
            return "" if v != v else repr(v)

        for i in range(n):
            for k in range(n_obs):
                cells = [self.names[i], str(k)]
                cells += [cell(v) for v in self.corners[i, k].tolist()]
                cells += [repr(v) for v in self.positions[i, k].tolist()]
                if orientation:
                    cells += [repr(v) for v in self.orientation[i, k].tolist()]
                cells.append(repr(float(self.depth[i])) if k == n_obs - 1 else "")
                lines.append(",".join(cells))
        return "\n".join(lines) + "\n"


def _axis_rotation(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Rotations (..., 3, 3) by ``angle`` (radians, (...)) about unit ``axis`` (..., 3)."""
    half = angle / 2
    q = np.concatenate([axis * np.sin(half)[..., None], np.cos(half)[..., None]], axis=-1)
    return rotation_matrices(q)


def make_scenes(
    n: int,
    motion: Motion = "ground",
    turn: float = 0.0,
    noise: bool = False,
    rng: int | np.random.Generator | None = 0,
    *,
    oriented: bool | None = None,
    shape: Shape = "plane",
    image_size: tuple[float, float] = IMAGE_SIZE,
    intrinsics: tuple[float, float, float, float] = INTRINSICS,
    forward_travel: tuple[float, float] = (0.2, 0.6),
) -> Scenes:
    """``n`` sequences of cars, people and signs (module docstring).

    Args:
        n: number of sequences (cars, people and signs in turn).
        motion: ``"ground"``, ``"forward"`` or ``"free"``.
        turn: the camera's turn between the first and the last observation, degrees.
        noise: add box noise, missed detections, odometry drift and orientation noise.
        rng: seed or generator.
        oriented: the fixed frame is turned at random and the orientation is written
            (default: where the camera turns); else the fixed frame has the camera's axes.
        shape: the object (module docstring): ``"plane"``, ``"ellipsoid"`` or
            ``"billboard"``.
        image_size: ``(W, H)`` of the camera's images (default 640 x 480).
        intrinsics: ``(fx, fy, cx, cy)`` (default fx = fy = 500 at the centre).
        forward_travel: the range of the forward travel, a share of the last depth
            (``"sideways"``: none).

    Returns:
        :class:`Scenes`, every object in view of every observation.

    Example:
        >>> s = make_scenes(3, "ground", turn=10.0, rng=1)
        >>> s.corners.shape, bool((s.depth >= 3).all() and (s.depth <= 30).all())
        ((3, 10, 4), True)
    """
    if motion not in MOTIONS:
        raise UsageError(f"unknown motion {motion!r}; expected one of {', '.join(MOTIONS)}")
    if shape not in ("billboard", "plane", "ellipsoid"):
        raise UsageError(f"unknown shape {shape!r}; expected billboard, plane or ellipsoid")
    if oriented is None:
        oriented = turn > 0
    gen = as_rng(rng)
    fx, fy, cx, cy = intrinsics
    width, height = image_size
    kinds = list(OBJECTS)
    out: dict[str, list[np.ndarray]] = {k: [] for k in ("corners", "pos", "rot", "depth", "size")}
    got = 0
    while got < n:
        m = 2 * (n - got) + 8
        size = np.array([OBJECTS[kinds[(got + i) % 3]] for i in range(m)])
        z = np.exp(gen.uniform(np.log(DEPTH_RANGE[0]), np.log(DEPTH_RANGE[1]), m))
        # The object's centre in the last camera's axes: near the middle of its view.
        obj = np.stack(
            [z * gen.uniform(-0.15, 0.15, m) * width / fx, z * gen.uniform(-0.1, 0.1, m) * height / fy, z],
            axis=1,
        )
        travel = np.zeros((m, 3))
        travel[:, 2] = -z * gen.uniform(*forward_travel, m)  # the first position is further back
        if motion == "sideways":
            travel[:, 2] = 0.0
        if motion in ("ground", "free", "sideways"):
            travel[:, 0] = z * gen.uniform(0.1, 0.3, m) * gen.choice([-1.0, 1.0], m)
        if motion == "free":
            travel[:, 1] = z * gen.uniform(0.05, 0.2, m) * gen.choice([-1.0, 1.0], m)
        t = np.linspace(0.0, 1.0, N_OBS)
        offset = (1 - t)[None, :, None] * travel[:, None, :]  # camera k relative to the last, last axes
        axis = np.stack([gen.uniform(-0.3, 0.3, m), np.ones(m), np.zeros(m)], axis=1)
        axis /= np.linalg.norm(axis, axis=1, keepdims=True)
        angle = np.radians(turn) * gen.choice([-1.0, 1.0], m)
        rel = _axis_rotation(axis[:, None, :], angle[:, None] * (1 - t)[None, :])  # camera k -> last axes
        if noise:
            jitter = gen.normal(0.0, 1.0, (m, N_OBS, 3))
            jitter /= np.linalg.norm(jitter, axis=2, keepdims=True)
            wobble = _axis_rotation(jitter, np.radians(gen.normal(0.0, 0.2, (m, N_OBS))))
            measured_rel = rel @ wobble
        else:
            measured_rel = rel
        # The object in each camera's axes: rel_k^T (obj - offset_k).
        p = np.einsum("nkji,nkj->nki", rel, obj[:, None, :] - offset)
        pz = p[..., 2]
        u = cx + fx * p[..., 0] / pz
        v = cy + fy * p[..., 1] / pz
        hw = fx * size[:, 0:1] / pz / 2
        hh = fy * size[:, 1:2] / pz / 2
        corners = np.stack([u - hw, v - hh, u + hw, v + hh], axis=-1)
        if shape == "plane" and turn != 0:  # (without a turn the billboard's box, to the last bit)
            us, vs = [], []
            for sx, sy in ((-1, -1), (1, -1), (-1, 1), (1, 1)):
                corner = obj + np.stack([sx * size[:, 0] / 2, sy * size[:, 1] / 2, np.zeros(m)], axis=1)
                q = np.einsum("nkji,nkj->nki", rel, corner[:, None, :] - offset)
                us.append(cx + fx * q[..., 0] / q[..., 2])
                vs.append(cy + fy * q[..., 1] / q[..., 2])
            su, sv = np.stack(us), np.stack(vs)
            corners = np.stack([su.min(axis=0), sv.min(axis=0), su.max(axis=0), sv.max(axis=0)], axis=-1)
        if shape == "ellipsoid":
            # Semi-axes W/2, H/2, W/2 along the last camera's axes; the box is bounded by the
            # tangent lines of the outline, the dual conic K (M_k^-1 - p p^T) K^T.
            kmat = np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])
            semi = np.stack([size[:, 0] / 2, size[:, 1] / 2, size[:, 0] / 2], axis=1)
            minv = np.einsum("nkji,nj,nkjl->nkil", rel, semi**2, rel)
            g = minv - p[..., :, None] * p[..., None, :]
            dual = np.einsum("ij,nkjl,ml->nkim", kmat, g, kmat)
            ends = []
            for a in (0, 1):
                c00, c02, c22 = dual[..., a, a], dual[..., a, 2], dual[..., 2, 2]
                root = np.sqrt(c02 * c02 - c00 * c22)
                ends.append(((c02 - root) / c22, (c02 + root) / c22))
            lo_u, hi_u = np.minimum(*ends[0]), np.maximum(*ends[0])
            lo_v, hi_v = np.minimum(*ends[1]), np.maximum(*ends[1])
            corners = np.stack([lo_u, lo_v, hi_u, hi_v], axis=-1)
        inside = (
            (pz > 0.5).all(axis=1)
            & (corners[..., 0] > 0).all(axis=1)
            & (corners[..., 1] > 0).all(axis=1)
            & (corners[..., 2] < width).all(axis=1)
            & (corners[..., 3] < height).all(axis=1)
        )
        keep = np.flatnonzero(inside)[: n - got]
        # The fixed frame: the last camera at a random place, turned by a random rotation.
        base_axis = gen.normal(0.0, 1.0, (keep.size, 3))
        base_axis /= np.linalg.norm(base_axis, axis=1, keepdims=True)
        base = _axis_rotation(base_axis, gen.uniform(0, np.pi, keep.size) * oriented)
        origin = gen.uniform(-50.0, 50.0, (keep.size, 3))
        offs = offset[keep]
        if noise:
            steps = np.diff(offs, axis=1)
            drift = gen.normal(0.0, 0.02, steps.shape) * np.linalg.norm(steps, axis=2, keepdims=True)
            # Drift accumulates from the first observation on; positions stay relative to the last.
            walk = np.concatenate([np.zeros((keep.size, 1, 3)), np.cumsum(drift, axis=1)], axis=1)
            offs = offs + walk - walk[:, -1:]
            corners = corners + gen.normal(0.0, 1.0, corners.shape)
            missed = gen.random((m, N_OBS)) < 0.1
            missed[:, -1] = False
            corners[missed] = np.nan
        pos = origin[:, None, :] + np.einsum("nij,nkj->nki", base, offs)
        rot = base[:, None] @ measured_rel[keep]
        out["corners"].append(corners[keep])
        out["pos"].append(pos)
        out["rot"].append(rot)
        out["depth"].append(z[keep])
        out["size"].append(size[keep])
        got += keep.size
    sizes = np.concatenate(out["size"])
    names = tuple(
        f"{next(k for k, s in OBJECTS.items() if s == tuple(sz))}-{i}" for i, sz in enumerate(sizes.tolist())
    )
    return Scenes(
        names=names,
        corners=np.concatenate(out["corners"]),
        positions=np.concatenate(out["pos"]),
        orientation=quaternions(np.concatenate(out["rot"])),
        depth=np.concatenate(out["depth"]),
        turn=float(turn),
        oriented=bool(oriented),
    )


#: The phone of the worked example (docs/own-data.md): 12 megapixels, fx = fy = 3100.
PHONE_SIZE = (4032.0, 3024.0)
PHONE_INTRINSICS = (3100.0, 3100.0, 2016.0, 1512.0)


def phone_example(rng: int = 3) -> Scenes:
    """The worked example's turning phone (``docs/sequences-turning.csv``).

    Three objects photographed ten times each while walking on flat ground and turning
    the phone by up to 12 degrees, with the noise of :func:`make_scenes` (hand-held
    jitter as odometry drift, the motion sensor's orientation noise, one in ten
    pictures missed) and the boxes rounded to whole pixels, as a detector writes them.
    """
    s = make_scenes(
        3,
        "ground",
        turn=12.0,
        noise=True,
        rng=rng,
        image_size=PHONE_SIZE,
        intrinsics=PHONE_INTRINSICS,
    )
    return dataclasses.replace(
        s,
        corners=np.round(s.corners),
        positions=np.round(s.positions, 3),
        orientation=np.round(s.orientation, 6),
    )


__all__ = [
    "IMAGE_SIZE",
    "INTRINSICS",
    "MOTIONS",
    "OBJECTS",
    "PHONE_INTRINSICS",
    "PHONE_SIZE",
    "Scenes",
    "make_scenes",
    "phone_example",
]


if __name__ == "__main__":  # python -m odmd_bench.predict.scenes > docs/sequences-turning.csv
    print(phone_example().csv(), end="")
