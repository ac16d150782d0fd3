"""Entry metadata and the hardening of what an entry may hold.

Bounded YAML without aliases, no symbolic links, code paths inside the repository, dates,
bounded text.
"""

from __future__ import annotations

import datetime as dt
import json
import resource
from pathlib import Path

import pytest
import yaml

from odmd_bench import documents
from odmd_bench import leaderboard as lb
from odmd_bench.errors import ValidationError
from odmd_bench.leaderboard.entry import MAX_LENGTHS, EntryMeta
from odmd_bench.leaderboard.rules import latest_date

SETS = ("normal", "camera", "object", "robot")
BOMB = (
    "a: &a [lol, lol, lol, lol, lol, lol, lol, lol, lol]\n"
    + "".join(
        f"{c}: &{c} [{', '.join([f'*{p}'] * 9)}]\n" for p, c in zip("abcdefgh", "bcdefghi", strict=True)
    )
    + "method: *i\n"
)


def _good_meta(**over: object) -> dict[str, object]:
    meta: dict[str, object] = {
        "method": "m",
        "name": "M",
        "description": "d",
        "paper": "none",
        "code": "https://example.org",
        "training_data": "none",
        "command": "cmd",
        "date": "2026-01-02",
        "benchmark": "odmd-v1",
        "split": "test",
        "calibrated": True,
        "sets_content_sha256": {s: "a" * 64 for s in SETS},
        "predictions": "predictions.csv",
        "predictions_sha256": "b" * 64,
        "scores": {**{s: 1.5 for s in SETS}, "all": 1.5},
        "uses_test_labels": False,
        "selected_on": "val",
        "training_kind": "generator",
    }
    return meta | over


def _repo(tmp_path: Path) -> Path:
    """A repository with a code folder and an entry folder; returns the entry folder."""
    (tmp_path / "baselines").mkdir(parents=True, exist_ok=True)
    (tmp_path / "baselines" / "m.py").write_text("")
    folder = tmp_path / "leaderboard" / lb.ENTRIES / "m" / "odmd-v1-test"
    folder.mkdir(parents=True)
    (folder / "predictions.csv").write_text("split,set,index,depth\n")
    return folder


def _write(folder: Path, meta: dict[str, object]) -> Path:
    (folder / "entry.yaml").write_text(yaml.safe_dump(meta))
    return folder


def _problems(folder: Path) -> str:
    with pytest.raises(ValidationError) as info:
        lb.read_entry(folder)
    return info.value.render()


# ----------------------------------------------------------------------------- metadata


def _entry_folder(
    tmp_path: Path, meta: dict[str, object], method: str = "m", name: str = "odmd-v1-test"
) -> Path:
    folder = tmp_path / "leaderboard" / lb.ENTRIES / method / name
    folder.mkdir(parents=True)
    (folder / "predictions.csv").write_text("split,set,index,depth\n")
    (folder / "entry.yaml").write_text(yaml.safe_dump(meta))
    return folder


def test_complete_metadata_is_read(tmp_path: Path) -> None:
    entry = lb.read_entry(_entry_folder(tmp_path, _good_meta()))
    assert entry.key == "m/odmd-v1-test" and entry.meta.calibrated is True
    assert isinstance(entry.meta, lb.EntryMeta) and entry.meta.to_dict() == _good_meta()
    assert entry.predictions.name == "predictions.csv"


def test_incomplete_metadata_names_every_problem(tmp_path: Path) -> None:
    meta = _good_meta()
    del meta["command"]
    meta["paper"] = ""
    meta["date"] = "22/11/2026"
    meta["calibrated"] = "yes"
    meta["colour"] = "blue"
    meta["sets_content_sha256"] = {"normal": "abc"}
    with pytest.raises(ValidationError) as info:
        lb.read_entry(_entry_folder(tmp_path, meta))
    text = info.value.render()
    for expected in (
        "missing field 'command'",
        "missing field 'paper'",
        "date '22/11/2026' is not a date",
        "calibrated must be true or false",
        "unknown field 'colour'",
        "lacks the sets camera, object, robot",
        "sets_content_sha256 of 'normal' is not 64",
    ):
        assert expected in text


