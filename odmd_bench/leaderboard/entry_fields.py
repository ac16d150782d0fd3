"""The fields an entry's metadata may hold, their limits, and how a value is shown in a message.

The vocabulary of :mod:`~odmd_bench.leaderboard.rules` (the required fields' checks) and
:mod:`~odmd_bench.leaderboard.optional_fields` (the optional mappings' checks). Values from
the document are shown in messages only as short quoted text (at most :data:`SHOWN_CHARS`
characters) or by their kind ("a mapping"), never as a ``repr`` of parsed data.
"""

from __future__ import annotations

import datetime as _dt
import re
from collections.abc import Iterable, Mapping

from odmd_bench.data.registry import BENCHMARKS, SPLITS

#: Metadata files an entry folder may hold (exactly one of them).
ENTRY_FILES: tuple[str, ...] = ("entry.yaml", "entry.json")
#: The values of ``selected_on``: ``val`` (chosen on validation sets), ``test`` (chosen on the
#: test sets: refused, a use of the test labels), ``nothing`` (no choice made on any data).
SELECTED_ON: tuple[str, ...] = ("val", "test", "nothing")
#: The values of ``training_kind``: ``none`` (nothing trained or fitted on data), ``generator``
#: (generated examples, the ODMD/ODMS generator), ``real`` (recorded data), ``other``.
TRAINING_KINDS: tuple[str, ...] = ("none", "generator", "real", "other")
#: Fields every entry must have: name -> what is expected.
REQUIRED_FIELDS: dict[str, str] = {
    "method": "the method's id (lowercase letters, digits, '.', '_', '-'), the same as its folder",
    "name": "the name shown in the table",
    "description": "one or two sentences",
    "paper": "an http(s) link, or 'none'",
    "code": "an http(s) link, or a path in this repository",
    "training_data": "what it was trained or tuned on ('none' for analytical methods)",
    "command": "the exact command that produced the predictions",
    "date": "when the predictions were made, YYYY-MM-DD, not in the future",
    "benchmark": f"one of {', '.join(BENCHMARKS)}",
    "split": f"one of {', '.join(SPLITS)}",
    "sets_content_sha256": "{set: SHA-256 of the set's content} for every set the predictions were made for",
    "calibrated": "true if the method uses the camera intrinsics, else false",
    "predictions": "the predictions file in the entry folder (.csv or .csv.gz)",
    "predictions_sha256": "SHA-256 of the predictions' CSV content (after gzip decompression), written by add",
    "scores": "{set: mean percent error, ..., all: their mean}, written by add; check re-scores and compares",
    "uses_test_labels": "whether the test labels were used in any way (training, tuning, selection); "
    "must be false to be on the board",
    "selected_on": f"what the method (weights, hyperparameters, checkpoint) was selected on: one of {', '.join(SELECTED_ON)}",
    "training_kind": f"the kind of training data: one of {', '.join(TRAINING_KINDS)} "
    "(the details go in training_data)",
}
#: Fields an entry may have.
OPTIONAL_FIELDS: dict[str, str] = {
    "notes": "anything else a reader should know",
    "plugin": "how to get a method not shipped in this repository: {requirement: NAME==VERSION} or "
    "{source: FOLDER, module: MODULE} (plain .py files in FOLDER of the entry folder); module optional "
    "with a requirement",
    "options": "{option: value} the method's options the predictions were made with (text, numbers, true/false)",
    "parameters": "the number of trained parameters (network weights) the command runs, a whole number; "
    "0 for a method without trained weights",
    "speed": "{examples_per_second: a number > 0, device: the CPU or GPU model, command: the command "
    "that measured it}",
}
#: The keys of ``plugin``.
PLUGIN_FIELDS: dict[str, str] = {
    "requirement": "a pinned requirement NAME==VERSION, installed with pip install NAME==VERSION",
    "source": "a folder in the entry folder holding the plug-in's plain .py files",
    "module": "the module that is the method (dotted name), e.g. my_package.my_method",
}
#: Most options an entry records, and the longest option value (characters).
MAX_OPTIONS = 20
MAX_OPTION_CHARS = 300
#: Limits of a plug-in's source folder: files, bytes per file, bytes in all.
MAX_PLUGIN_FILES = 50
MAX_PLUGIN_FILE_BYTES = 256 * 1024
MAX_PLUGIN_BYTES = 1024 * 1024
#: Scores agree when equal at this many decimals (``leaderboard.json``'s rounding).
SCORE_DECIMALS = 6

#: The fields of ``speed``: name -> what is expected.
SPEED_FIELDS: dict[str, str] = {
    "examples_per_second": "examples predicted per second, a number > 0",
    "device": "the CPU or GPU model it ran on (one line, at most 200 characters)",
    "command": "the command that measured it (one line, at most 500 characters)",
}
#: Longest text of each text field of ``speed``.
SPEED_LENGTHS: dict[str, int] = {"device": 200, "command": 500}
#: Largest ``parameters`` count accepted (far above any model of this task).
MAX_PARAMETERS = 10**15
#: Longest value of each text field, in characters.
MAX_LENGTHS: dict[str, int] = {
    "method": 40,
    "name": 80,
    "description": 500,
    "paper": 300,
    "code": 300,
    "training_data": 500,
    "command": 500,
    "benchmark": 40,
    "split": 40,
    "predictions": 40,
    "predictions_sha256": 64,
    "selected_on": 40,
    "training_kind": 40,
    "notes": 1000,
}
#: Text fields that must fit on one line (the others may hold newlines, no other control characters).
ONE_LINE: frozenset[str] = frozenset(
    {
        "method",
        "name",
        "paper",
        "code",
        "benchmark",
        "split",
        "predictions",
        "predictions_sha256",
        "selected_on",
        "training_kind",
    }
)
#: How many characters of a value a message shows.
SHOWN_CHARS = 60


#: A control character (a text field may hold a newline where it is not one line).
CONTROL = re.compile(r"[\x00-\x09\x0b-\x1f\x7f]")


def show(value: object) -> str:
    """A value for a message: short quoted text, or its kind (never a repr of parsed data)."""
    if isinstance(value, str):
        return repr(value) if len(value) <= SHOWN_CHARS else repr(value[:SHOWN_CHARS]) + "..."
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return show(str(value))
    kinds = {dict: "a mapping", list: "a list", _dt.date: "a date", type(None): "nothing"}
    return next((k for t, k in kinds.items() if isinstance(value, t)), f"a {type(value).__name__}")


def unknown_fields(name: str, value: Mapping[str, object], fields: Iterable[str]) -> list[str]:
    """One line per key of the mapping field ``name`` that is not one of ``fields``."""
    known = list(fields)
    return [
        f"{name}: unknown field {show(k)}; the fields are {', '.join(known)}" for k in value if k not in known
    ]
