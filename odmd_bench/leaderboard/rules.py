"""The rules an entry's metadata must follow: the required fields' checks, and all of them at once.

:func:`content_problems` runs every rule that depends on the metadata alone; the fields and
their limits are in :mod:`~odmd_bench.leaderboard.entry_fields`, the optional fields' rules
in :mod:`~odmd_bench.leaderboard.optional_fields` (both re-exported here, where the
package's modules import them from).
"""

from __future__ import annotations

import datetime as _dt
import re
from collections.abc import Mapping
from pathlib import Path

from odmd_bench.data.registry import BENCHMARKS, SPLITS
from odmd_bench.leaderboard.entry_fields import (
    CONTROL,
    ENTRY_FILES,
    MAX_LENGTHS,
    MAX_OPTION_CHARS,
    MAX_OPTIONS,
    MAX_PARAMETERS,
    MAX_PLUGIN_BYTES,
    MAX_PLUGIN_FILE_BYTES,
    MAX_PLUGIN_FILES,
    ONE_LINE,
    OPTIONAL_FIELDS,
    PLUGIN_FIELDS,
    REQUIRED_FIELDS,
    SCORE_DECIMALS,
    SELECTED_ON,
    SHOWN_CHARS,
    SPEED_FIELDS,
    SPEED_LENGTHS,
    TRAINING_KINDS,
    show,
    unknown_fields,
)
from odmd_bench.leaderboard.optional_fields import (
    options_problems,
    parameters_problems,
    plugin_problems,
    requirement_name,
    speed_problems,
)
from odmd_bench.leaderboard.specs import BOARDS

_METHOD_ID = re.compile(r"[a-z0-9][a-z0-9._-]*")
_SHA256 = re.compile(r"[0-9a-f]{64}")
_DATE = re.compile(r"\d{4}-\d{2}-\d{2}")
_URL = re.compile(r"https?://\S+")


def method_id_problems(method: str) -> list[str]:
    """Why ``method`` is not a method id (empty when it is one)."""
    if len(method) > MAX_LENGTHS["method"]:
        return [
            f"field 'method' is {len(method)} characters long; at most {MAX_LENGTHS['method']} are allowed"
        ]
    if not _METHOD_ID.fullmatch(method):
        return [f"method {show(method)} must be lowercase letters, digits, '.', '_' or '-'"]
    return []


def latest_date() -> _dt.date:
    """The latest date an entry may have: today anywhere on Earth (UTC+14)."""
    return (_dt.datetime.now(_dt.timezone.utc) + _dt.timedelta(hours=14)).date()


def field_problems(data: Mapping[str, object]) -> tuple[list[str], set[str]]:
    """Unknown, missing, mistyped, too long or control-character fields; and the bad fields."""
    problems: list[str] = []
    bad: set[str] = set()
    known = (*REQUIRED_FIELDS, *OPTIONAL_FIELDS)
    for k in data:
        if k not in known:
            problems.append(
                f"unknown field {show(k)}; the fields are {', '.join(REQUIRED_FIELDS)} "
                f"(optional: {', '.join(OPTIONAL_FIELDS)})"
            )
    for k, what in REQUIRED_FIELDS.items():
        v = data.get(k)
        if v is None or (isinstance(v, str) and not v.strip()):
            problems.append(f"missing field {k!r}: {what}")
            bad.add(k)
    for k, limit in MAX_LENGTHS.items():
        v = data.get(k)
        if v is None or k in bad:
            continue
        if not isinstance(v, str):
            problems.append(f"field {k!r} must be text, got {show(v)}")
        elif len(v) > limit:
            problems.append(f"field {k!r} is {len(v)} characters long; at most {limit} are allowed")
        elif CONTROL.search(v) or (k in ONE_LINE and "\n" in v):
            one = "line breaks or " if k in ONE_LINE else ""
            problems.append(f"field {k!r} must not hold {one}control characters")
        else:
            continue
        bad.add(k)
    return problems, bad


def _identity_problems(data: Mapping[str, object], bad: set[str]) -> list[str]:
    """The method id, benchmark and split, and that they name a board."""
    problems = []
    method, bench, split = (data.get(k) if k not in bad else None for k in ("method", "benchmark", "split"))
    if isinstance(method, str) and not _METHOD_ID.fullmatch(method):
        problems.append(f"method {show(method)} must be lowercase letters, digits, '.', '_' or '-'")
    if isinstance(bench, str) and bench not in BENCHMARKS:
        problems.append(f"unknown benchmark {show(bench)}; expected one of {', '.join(BENCHMARKS)}")
    if isinstance(split, str) and split not in SPLITS:
        problems.append(f"unknown split {show(split)}; expected one of {', '.join(SPLITS)}")
    if (
        bench in BENCHMARKS
        and split in SPLITS
        and not any((b.benchmark, b.split) == (bench, split) for b in BOARDS)
    ):
        problems.append(
            f"there is no board for {bench} {split}; the boards are {', '.join(b.key for b in BOARDS)}"
        )
    return problems