def test_metadata_must_match_its_folder(tmp_path: Path) -> None:
    with pytest.raises(ValidationError, match="does not match its folder"):
        lb.read_entry(_entry_folder(tmp_path, _good_meta(), method="other"))


def test_json_metadata_and_a_missing_predictions_file(tmp_path: Path) -> None:
    folder = _entry_folder(tmp_path, _good_meta())
    (folder / "entry.yaml").unlink()
    meta = _good_meta() | {"predictions": "nope.csv.gz"}
    (folder / "entry.json").write_text(json.dumps(meta))
    with pytest.raises(ValidationError, match="predictions file nope.csv.gz is not in the entry folder"):
        lb.read_entry(folder)


# ----------------------------------------------------------------------------- YAML


def test_the_bomb_is_small_and_would_expand_to_a_billion_items() -> None:
    assert len(BOMB) < 1024 and BOMB.count("&") == 9  # 9 ** 9 = 387,420,489 leaves


def test_an_alias_bomb_is_a_clear_error_without_expanding(tmp_path: Path) -> None:
    folder = _repo(tmp_path)
    (folder / "entry.yaml").write_text(BOMB)
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    cap = 2 * 2**30  # 2 GiB: the expanded bomb needs far more
    resource.setrlimit(resource.RLIMIT_AS, (cap if hard == resource.RLIM_INFINITY else min(cap, hard), hard))
    try:
        text = _problems(folder)
    finally:
        resource.setrlimit(resource.RLIMIT_AS, (soft, hard))
    assert "entry.yaml cannot be read: line 1: YAML anchors (&name) are not allowed" in text
    assert "lol" not in text and len(text) < 300


@pytest.mark.parametrize(
    ("doc", "expected"),
    [
        ("method: *x\n", "YAML aliases (*name) are not allowed"),
        ("base: &b {a: 1}\nother:\n  <<: *b\n", "YAML anchors (&name) are not allowed"),
        ("a: " + "[" * 12 + "]" * 12 + "\n", "nested more than 8 levels deep"),
        ("a: !!python/object/apply:os.system [echo]\n", "could not determine a constructor"),
        ("a: 1\n---\nb: 2\n", "expected a single document"),
        ("a: " + "x" * (70 * 1024) + "\n", "bytes; at most 65536 are read"),
    ],
)
def test_unsafe_yaml_is_refused_by_line_and_reason(doc: str, expected: str) -> None:
    with pytest.raises(documents.DocumentError, match=None) as info:
        documents.load_document(doc.encode(), "yaml")
    assert expected in str(info.value) and len(str(info.value)) < 200


def test_deep_json_is_refused_without_a_recursion_error() -> None:
    for depth in (12, 30_000):
        with pytest.raises(documents.DocumentError, match="nested more than 8 levels deep"):
            documents.load_document(b"[" * depth + b"]" * depth, "json")


def test_plain_yaml_and_json_are_read() -> None:
    assert documents.load_document(b"a: [1, {b: x}]\n", "yaml") == {"a": [1, {"b": "x"}]}
    assert documents.load_document(b'{"a": [1]}', "json") == {"a": [1]}
    assert documents.load_document(b"", "yaml") is None


def test_a_mapping_value_is_shown_by_its_kind_never_expanded(tmp_path: Path) -> None:
    folder = _write(_repo(tmp_path), _good_meta(name={"x": ["secret"] * 50}, calibrated=[1, 2]))
    text = _problems(folder)
    assert "field 'name' must be text, got a mapping" in text
    assert "calibrated must be true or false, got a list" in text
    assert "secret" not in text


# ----------------------------------------------------------------------------- symbolic links


