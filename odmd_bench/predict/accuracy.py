"""Each method's accuracy on realistic scenes (:mod:`odmd_bench.predict.scenes`): the tables of ``docs/own-data.md``.

``python -m odmd_bench.predict.accuracy`` prints them; ``tests/test_own_scenes.py``
checks that the document holds exactly what this prints. Every scene set is seeded, and
every method runs the way ``odmd-bench predict`` runs it (the sequences CSV read back
with :func:`~odmd_bench.predict.sequences.read_sequences`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from odmd_bench.predict.orientation import CARRIES
from odmd_bench.predict.scenes import IMAGE_SIZE, INTRINSICS, Motion, Shape, make_scenes
from odmd_bench.predict.sequences import read_sequences

#: Sequences per scene set (cars, people and signs in turn).
N_SCENES = 60


@dataclass(frozen=True)
class SceneSet:
    """One row of the accuracy table."""

    label: str
    motion: Motion
    turn: float
    noise: bool
    seed: int


SCENE_SETS: tuple[SceneSet, ...] = (
    SceneSet("ground (x, z), no turn", "ground", 0.0, False, 11),
    SceneSet("forward (z), no turn", "forward", 0.0, False, 12),
    SceneSet("free (x, y, z), no turn", "free", 0.0, False, 13),
    SceneSet("ground, turn 15°", "ground", 15.0, False, 14),
    SceneSet("free, turn 15°", "free", 15.0, False, 15),
    SceneSet("ground, no turn, noisy", "ground", 0.0, True, 21),
    SceneSet("forward, no turn, noisy", "forward", 0.0, True, 22),
    SceneSet("free, no turn, noisy", "free", 0.0, True, 23),
    SceneSet("ground, turn 15°, noisy", "ground", 15.0, True, 24),
    SceneSet("free, turn 15°, noisy", "free", 15.0, True, 25),
)

#: The table's columns: a label, the method and its options.
METHODS: tuple[tuple[str, str, dict[str, Any]], ...] = (
    ("box-ls", "box-ls", {}),
    ("expansion", "expansion", {}),
    ("parallax", "parallax", {}),
    ("parallax --combine lsq", "parallax", {"combine": "lsq"}),
    ("robust", "robust", {}),
    ("dbox", "dbox", {}),
)

#: Turns (degrees) of the carry table.
TURNS: tuple[float, ...] = (0.0, 5.0, 10.0, 15.0, 20.0)


def percent_errors(
    scene: SceneSet | tuple[Motion, float, bool, int],
    method: str,
    options: dict[str, Any] | None = None,
    *,
    carry: str = "plane",
    shape: Shape = "plane",
    n: int = N_SCENES,
) -> np.ndarray:
    """(n,) percent errors of ``method`` on a scene set, run as ``predict`` runs it.

    Every sequence is scored, a fallback's stand-in depth included (as the benchmarks
    score them; ``predict`` writes no depth there, with the reason).
    """
    from odmd_bench.predict import predict_sequences

    if isinstance(scene, SceneSet):
        motion, turn, noise, seed = scene.motion, scene.turn, scene.noise, scene.seed
    else:
        motion, turn, noise, seed = scene
    s = make_scenes(n, motion, turn=turn, noise=noise, rng=seed, shape=shape)
    seqs = read_sequences(s.csv().encode(), IMAGE_SIZE, INTRINSICS, carry=carry)  # type: ignore[arg-type]
    result = predict_sequences(seqs, method, **(options or {}))
    return np.asarray(np.abs(np.asarray(result.method_depth) / result.truth - 1) * 100)


def _cell(err: np.ndarray) -> str:
    return f"{err.mean():.2f} ({err.max():.1f})"


def accuracy_table() -> str:
    """Mean (max) percent error of each method on each scene set, as a Markdown table."""
    lines = [
        "| scenes | " + " | ".join(f"`{label}`" for label, _, _ in METHODS) + " |",
        "| --- | " + " | ".join("---" for _ in METHODS) + " |",
    ]
    for scene in SCENE_SETS:
        cells = []
        for _, method, options in METHODS:
            if method == "parallax" and scene.motion == "forward":
                cells.append("n/a")
                continue
            cells.append(_cell(percent_errors(scene, method, options)))
        lines.append(f"| {scene.label} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


#: The objects of the turn tables (:func:`odmd_bench.predict.scenes.make_scenes`).
SHAPES: tuple[str, ...] = ("plane", "ellipsoid", "billboard")

#: The methods of the turn table (DBox's shipped weights do not transfer to these scenes).
TURN_METHODS: tuple[tuple[str, str, dict[str, Any]], ...] = (
    ("box-ls", "box-ls", {}),
    ("expansion", "expansion", {}),
    ("parallax", "parallax", {}),
    ("robust", "robust", {}),
)

#: The scenes of the turn tables: sideways and forward motion, noiseless.
TURN_SCENES: tuple[Motion, int] = ("ground", 31)


def _turn_row(method: str, options: dict[str, Any], carry: str, shape: str) -> str:
    motion, seed = TURN_SCENES
    return " | ".join(
        _cell(percent_errors((motion, t, False, seed), method, options, carry=carry, shape=shape))  # type: ignore[arg-type]
        for t in TURNS
    )


def carry_table() -> str:
    """Box_LS's mean (max) percent error against the turn for each object and way of carrying boxes."""
    lines = [
        "| object | carry | " + " | ".join(f"{t:g}°" for t in TURNS) + " |",
        "| --- | --- | " + " | ".join("---" for _ in TURNS) + " |",
    ]
    for shape in SHAPES:
        for carry in CARRIES:
            lines.append(f"| {shape} | `{carry}` | " + _turn_row("box-ls", {}, carry, shape) + " |")
    return "\n".join(lines) + "\n"


def turn_table() -> str:
    """Each method's mean (max) percent error against the turn, boxes carried as ``predict`` does."""
    lines = [
        "| method | object | " + " | ".join(f"{t:g}°" for t in TURNS) + " |",
        "| --- | --- | " + " | ".join("---" for _ in TURNS) + " |",
    ]
    for label, method, options in TURN_METHODS:
        for shape in SHAPES[:2]:
            lines.append(f"| `{label}` | {shape} | " + _turn_row(method, options, "plane", shape) + " |")
    return "\n".join(lines) + "\n"


def main() -> None:
    """Print the three tables."""
    print(accuracy_table())
    print(carry_table())
    print(turn_table(), end="")


if __name__ == "__main__":
    main()


__all__ = [
    "METHODS",
    "N_SCENES",
    "SCENE_SETS",
    "SHAPES",
    "TURNS",
    "TURN_METHODS",
    "TURN_SCENES",
    "accuracy_table",
    "carry_table",
    "percent_errors",
    "turn_table",
]