def folder_problems(data: Mapping[str, object], method_folder: str, folder: str) -> list[str]:
    """The folders ``entries/<method>/<benchmark>-<split>/`` an entry must be in."""
    method, bench, split = (data.get(k) for k in ("method", "benchmark", "split"))
    problems = []
    if isinstance(method, str) and _METHOD_ID.fullmatch(method) and method != method_folder:
        problems.append(f"method {show(method)} does not match its folder entries/{method_folder}/")
    if bench in BENCHMARKS and split in SPLITS and folder != f"{bench}-{split}":
        problems.append(
            f"an entry for {bench} {split} must be in a folder named {bench}-{split}, not {folder}"
        )
    return problems


def parse_date(value: object) -> tuple[str | None, list[str]]:
    """The date as ``YYYY-MM-DD``, or the problem."""
    if isinstance(value, _dt.date) and not isinstance(value, _dt.datetime):
        day = value
    elif isinstance(value, str) and _DATE.fullmatch(value):
        try:
            day = _dt.date.fromisoformat(value)
        except ValueError:
            return None, [f"date {show(value)} is not a date YYYY-MM-DD"]
    else:
        return None, [f"date {show(value)} is not a date YYYY-MM-DD"]
    if day > latest_date():
        return None, [f"date {day.isoformat()} is in the future; the predictions must already exist"]
    return day.isoformat(), []


def code_problems(code: object, repo: Path) -> list[str]:
    """``code``: a link, or a path that exists inside ``repo`` once resolved (links followed)."""
    if not isinstance(code, str) or _URL.fullmatch(code):
        return []
    top = repo.resolve()
    target = (top / code).resolve()
    if Path(code).is_absolute() or not target.is_relative_to(top):
        return [f"code {show(code)} is a path outside the repository; give a link or a path in it"]
    parts = code.replace("\\", "/").split("/")
    if any(part in ("", ".", "..") for part in parts):
        # one spelling per file, so that the tests that re-run the commands of this
        # repository's entries (code under baselines/) find every one of them
        plain = "/".join(part for part in parts if part not in ("", "."))
        hint = "without '..'" if ".." in parts else f"write it as {show(plain)}"
        return [f"code {show(code)} is not a plain relative path; {hint}"]
    if not target.exists():
        return [f"code {show(code)} is not {REQUIRED_FIELDS['code']} that exists"]
    return []


def _hash_problems(value: object, bench: object) -> list[str]:
    """``sets_content_sha256``: exactly the benchmark's sets, each with 64 lowercase hex digits."""
    if not isinstance(value, dict):
        return [f"sets_content_sha256 must map each set to its SHA-256, got {show(value)}"]
    problems = []
    if isinstance(bench, str) and bench in BENCHMARKS:
        sets = BENCHMARKS[bench].sets
        missing = [s for s in sets if s not in value]
        extra = [show(s) for s in value if s not in sets]
        if missing:
            problems.append(f"sets_content_sha256 lacks the sets {', '.join(missing)}")
        if extra:
            problems.append(
                f"sets_content_sha256 names unknown sets {', '.join(extra)}; {bench} has {', '.join(sets)}"
            )
    for s, h in value.items():
        if not isinstance(h, str) or not _SHA256.fullmatch(h):
            problems.append(f"sets_content_sha256 of {show(s)} is not 64 lowercase hex digits: {show(h)}")
    return problems


def _predictions_problems(name: object) -> list[str]:
    if not isinstance(name, str):
        return []
    if "/" in name or "\\" in name or name.startswith("."):
        return [f"predictions {show(name)} must be a file name in the entry folder"]
    if not name.endswith((".csv", ".csv.gz")):
        return [f"predictions {show(name)} must be a .csv or .csv.gz file"]
    return []