def test_a_linked_predictions_file_is_refused_without_reading_it(tmp_path: Path) -> None:
    folder = _write(_repo(tmp_path), _good_meta())
    secret = tmp_path / "secret.txt"
    secret.write_text("root:x:0:0:the first line\n")
    (folder / "predictions.csv").unlink()
    (folder / "predictions.csv").symlink_to(secret)
    text = _problems(folder)
    assert "symbolic links are not allowed" in text
    assert "m/odmd-v1-test/predictions.csv is a symbolic link" in text
    assert "root:x" not in text and str(secret) not in text


@pytest.mark.parametrize("which", ["entry.yaml", "folder", "method", "nested"])
def test_a_link_anywhere_in_an_entry_is_refused(tmp_path: Path, which: str) -> None:
    folder = _write(_repo(tmp_path), _good_meta())
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    if which == "entry.yaml":
        (elsewhere / "entry.yaml").write_text((folder / "entry.yaml").read_text())
        (folder / "entry.yaml").unlink()
        (folder / "entry.yaml").symlink_to(elsewhere / "entry.yaml")
        target = folder
    elif which == "folder":
        target = folder.parent / "odmd-paper-test"
        target.symlink_to(folder)
    elif which == "method":
        target = folder.parents[1] / "other"
        target.symlink_to(folder.parent)
    else:
        (folder / "sub").mkdir()
        (folder / "sub" / "link").symlink_to(elsewhere)
        target = folder
    assert target in lb.discover(tmp_path / "leaderboard") or which == "nested"
    text = _problems(target)
    assert "is a symbolic link" in text and str(elsewhere) not in text


# ----------------------------------------------------------------------------- paths, dates, lengths


@pytest.mark.parametrize(
    "code", ["baselines/../../../../etc/passwd", "/etc/passwd", "../outside", "baselines/../../x"]
)
def test_code_paths_must_stay_inside_the_repository(tmp_path: Path, code: str) -> None:
    folder = _write(_repo(tmp_path), _good_meta(code=code))
    assert "is a path outside the repository" in _problems(folder)


@pytest.mark.parametrize(
    ("code", "plain"),
    [
        ("./baselines/m.py", "baselines/m.py"),
        ("baselines//m.py", "baselines/m.py"),
        ("baselines/./m.py", "baselines/m.py"),
        ("baselines/../baselines/m.py", None),
        ("baselines/", "baselines"),
    ],
)
def test_code_paths_are_written_one_way(tmp_path: Path, code: str, plain: str | None) -> None:
    """``./baselines/x.py`` would hide an entry from the tests that re-run this repository's commands."""
    folder = _write(_repo(tmp_path), _good_meta(code=code))
    problems = _problems(folder)
    assert f"code '{code}' is not a plain relative path" in problems, problems
    assert (f"write it as '{plain}'" if plain is not None else "without '..'") in problems


def test_a_code_link_leaving_the_repository_is_refused(tmp_path: Path) -> None:
    folder = _repo(tmp_path / "repo")
    (tmp_path / "outside.py").write_text("")
    (tmp_path / "repo" / "baselines" / "escape.py").symlink_to(tmp_path / "outside.py")
    _write(folder, _good_meta(code="baselines/escape.py"))
    assert "is a path outside the repository" in _problems(folder)
    _write(folder, _good_meta(code="baselines/m.py"))
    assert lb.read_entry(folder).meta.code == "baselines/m.py"


def test_dates_must_not_be_in_the_future(tmp_path: Path) -> None:
    folder = _write(_repo(tmp_path), _good_meta(date="2999-01-01"))
    assert "date 2999-01-01 is in the future" in _problems(folder)
    tomorrow = latest_date() + dt.timedelta(days=1)
    _write(folder, _good_meta(date=tomorrow.isoformat()))
    assert "is in the future" in _problems(folder)
    _write(folder, _good_meta(date=dt.date.today()))  # a YAML date, today
    assert lb.read_entry(folder).meta.date == dt.date.today().isoformat()


