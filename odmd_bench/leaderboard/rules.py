"""The rules an entry's metadata must follow: its fields, their limits, and each check.

Values from the document are shown in messages only as short quoted text (at most
:data:`SHOWN_CHARS` characters) or by their kind ("a mapping"), never as a ``repr`` of
parsed data.
"""

from __future__ import annotations

import datetime as _dt
import re
from collections.abc import Iterable, Mapping
from pathlib import Path

from odmd_bench.data.registry import BENCHMARKS, SPLITS
from odmd_bench.leaderboard.specs import BOARDS

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

_METHOD_ID = re.compile(r"[a-z0-9][a-z0-9._-]*")
_SHA256 = re.compile(r"[0-9a-f]{64}")
_DATE = re.compile(r"\d{4}-\d{2}-\d{2}")
_URL = re.compile(r"https?://\S+")
_CONTROL = re.compile(r"[\x00-\x09\x0b-\x1f\x7f]")
# A pinned requirement: a PEP 508 distribution name, ``==`` and a PEP 440 version (no
# extras, URLs, markers or wildcards). packaging would parse all of PEP 508, but it is not
# a dependency, and this one shape is all an entry may give.
_REQUIREMENT = re.compile(
    r"([A-Za-z0-9](?:[A-Za-z0-9._-]{0,98}[A-Za-z0-9])?)==([0-9][0-9A-Za-z.+!_-]{0,60})(?<!\*)"
)
_MODULE = re.compile(r"[A-Za-z_][A-Za-z0-9_]*(?:\.[A-Za-z_][A-Za-z0-9_]*){0,9}")
_OPTION = re.compile(r"[a-z][a-z0-9_]{0,39}")
_FOLDER_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_-]{0,39}")


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
        elif _CONTROL.search(v) or (k in ONE_LINE and "\n" in v):
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


def unknown_fields(name: str, value: Mapping[str, object], fields: Iterable[str]) -> list[str]:
    """One line per key of the mapping field ``name`` that is not one of ``fields``."""
    known = list(fields)
    return [
        f"{name}: unknown field {show(k)}; the fields are {', '.join(known)}" for k in value if k not in known
    ]


def plugin_problems(value: object) -> list[str]:
    """``plugin``: absent, or ``{requirement}`` / ``{source, module}`` (``module`` optional with a requirement).

    Where the source folder is and what it holds is checked with the entry's files
    (:func:`odmd_bench.leaderboard.files.read_entry`).
    """
    if value is None:
        return []
    if not isinstance(value, dict):
        return [f"plugin must be a mapping {OPTIONAL_FIELDS['plugin']}, got {show(value)}"]
    problems = unknown_fields("plugin", value, PLUGIN_FIELDS)
    for k in PLUGIN_FIELDS:
        v = value.get(k)
        if k in value and (not isinstance(v, str) or _CONTROL.search(v) or "\n" in v):
            problems.append(f"plugin: {k} must be one line of text, got {show(v)}")
    given = [k for k in ("requirement", "source") if k in value]
    if len(given) != 1:
        problems.append("plugin must give exactly one of requirement (NAME==VERSION) and source (a folder)")
    requirement, source, module = (value.get(k) for k in PLUGIN_FIELDS)
    if isinstance(requirement, str) and not _REQUIREMENT.fullmatch(requirement):
        problems.append(
            f"plugin: requirement {show(requirement)} must be pinned as NAME==VERSION (== only; no "
            "extras, URL, marker or wildcard), so that everyone installs the same code"
        )
    if isinstance(source, str) and not _FOLDER_NAME.fullmatch(source):
        problems.append(
            f"plugin: source {show(source)} must be the name of a folder in the entry folder "
            "(letters, digits, '_', '-'; not a path)"
        )
    if "source" in value and "module" not in value:
        problems.append("plugin: a source needs module, the module in it that is the method")
    if isinstance(module, str) and not _MODULE.fullmatch(module):
        problems.append(f"plugin: module {show(module)} is not a dotted module name")
    return problems


def requirement_name(requirement: str) -> str | None:
    """The distribution name of a pinned requirement ``NAME==VERSION`` (None if it is not one)."""
    m = _REQUIREMENT.fullmatch(requirement)
    return m.group(1) if m else None


def options_problems(value: object) -> list[str]:
    """``options``: absent, or at most :data:`MAX_OPTIONS` ``name: value`` pairs.

    A name is lowercase letters, digits and ``_`` (the keyword the method takes); a value
    is one line of text (at most :data:`MAX_OPTION_CHARS` characters), a number or true/false.
    """
    if value is None:
        return []
    if not isinstance(value, dict):
        return [f"options must be a mapping {OPTIONAL_FIELDS['options']}, got {show(value)}"]
    problems = []
    if len(value) > MAX_OPTIONS:
        problems.append(f"options holds {len(value)} options; at most {MAX_OPTIONS} are allowed")
    for k, v in value.items():
        if not isinstance(k, str) or not _OPTION.fullmatch(k):
            problems.append(
                f"options: name {show(k)} must be lowercase letters, digits and '_' (the method's keyword)"
            )
        if isinstance(v, str):
            if len(v) > MAX_OPTION_CHARS or not v or _CONTROL.search(v) or "\n" in v:
                problems.append(
                    f"options: the value of {show(k)} must be one line of 1 to {MAX_OPTION_CHARS} characters"
                )
        elif isinstance(v, float) and not abs(v) < float("inf"):
            problems.append(f"options: the value of {show(k)} must be a finite number")
        elif not isinstance(v, (bool, int, float)):
            problems.append(
                f"options: the value of {show(k)} must be text, a number or true/false, got {show(v)}"
            )
    return problems


def parameters_problems(value: object) -> list[str]:
    """``parameters``: absent, or a whole number from 0 to :data:`MAX_PARAMETERS`."""
    if value is None:
        return []
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= MAX_PARAMETERS:
        return [f"parameters must be {OPTIONAL_FIELDS['parameters']}, got {show(value)}"]
    return []


def speed_problems(value: object) -> list[str]:
    """``speed``: absent, or exactly the fields of :data:`SPEED_FIELDS`, each as described."""
    if value is None:
        return []
    if not isinstance(value, dict):
        return [f"speed must be a mapping {OPTIONAL_FIELDS['speed']}, got {show(value)}"]
    problems = unknown_fields("speed", value, SPEED_FIELDS)
    problems += [f"speed: missing field {k!r}: {what}" for k, what in SPEED_FIELDS.items() if k not in value]
    rate = value.get("examples_per_second")
    if "examples_per_second" in value and (
        isinstance(rate, bool) or not isinstance(rate, (int, float)) or not 0 < rate < float("inf")
    ):
        problems.append(f"speed: examples_per_second must be a number > 0, got {show(rate)}")
    for k, limit in SPEED_LENGTHS.items():
        v = value.get(k)
        if k not in value:
            continue
        if not isinstance(v, str) or not v.strip():
            problems.append(f"speed: field {k!r} must be text, got {show(v)}")
        elif len(v) > limit:
            problems.append(f"speed: field {k!r} is {len(v)} characters long; at most {limit} are allowed")
        elif _CONTROL.search(v) or "\n" in v:
            problems.append(f"speed: field {k!r} must not hold line breaks or control characters")
    return problems