def content_problems(data: Mapping[str, object]) -> list[str]:
    """Every rule that depends on the metadata alone (not on where it is)."""
    problems, bad = field_problems(data)
    problems += _identity_problems(data, bad)
    if "date" not in bad:
        problems += parse_date(data["date"])[1]
    calibrated = data.get("calibrated")
    if calibrated is not None and not isinstance(calibrated, bool):
        problems.append(f"calibrated must be true or false, got {show(calibrated)}")
    paper = data.get("paper") if "paper" not in bad else None
    if isinstance(paper, str) and paper != "none" and not _URL.fullmatch(paper):
        problems.append(f"paper {show(paper)} is not {REQUIRED_FIELDS['paper']}")
    if "sets_content_sha256" not in bad:
        problems += _hash_problems(data["sets_content_sha256"], data.get("benchmark"))
    if "predictions" not in bad:
        problems += _predictions_problems(data["predictions"])
    problems += honesty_problems(data, bad)
    sha = data.get("predictions_sha256") if "predictions_sha256" not in bad else None
    if isinstance(sha, str) and not _SHA256.fullmatch(sha):
        problems.append(f"predictions_sha256 is not 64 lowercase hex digits: {show(sha)}")
    if "scores" not in bad:
        problems += scores_problems(data["scores"], data.get("benchmark"))
    problems += plugin_problems(data.get("plugin"))
    problems += options_problems(data.get("options"))
    problems += parameters_problems(data.get("parameters"))
    problems += speed_problems(data.get("speed"))
    return problems


def honesty_problems(data: Mapping[str, object], bad: set[str] | frozenset[str] = frozenset()) -> list[str]:
    """``uses_test_labels``, ``selected_on`` and ``training_kind``: declared, and allowed on the board.

    The board ranks methods that never used the test labels: ``uses_test_labels: true`` and
    ``selected_on: test`` (a choice made by the test labels) are refused, with the reason.
    """
    problems = []
    used = data.get("uses_test_labels")
    if used is not None and not isinstance(used, bool):
        problems.append(f"uses_test_labels must be true or false, got {show(used)}")
    elif used is True:
        problems.append(
            "uses_test_labels is true: the board ranks only methods that never used the test labels "
            "(in training, tuning or selection); such a result can be cited in reported.yaml instead"
        )
    selected = data.get("selected_on") if "selected_on" not in bad else None
    if isinstance(selected, str) and selected not in SELECTED_ON:
        problems.append(f"selected_on {show(selected)} is not one of {', '.join(SELECTED_ON)}")
    elif selected == "test":
        problems.append(
            "selected_on is test: a method chosen on the test sets has used their labels; select on val "
            "(or on nothing) and make the predictions again"
        )
    kind = data.get("training_kind") if "training_kind" not in bad else None
    if isinstance(kind, str) and kind not in TRAINING_KINDS:
        problems.append(f"training_kind {show(kind)} is not one of {', '.join(TRAINING_KINDS)}")
    return problems


def scores_problems(value: object, bench: object) -> list[str]:
    """``scores``: every set of the benchmark and ``all``, each a finite number >= 0."""
    if not isinstance(value, dict):
        return [f"scores must map each set (and all) to its mean percent error, got {show(value)}"]
    problems = []
    if isinstance(bench, str) and bench in BENCHMARKS:
        wanted = (*BENCHMARKS[bench].sets, "all")
        missing = [s for s in wanted if s not in value]
        extra = [show(s) for s in value if s not in wanted]
        if missing:
            problems.append(f"scores lack {', '.join(missing)}; run `odmd-bench leaderboard add` again")
        if extra:
            problems.append(f"scores name unknown sets {', '.join(extra)}; {bench} has {', '.join(wanted)}")
    for k, v in value.items():
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0 <= v < float("inf"):
            problems.append(f"scores of {show(k)} must be a number >= 0, got {show(v)}")
    return problems


__all__ = [
    "CONTROL",
    "ENTRY_FILES",
    "MAX_LENGTHS",
    "MAX_OPTIONS",
    "MAX_OPTION_CHARS",
    "MAX_PARAMETERS",
    "MAX_PLUGIN_BYTES",
    "MAX_PLUGIN_FILES",
    "MAX_PLUGIN_FILE_BYTES",
    "ONE_LINE",
    "OPTIONAL_FIELDS",
    "PLUGIN_FIELDS",
    "REQUIRED_FIELDS",
    "SCORE_DECIMALS",
    "SELECTED_ON",
    "SHOWN_CHARS",
    "SPEED_FIELDS",
    "SPEED_LENGTHS",
    "TRAINING_KINDS",
    "code_problems",
    "content_problems",
    "field_problems",
    "folder_problems",
    "honesty_problems",
    "latest_date",
    "method_id_problems",
    "options_problems",
    "parameters_problems",
    "parse_date",
    "plugin_problems",
    "requirement_name",
    "scores_problems",
    "show",
    "speed_problems",
    "unknown_fields",
]