def test_unquoted_impossible_dates_and_times_are_named_not_a_traceback(tmp_path: Path) -> None:
    """YAML's timestamps stay text, so the entry's reader names what is wrong with them."""
    folder = _repo(tmp_path)
    text = yaml.safe_dump(_good_meta(date="DAY")).replace("'DAY'", "DAY").replace("DAY", "{}")
    for day in ("2026-13-01", "2026-02-30", "2026-11-25T10:00:00", "2026-11-25 10:00:00"):
        (folder / "entry.yaml").write_text(text.format(day))
        assert f"date '{day}' is not a date YYYY-MM-DD" in _problems(folder), day
    (folder / "entry.yaml").write_text(text.format("2026-01-02"))  # unquoted and valid: read
    assert lb.read_entry(folder).meta.date == "2026-01-02"
    (folder / "entry.yaml").write_text(text.format("!!timestamp 2026-13-01"))
    assert "a value cannot be read (ValueError: month must be in 1..12)" in _problems(folder)


def test_text_fields_are_bounded_and_not_echoed(tmp_path: Path) -> None:
    huge = "N" * 10_000
    folder = _write(_repo(tmp_path), _good_meta(name=huge, notes="x" * (MAX_LENGTHS["notes"] + 1)))
    text = _problems(folder)
    assert f"field 'name' is 10000 characters long; at most {MAX_LENGTHS['name']} are allowed" in text
    assert f"field 'notes' is {MAX_LENGTHS['notes'] + 1} characters long" in text
    assert "NNNNNNNNNN" not in text
    _write(folder, _good_meta(name="two\nlines", description="ring\x07bell"))
    text = _problems(folder)
    assert "field 'name' must not hold line breaks or control characters" in text
    assert "field 'description' must not hold control characters" in text


def test_an_unknown_field_name_is_shown_shortened(tmp_path: Path) -> None:
    folder = _write(_repo(tmp_path), _good_meta() | {"k" * 500: 1})
    text = _problems(folder)
    assert "unknown field 'kkkk" in text and "k" * 100 not in text


def test_an_entry_needs_a_board(tmp_path: Path) -> None:
    folder = _repo(tmp_path)
    folder = folder.rename(folder.parent / "odmd-v1-val")
    _write(folder, _good_meta(split="val"))
    assert "there is no board for odmd-v1 val; the boards are odmd-paper test, odmd-v1 test" in _problems(
        folder
    )


def test_entry_meta_is_validated_on_creation() -> None:
    good = _good_meta()
    meta = EntryMeta(**good)  # type: ignore[arg-type]
    assert meta.to_dict() == good
    with pytest.raises(ValidationError, match="incomplete or wrong") as info:
        EntryMeta(**(good | {"date": "2999-01-01", "benchmark": "nope"}))  # type: ignore[arg-type]
    assert "unknown benchmark 'nope'" in info.value.render()
    with pytest.raises(AttributeError):
        meta.name = "other"  # type: ignore[misc]


def test_json_metadata_gets_the_same_checks(tmp_path: Path) -> None:
    folder = _repo(tmp_path)
    (folder / "entry.json").write_text(json.dumps(_good_meta(code="../../../etc/passwd")))
    assert "is a path outside the repository" in _problems(folder)


# ----------------------------------------------------------------------------- size and speed


def test_parameters_and_speed_are_read_and_kept(tmp_path: Path) -> None:
    speed = {"examples_per_second": 7228.5, "device": "Intel(R) Xeon(R) Processor", "command": "pytest b.py"}
    meta = _good_meta(parameters=604929, speed=speed)
    entry = lb.read_entry(_entry_folder(tmp_path, meta))
    assert entry.meta.parameters == 604929 and entry.meta.speed == speed
    assert entry.meta.to_dict() == meta
    assert list(entry.meta.to_dict())[-2:] == ["parameters", "speed"]


