"""An entry: its metadata as :class:`EntryMeta`, validated on creation, and where it is.

:func:`validate_meta` turns the parsed ``entry.yaml`` (or ``entry.json``) into an
:class:`EntryMeta`, naming every problem at once; the rules are in
:mod:`~odmd_bench.leaderboard.rules`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

from odmd_bench.errors import ValidationError
from odmd_bench.leaderboard.rules import (
    ENTRY_FILES,
    MAX_LENGTHS,
    OPTIONAL_FIELDS,
    PLUGIN_FIELDS,
    REQUIRED_FIELDS,
    SPEED_FIELDS,
    code_problems,
    content_problems,
    field_problems,
    folder_problems,
    parse_date,
    show,
)

__all__ = [
    "ENTRY_FILES",
    "MAX_LENGTHS",
    "OPTIONAL_FIELDS",
    "REQUIRED_FIELDS",
    "Entry",
    "EntryMeta",
    "validate_meta",
]


@dataclass(frozen=True)
class EntryMeta:
    """An entry's checked metadata (the fields of :data:`REQUIRED_FIELDS` and :data:`OPTIONAL_FIELDS`).

    ``date`` is ``YYYY-MM-DD``; ``sets_content_sha256`` keeps the order it was written in.
    """

    method: str
    name: str
    description: str
    paper: str
    code: str
    training_data: str
    command: str
    date: str
    benchmark: str
    split: str
    sets_content_sha256: Mapping[str, str]
    calibrated: bool
    predictions: str
    predictions_sha256: str
    scores: Mapping[str, float]
    uses_test_labels: bool
    selected_on: str
    training_kind: str
    notes: str | None = field(default=None)
    plugin: Mapping[str, str] | None = field(default=None)
    options: Mapping[str, str | int | float | bool] | None = field(default=None)
    parameters: int | None = field(default=None)
    speed: Mapping[str, object] | None = field(default=None)

    def __post_init__(self) -> None:
        problems = content_problems(self.to_dict())
        if problems:
            raise ValidationError(f"entry metadata of {show(self.method)} is incomplete or wrong", problems)

    def to_dict(self) -> dict[str, object]:
        """The fields as a plain mapping, in the documented order (optional ones only when set)."""
        out: dict[str, object] = {k: getattr(self, k) for k in REQUIRED_FIELDS}
        out["sets_content_sha256"] = dict(self.sets_content_sha256)
        out["scores"] = dict(self.scores)
        if self.notes is not None:
            out["notes"] = self.notes
        if self.plugin is not None:
            out["plugin"] = {k: self.plugin[k] for k in PLUGIN_FIELDS if k in self.plugin}
        if self.options is not None:
            out["options"] = dict(self.options)
        if self.parameters is not None:
            out["parameters"] = self.parameters
        if self.speed is not None:
            out["speed"] = {k: self.speed[k] for k in SPEED_FIELDS}
        return out


@dataclass(frozen=True)
class Entry:
    """One method's predictions on one board, with their metadata.

    Attributes:
        folder: the entry folder.
        key: ``<method>/<benchmark>-<split>``, how messages name the entry.
        meta: the checked metadata.
        predictions: the predictions file.
    """

    folder: Path
    key: str
    meta: EntryMeta
    predictions: Path

    @property
    def method(self) -> str:
        """The entry's method name (from its metadata)."""
        return self.meta.method

    @property
    def benchmark(self) -> str:
        """The benchmark the entry is scored on."""
        return self.meta.benchmark

    @property
    def split(self) -> str:
        """The split the entry is scored on."""
        return self.meta.split


def validate_meta(
    data: Mapping[str, object], *, method_folder: str, folder: str, repo: Path
) -> tuple[EntryMeta | None, list[str]]:
    """Check parsed metadata against every rule above, and against where it is.

    Args:
        data: the parsed document.
        method_folder: the name of the method's folder (``entries/<method>/``).
        folder: the name of the entry folder (``<benchmark>-<split>``).
        repo: the repository root, where ``code`` paths are resolved.

    Returns:
        ``(EntryMeta, [])`` when it is good, else ``(None, problems)``, every problem
        named once.
    """
    problems = content_problems(data)
    problems += folder_problems(data, method_folder, folder)
    if "code" not in field_problems(data)[1]:
        problems += code_problems(data.get("code"), repo)
    if problems:
        return None, problems
    text = {k: v for k in MAX_LENGTHS if isinstance(v := data.get(k), str)}
    hashes, scores = data["sets_content_sha256"], data["scores"]
    day = parse_date(data["date"])[0]
    if not isinstance(hashes, dict) or not isinstance(scores, dict) or day is None:  # checked above
        return None, ["sets_content_sha256, scores or date cannot be used"]
    plugin, options = data.get("plugin"), data.get("options")
    meta = EntryMeta(
        method=text["method"],
        name=text["name"],
        description=text["description"],
        paper=text["paper"],
        code=text["code"],
        training_data=text["training_data"],
        command=text["command"],
        date=day,
        benchmark=text["benchmark"],
        split=text["split"],
        sets_content_sha256={str(s): str(h) for s, h in hashes.items()},
        calibrated=data["calibrated"] is True,
        predictions=text["predictions"],
        predictions_sha256=text["predictions_sha256"],
        scores={str(k): float(v) for k, v in scores.items()},
        uses_test_labels=data["uses_test_labels"] is True,
        selected_on=text["selected_on"],
        training_kind=text["training_kind"],
        notes=text.get("notes"),
        plugin={str(k): str(v) for k, v in plugin.items()} if isinstance(plugin, dict) else None,
        options=dict(options) if isinstance(options, dict) else None,
        parameters=parameters if isinstance(parameters := data.get("parameters"), int) else None,
        speed=dict(speed) if isinstance(speed := data.get("speed"), dict) else None,
    )
    return meta, []
