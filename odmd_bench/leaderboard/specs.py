"""The boards, as data: which benchmark and split each one ranks, its sets and its title."""

from __future__ import annotations

from dataclasses import dataclass

from odmd_bench.errors import UsageError

#: How tables and plots name each set.
SET_TITLES: dict[str, str] = {
    "normal": "Normal",
    "camera": "Camera",
    "object": "Object",
    "robot": "Robot",
    "perturb": "Perturb",
    "driving": "Driving",
    "vehicle": "Vehicle",
    "person": "Person",
}


@dataclass(frozen=True)
class BoardSpec:
    """One board of the leaderboard.

    Attributes:
        benchmark: the registered benchmark it ranks.
        split: the split it ranks.
        sets: the benchmark's sets, in table order.
        title: a short human title (plot panels, the empty-board line).
    """

    benchmark: str
    split: str
    sets: tuple[str, ...]
    title: str

    @property
    def key(self) -> str:
        """``<benchmark> <split>``, how headings and messages name the board."""
        return f"{self.benchmark} {self.split}"

    @property
    def folder(self) -> str:
        """``<benchmark>-<split>``, the name of an entry folder for this board."""
        return f"{self.benchmark}-{self.split}"


#: Every board, in the order the leaderboard shows them.
BOARDS: tuple[BoardSpec, ...] = (
    BoardSpec("odmd-paper", "test", ("normal", "camera", "object", "robot"), "ODMD, the original release"),
    BoardSpec("odmd-v1", "test", ("normal", "camera", "object", "robot"), "ODMD, generator v1"),
    BoardSpec("odms-detection", "test", ("normal", "perturb", "robot", "driving"), "ODMS converted to boxes"),
    BoardSpec(
        "kitti-tracking", "test", ("vehicle", "person"), "KITTI tracking, static objects (real driving)"
    ),
)


def board_spec(benchmark: str, split: str) -> BoardSpec:
    """The board of ``benchmark`` ``split``.

    Raises:
        UsageError: When there is no such board (the boards are named).
    """
    for spec in BOARDS:
        if (spec.benchmark, spec.split) == (benchmark, split):
            return spec
    raise UsageError(
        f"there is no board for {benchmark} {split}; the boards are {', '.join(b.key for b in BOARDS)}"
    )


#: Decimals kept for floats in leaderboard.json, so that the file does not depend on the
#: last bit of a sum (which may differ between numpy builds).
JSON_DECIMALS = 6


def rounded(x: float) -> float:
    """``x`` rounded as ``leaderboard.json`` keeps floats (:data:`JSON_DECIMALS`; no ``-0.0``)."""
    v = round(float(x), JSON_DECIMALS)
    return 0.0 if v == 0 else v