@pytest.mark.parametrize(
    ("over", "words"),
    [
        ({"parameters": -1}, "parameters must be the number of trained parameters"),
        ({"parameters": 1.5}, "parameters must be"),
        ({"parameters": True}, "parameters must be"),
        ({"parameters": "600k"}, "parameters must be"),
        ({"speed": 7000}, "speed must be a mapping"),
        ({"speed": {"examples_per_second": 1.0, "device": "x"}}, "speed: missing field 'command'"),
        (
            {"speed": {"examples_per_second": 1.0, "device": "x", "command": "c", "threads": 1}},
            "speed: unknown field 'threads'",
        ),
        (
            {"speed": {"examples_per_second": 0, "device": "x", "command": "c"}},
            "examples_per_second must be a number > 0",
        ),
        (
            {"speed": {"examples_per_second": "fast", "device": "x", "command": "c"}},
            "examples_per_second must be",
        ),
        (
            {"speed": {"examples_per_second": 1.0, "device": "a\nb", "command": "c"}},
            "'device' must not hold line breaks",
        ),
        ({"speed": {"examples_per_second": 1.0, "device": "x", "command": "c" * 501}}, "at most 500"),
        ({"speed": {"examples_per_second": 1.0, "device": ["x"], "command": "c"}}, "'device' must be text"),
    ],
)
def test_parameters_and_speed_are_checked(tmp_path: Path, over: dict[str, object], words: str) -> None:
    assert words in _problems(_entry_folder(tmp_path, _good_meta(**over)))


def test_every_problem_of_speed_is_named_at_once(tmp_path: Path) -> None:
    meta = _good_meta(parameters=-5, speed={"examples_per_second": -1, "device": "", "extra": 1})
    text = _problems(_entry_folder(tmp_path, meta))
    for words in (
        "parameters must be",
        "unknown field 'extra'",
        "missing field 'command'",
        "> 0",
        "'device' must be text",
    ):
        assert words in text


# ----------------------------------------------------------------------------- honesty, plug-in, options


def test_the_honesty_fields_are_required_and_test_labels_are_refused(tmp_path: Path) -> None:
    meta = _good_meta()
    for k in ("uses_test_labels", "selected_on", "training_kind"):
        del meta[k]
    text = _problems(_write(_repo(tmp_path), meta))
    for k in ("uses_test_labels", "selected_on", "training_kind"):
        assert f"missing field {k!r}" in text
    bad = _good_meta(uses_test_labels="no", selected_on="train", training_kind="imagenet")
    text = _problems(_write(_repo(tmp_path / "b"), bad))
    assert "uses_test_labels must be true or false, got 'no'" in text
    assert "selected_on 'train' is not one of val, test, nothing" in text
    assert "training_kind 'imagenet' is not one of none, generator, real, other" in text
    text = _problems(_write(_repo(tmp_path / "c"), _good_meta(uses_test_labels=True, selected_on="test")))
    assert "the board ranks only methods that never used the test labels" in text
    assert "selected_on is test: a method chosen on the test sets has used their labels" in text


def test_scores_and_predictions_sha256_are_checked(tmp_path: Path) -> None:
    meta = _good_meta(predictions_sha256="B" * 64, scores={"normal": -1, "camera": "x", "extra": 1.0})
    text = _problems(_write(_repo(tmp_path), meta))
    assert "predictions_sha256 is not 64 lowercase hex digits" in text
    assert "scores lack object, robot, all" in text and "scores name unknown sets 'extra'" in text
    assert (
        "scores of 'normal' must be a number >= 0" in text and "scores of 'camera' must be a number" in text
    )


@pytest.mark.parametrize(
    ("plugin", "problem"),
    [
        ({"requirement": "my-method>=1.0"}, "must be pinned as NAME==VERSION"),
        ({"requirement": "my-method==1.*"}, "must be pinned as NAME==VERSION"),
        ({"requirement": "my-method @ https://x.org/a.whl"}, "must be pinned as NAME==VERSION"),
        ({"requirement": "a==1", "source": "plugin", "module": "m"}, "exactly one of requirement"),
        ({"module": "m"}, "exactly one of requirement"),
        ({"source": "../up", "module": "m"}, "must be the name of a folder in the entry folder"),
        ({"source": "plugin"}, "a source needs module"),
        ({"source": "plugin", "module": "os/path"}, "is not a dotted module name"),
        ({"requirement": "a==1", "url": "x"}, "plugin: unknown field 'url'"),
        ("my-method==1.0", "plugin must be a mapping"),
    ],
)
def test_a_plugin_is_pinned_or_kept_in_the_entry(tmp_path: Path, plugin: object, problem: str) -> None:
    assert problem in _problems(_write(_repo(tmp_path), _good_meta(plugin=plugin)))


