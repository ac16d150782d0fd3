"""The fixed, versioned rules that cut KITTI tracks into examples (docs/kitti.md#rules).

For each track of a kept class, windows of ``n_obs`` observations every ``stride``-th
frame (frames ``f - 18, f - 16, ..., f`` by default) are scanned in the order of their
last frame ``f``. The window ending at ``f`` is taken when all its frames are labelled
and posed, it passes every rule below, and ``f`` is at least ``gap`` frames after the
last frame of the track's previous window taken (one window per track at a time). The
rules, checked in this order (the first that fails is counted against the window):

1. ``static``: the object's world position (its 3-D box centre carried by the pose)
   stays within ``static_m`` of its mean over the window;
2. ``truncated``: KITTI's ``truncated`` is 0 at the last observation;
3. ``occluded``: KITTI's ``occluded`` is at most ``max_occluded`` at the last observation;
4. ``box_height``: every box is at least ``min_box_px`` pixels high;
5. ``travel``: the camera moves at least ``min_travel_m`` (straight line) from the first
   observation to the last;
6. ``depth``: the true depth (``Z`` of the 3-D box centre in the last camera frame) is
   strictly between ``min_depth_m`` and ``max_depth_m``.

Any change that alters which windows are taken is a new :data:`RULES_VERSION` (and new
pins in ``splits/kitti-tracking.json``).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np

from odmd_bench.kitti.readers import Labels

#: The version of :data:`RULES`; recorded in every set made by them.
RULES_VERSION = 1

#: The rules in the order they are checked; the first that fails removes the window.
RULE_NAMES: tuple[str, ...] = ("static", "truncated", "occluded", "box_height", "travel", "depth")


@dataclass(frozen=True)
class WindowRules:
    """The rules of one :data:`RULES_VERSION` (module docstring)."""

    classes: dict[str, str] = field(
        default_factory=lambda: {
            "Car": "vehicle",
            "Van": "vehicle",
            "Truck": "vehicle",
            "Tram": "vehicle",
            "Pedestrian": "person",
            "Person": "person",
            "Person_sitting": "person",
            "Cyclist": "person",
        }
    )
    n_obs: int = 10
    stride: int = 2
    gap: int = 18
    static_m: float = 0.5
    max_truncated: int = 0
    max_occluded: int = 1
    min_box_px: float = 20.0
    min_travel_m: float = 1.0
    min_depth_m: float = 2.0
    max_depth_m: float = 60.0

    def as_dict(self) -> dict[str, object]:
        """The rules as plain data (recorded in each set's attributes)."""
        return {"version": RULES_VERSION, **asdict(self)}


#: The rules of version :data:`RULES_VERSION`.
RULES = WindowRules()


@dataclass(frozen=True, eq=False)
class Window:
    """One window taken: the label rows of its observations, in frame order.

    Attributes:
        track: the track id.
        rows: (n_obs,) indices into the sequence's :class:`~odmd_bench.kitti.readers.Labels`.
        frames: (n_obs,) the frames.
    """

    track: int
    rows: np.ndarray
    frames: np.ndarray


def box_centres(labels: Labels, rows: np.ndarray) -> np.ndarray:
    """(..., 3) the 3-D box centres ``X, Y - h/2, Z`` of label rows, camera frame, metres."""
    centre = labels.bottom[rows].copy()
    centre[..., 1] -= labels.size[rows, 0] / 2
    return centre


def world_points(poses: np.ndarray, frames: np.ndarray, points: np.ndarray) -> np.ndarray:
    """``R_f p + t_f``: points (..., 3) seen at ``frames`` (...) in the world frame.

    Written out by element (not a matrix product) so that the result is the same on every
    processor.
    """
    r = poses[frames, :, :3]
    t = poses[frames, :, 3]
    return (r * points[..., None, :]).sum(axis=-1) + t


def select_windows(
    labels: Labels, poses: np.ndarray, rules: WindowRules = RULES
) -> tuple[list[Window], dict[str, int]]:
    """The windows of one sequence taken by ``rules``, and how many each rule removed.

    Args:
        labels: the sequence's labels.
        poses: (F, 3, 4) camera-to-world poses (frames past ``F`` have none; NaN: none).
        rules: the rules (default: :data:`RULES`).

    Returns:
        ``(windows, counts)``: windows in order of (track, last frame); ``counts`` has
        ``candidates`` (windows fully labelled and posed, of a kept class, not
        overlapping a taken one), one count per rule of :data:`RULE_NAMES` (the windows
        that rule removed, the first failing one counted) and ``taken``.
    """
    counts = dict.fromkeys(("candidates", *RULE_NAMES, "taken"), 0)
    posed = np.isfinite(poses).all(axis=(1, 2))
    offsets = np.arange(-(rules.n_obs - 1) * rules.stride, 1, rules.stride)
    windows: list[Window] = []
    order = np.lexsort((labels.frame, labels.track))
    tracks, starts = np.unique(labels.track[order], return_index=True)
    ends = np.append(starts[1:], len(order))
    for track, a, b in zip(tracks.tolist(), starts.tolist(), ends.tolist(), strict=True):
        rows = order[a:b]
        if str(labels.type[rows[0]]) not in rules.classes:
            continue
        frames_of = labels.frame[rows]
        row_at = np.full(int(frames_of.max()) + 1, -1, dtype=np.int64)
        row_at[frames_of] = rows
        window_frames = frames_of[:, None] + offsets  # (K, n_obs), one window per labelled frame
        inside = (window_frames[:, 0] >= 0) & (window_frames[:, -1] < len(posed))
        window_frames = window_frames[inside]
        take = row_at[window_frames]
        whole = (take >= 0).all(axis=1) & posed[window_frames].all(axis=1)
        window_frames, take = window_frames[whole], take[whole]
        if not len(take):
            continue
        failed = failed_rules(labels, poses, take, window_frames, rules)
        last_taken: int | None = None
        for i, f in enumerate(window_frames[:, -1].tolist()):
            if last_taken is not None and f - last_taken < rules.gap:
                continue
            counts["candidates"] += 1
            if failed[i] >= 0:
                counts[RULE_NAMES[failed[i]]] += 1
                continue
            counts["taken"] += 1
            windows.append(Window(track=int(track), rows=take[i], frames=window_frames[i].astype(np.int64)))
            last_taken = f
    return windows, counts


def failed_rules(
    labels: Labels, poses: np.ndarray, rows: np.ndarray, frames: np.ndarray, rules: WindowRules = RULES
) -> np.ndarray:
    """For each window, the index in :data:`RULE_NAMES` of the first rule it fails, -1 if none.

    Args:
        labels: the sequence's labels.
        poses: (F, 3, 4) camera-to-world poses.
        rows: (K, n_obs) label rows of each window's observations.
        frames: (K, n_obs) their frames.
        rules: the rules (default: :data:`RULES`).

    Returns:
        (K,) int.
    """
    world = world_points(poses, frames, box_centres(labels, rows))  # (K, n_obs, 3)
    spread = np.sqrt(((world - world.mean(axis=1, keepdims=True)) ** 2).sum(axis=-1)).max(axis=1)
    last = rows[:, -1]
    heights = labels.corners[rows, 3] - labels.corners[rows, 1]
    move = poses[frames[:, -1], :, 3] - poses[frames[:, 0], :, 3]
    depth = labels.bottom[last, 2]
    fails = np.stack(
        [
            ~(spread <= rules.static_m),
            labels.truncated[last] > rules.max_truncated,
            labels.occluded[last] > rules.max_occluded,
            ~(heights >= rules.min_box_px).all(axis=1),
            ~(np.sqrt((move * move).sum(axis=1)) >= rules.min_travel_m),
            ~((depth > rules.min_depth_m) & (depth < rules.max_depth_m)),
        ],
        axis=1,
    )
    return np.where(fails.any(axis=1), fails.argmax(axis=1), -1)


__all__ = [
    "RULES",
    "RULES_VERSION",
    "RULE_NAMES",
    "Window",
    "WindowRules",
    "box_centres",
    "failed_rules",
    "select_windows",
    "world_points",
]
