"""Which observations a method is given: chosen evenly for a fixed count, or the missed left out.

:func:`select_observations` keeps ``count`` observations chosen evenly (a method built for
a fixed number, DBox's 10); :func:`omit_missing` leaves each sequence's missed detections
out (``--missing omit``).
"""

from __future__ import annotations

from typing import Literal

import numpy as np

from odmd_bench.data.examples import Examples
from odmd_bench.errors import DataError, UsageError


def select_observations(examples: Examples, count: int) -> Examples:
    """``count`` observations chosen evenly, the first and the last kept.

    Observation ``round((n_obs - 1) * i / (count - 1))`` for ``i = 0 .. count - 1``
    (halves rounded up): distinct because the spacing is at least 1. The last is the
    one whose depth is estimated and the camera stays relative to it.

    Args:
        examples: examples of ``n_obs >= count`` observations.
        count: observations to keep, >= 2.

    Returns:
        The same examples with ``count`` observations (``examples`` itself when
        ``n_obs == count``); ``extras`` with an observation axis are indexed, the
        others dropped.

    Raises:
        DataError: fewer than ``count`` observations.

    Example:
        >>> import odmd_bench
        >>> ex = odmd_bench.generate(2, rng=0)
        >>> select_observations(ex, 4).n_obs
        4
        >>> observation_indices(10, 4).tolist()
        [0, 3, 6, 9]
    """
    if count < 2:
        raise UsageError(f"count must be >= 2, got {count}")
    n_obs = examples.n_obs
    if n_obs < count:
        raise DataError(f"{count} observations are needed, the examples have {n_obs}")
    if n_obs == count:
        return examples
    idx = observation_indices(n_obs, count)
    return Examples(
        boxes=examples.boxes[:, idx],
        detected=examples.detected[:, idx],
        camera=examples.camera[:, idx],
        depth=examples.depth.copy(),
        observation_depth=None if examples.observation_depth is None else examples.observation_depth[:, idx],
        extras={k: v[:, idx] for k, v in examples.extras.items() if v.ndim >= 2 and v.shape[1] == n_obs},
        attrs=dict(examples.attrs),
    )


def observation_indices(n_obs: int, count: int) -> np.ndarray:
    """The ``count`` observation indices :func:`select_observations` keeps out of ``n_obs``."""
    return np.floor(np.linspace(0.0, n_obs - 1, count) + 0.5).astype(np.intp)


#: The rules for missed detections ``predict`` offers.
MISSING: tuple[str, ...] = ("omit", "fill")
Missing = Literal["omit", "fill"]


def omit_missing(examples: Examples) -> tuple[np.ndarray, list[tuple[np.ndarray, Examples, np.ndarray]]]:
    """The examples with their missed observations left out, grouped by what remains.

    Each example keeps its detected observations, in order; where the last observation
    is missed, the last detection becomes the example's last: the camera is taken
    relative to it, and the depth estimated there (along the last observation's optical
    axis, where the boxes were carried) becomes the last observation's by adding the
    detection's camera ``z`` relative to the last, ``shift`` (exact for a static object:
    ``Z_last = Z_j + c_jz``). ``extras`` with an observation axis are indexed alike.

    Args:
        examples: N examples.

    Returns:
        ``(few, parts)``: ``few`` the examples with fewer than 2 detections (nothing to
        estimate from), and per number of detections ``k >= 2`` ``(at, examples, shift)``:
        ``at`` the positions in ``examples``, the k-observation examples, ``shift`` (len(at),).
    """
    det = examples.detected
    k = det.sum(axis=1)
    few = np.flatnonzero(k < 2)
    parts = []
    for count in np.unique(k[k >= 2]).tolist():
        at = np.flatnonzero(k == count)
        # The detected observations' indices, in order: a stable sort puts them first.
        idx = np.argsort(~det[at], axis=1, kind="stable")[:, :count]
        rows = at[:, None]
        cam = examples.camera[rows, idx]
        shift = cam[:, -1, 2].copy()
        extras = {
            key: v[rows, idx]
            for key, v in examples.extras.items()
            if v.ndim >= 2 and v.shape[:2] == det.shape
        }
        sub = Examples(
            boxes=examples.boxes[rows, idx],
            detected=np.ones((at.size, count), dtype=bool),
            camera=cam - cam[:, -1:],
            depth=None if examples.depth is None else examples.depth[at],
            attrs=dict(examples.attrs),
            extras=extras,
        )
        parts.append((at, sub, shift))
    return few, parts


__all__ = ["MISSING", "Missing", "observation_indices", "omit_missing", "select_observations"]