def test_a_pinned_requirement_is_read(tmp_path: Path) -> None:
    plugin = {"requirement": "my-method==1.0.2", "module": "my_method.depth"}
    entry = lb.read_entry(_write(_repo(tmp_path), _good_meta(plugin=plugin)))
    assert entry.meta.plugin == plugin and entry.meta.to_dict()["plugin"] == plugin


def test_a_plugin_source_holds_plain_python_files_with_its_module(tmp_path: Path) -> None:
    folder = _repo(tmp_path)
    meta = _good_meta(plugin={"source": "plugin", "module": "mine.depth"})
    _write(folder, meta)
    assert "plugin source plugin/ is not a folder in the entry folder" in _problems(folder)
    (folder / "plugin" / "mine").mkdir(parents=True)
    assert "plugin source plugin/ has no module mine.depth (mine/depth.py or mine/depth/__init__.py)" in (
        _problems(folder)
    )
    (folder / "plugin" / "mine" / "__init__.py").write_text("")
    (folder / "plugin" / "mine" / "depth.py").write_text("def predict(examples):\n    return None\n")
    assert lb.read_entry(folder).meta.plugin == {"source": "plugin", "module": "mine.depth"}
    (folder / "plugin" / "mine" / "weights.bin").write_bytes(b"\0\1")
    (folder / "plugin" / "mine" / "latin.py").write_bytes(b"x = '\xe9'\n")
    (folder / "plugin" / "mine" / "big.py").write_bytes(b"#" * (300 * 1024))
    cache = folder / "plugin" / "mine" / "__pycache__"
    cache.mkdir()
    (cache / "depth.cpython-311.py").write_text("")
    text = _problems(folder)
    assert "plugin source plugin/mine/weights.bin is not a .py file" in text
    assert "plugin source plugin/mine/latin.py is not UTF-8 text" in text
    assert "plugin source plugin/mine/big.py is larger than 256 KiB" in text
    assert "plugin source plugin/mine/__pycache__/depth.cpython-311.py is not a .py file" in text


def test_a_link_in_a_plugin_source_is_refused_unread(tmp_path: Path) -> None:
    folder = _repo(tmp_path)
    _write(folder, _good_meta(plugin={"source": "plugin", "module": "mine"}))
    (folder / "plugin").mkdir()
    secret = tmp_path / "secret.py"
    secret.write_text("TOKEN = 'do not show'\n")
    (folder / "plugin" / "mine.py").symlink_to(secret)
    text = _problems(folder)
    assert "is a symbolic link" in text and "do not show" not in text


@pytest.mark.parametrize(
    ("options", "problem"),
    [
        ({"Config": "p"}, "options: name 'Config' must be lowercase"),
        ({"config": ""}, "must be one line of 1 to 300 characters"),
        ({"config": "a\nb"}, "must be one line of 1 to 300 characters"),
        ({"config": ["a"]}, "must be text, a number or true/false, got a list"),
        ({"scale": float("inf")}, "must be a finite number"),
        ({f"o{i}": i for i in range(21)}, "holds 21 options; at most 20 are allowed"),
        ("config=p", "options must be a mapping"),
    ],
)
def test_options_are_scalars_by_keyword(tmp_path: Path, options: object, problem: str) -> None:
    assert problem in _problems(_write(_repo(tmp_path), _good_meta(options=options)))


def test_options_are_read_with_their_types(tmp_path: Path) -> None:
    options = {"config": "p-z", "selection": "per-set", "steps": 3, "scale": 0.5, "robust": True}
    entry = lb.read_entry(_write(_repo(tmp_path), _good_meta(options=options)))
    assert entry.meta.options == options and entry.meta.to_dict()["options"] == options
    assert {k: type(v) for k, v in entry.meta.options.items()} == {k: type(v) for k, v in options.items()}
