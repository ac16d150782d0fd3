"""DBox's weights: the registry of shipped checkpoints, and their verification.

Where each shipped checkpoint lives (per configuration, per set, per val benchmark),
which are shipped, the records beside them, and a checkpoint's bytes checked against
the SHA-256 its record (or the caller, or the release's pins) gives. Reading a verified
checkpoint into the network is :mod:`.loading`; which checkpoint runs on given data is
:mod:`.choice`. Nothing here imports torch.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
from pathlib import Path

from odmd_bench import DataError, UsageError, known_originals

WEIGHTS_DIR = Path(__file__).resolve().parent / "weights"
#: The paper's six training configurations.
CONFIGS = ("p", "abs", "ns", "p-z", "ns-z", "abs-z")
#: The benchmark whose val split selects each configuration's top-level shipped weights.
VAL_BENCHMARK = {c: ("odms-detection" if c.endswith("-z") else "odmd-v1") for c in CONFIGS}
#: Checkpoints larger than this are refused before they are read (the network is 2.4 MB).
MAX_WEIGHTS_BYTES = 64 << 20
DEFAULT_WEIGHTS = WEIGHTS_DIR / "dbox_p.pt"
_SHA256 = re.compile(r"[0-9a-f]{64}")


def weights_path(config: str, set_name: str | None = None, selected_on: str | None = None) -> Path:
    """Where the shipped checkpoint of ``config`` lives.

    Args:
        config: the configuration.
        set_name: its per-set checkpoint for this set.
        selected_on: the checkpoint selected on this benchmark's val split when it is not
            the configuration's own (:data:`VAL_BENCHMARK`): ``selected-on-<benchmark>/``.
    """
    folder = WEIGHTS_DIR
    if selected_on is not None and selected_on != VAL_BENCHMARK.get(config):
        folder = WEIGHTS_DIR / f"selected-on-{selected_on}"
    return folder / (f"dbox_{config}.pt" if set_name is None else f"dbox_{config}.{set_name}.pt")


def per_set_path(weights: str | os.PathLike[str], set_name: str) -> Path:
    """The per-set checkpoint beside ``weights``: ``dbox_<config>.<set>.pt``."""
    path = Path(weights)
    return path.with_name(f"{path.stem}.{set_name}{path.suffix}")


def per_set_names(overall: Path, config: str) -> list[str]:
    """The sets with a per-set checkpoint beside ``overall`` (``dbox_<config>.<set>.pt``).

    A shipped per-set checkpoint that is the same file as another of its folder is shipped
    once: its record stands for it (:func:`stored_at`).
    """
    prefix = f"dbox_{config}."
    kept_once = (p.with_suffix(".pt") for p in overall.parent.glob(f"{prefix}*.json"))
    found = {p for p in kept_once if stored_at(p) != p}
    found.update(overall.parent.glob(f"{prefix}*.pt"))
    return sorted(
        p.name[len(prefix) : -len(".pt")] for p in found if "." not in p.name[len(prefix) : -len(".pt")]
    )


def _shipped_folders() -> tuple[Path, ...]:
    """The folders of the shipped checkpoints, resolved: the weights folder and its ``selected-on-*``."""
    return (WEIGHTS_DIR.resolve(), *(d.resolve() for d in WEIGHTS_DIR.glob("selected-on-*")))


#: In a shipped checkpoint's record: the file of its folder that holds the same bytes.
SAME_AS = "same_weights_as"


def stored_at(path: Path) -> Path:
    """Where the bytes of the shipped checkpoint ``path`` are stored.

    The wheel ships a checkpoint once: a per-set checkpoint selected at the same step
    as another of its configuration (the same bytes) has no file of its own, and its
    record names the file that holds them (``"same_weights_as": "dbox_ns-z.pt"``, beside
    it). The bytes are still checked against this record's own ``weights_sha256``.
    Anything else, and any path outside the shipped folders, is stored at itself.
    """
    record = path.with_suffix(".json")
    if path.exists() or path.parent.resolve() not in _shipped_folders() or not record.is_file():
        return path
    try:
        name = json.loads(record.read_text(encoding="utf-8")).get(SAME_AS)
    except (OSError, ValueError, AttributeError):
        return path
    if isinstance(name, str) and re.fullmatch(r"dbox_[a-z-]+(\.[a-z]+)?\.pt", name) and name != path.name:
        return path.with_name(name)
    return path


def shipped() -> dict[str, list[str]]:
    """The shipped configurations and, for each, the sets it has per-set checkpoints for.

    These are the checkpoints selected on the configuration's own val benchmark
    (:data:`VAL_BENCHMARK`); those selected on another sit in ``selected-on-<benchmark>/``.
    """
    return {
        config: per_set_names(weights_path(config), config)
        for config in CONFIGS
        if weights_path(config).is_file()
    }


def training_depth_range(config: str) -> tuple[float, float]:
    """The depths (metres) at the last observation that ``config``'s training data span.

    Derived from the generator preset its JSON record names: the first observation's
    depth range widened by the largest z move (reversed examples end where they began),
    e.g. 0.225 to 1.325 m for the ``odmd`` preset, 0.088 to 1.4625 m for ``odms``.

    Raises:
        UsageError: an unknown configuration; DataError: a record that names no preset.
    """
    from odmd_bench import PRESETS

    if config not in CONFIGS:
        raise UsageError(f"unknown DBox config {config!r}; expected one of {', '.join(CONFIGS)}")
    record = weights_path(config).with_suffix(".json")
    try:
        preset = json.loads(record.read_text(encoding="utf-8"))["config"]["preset"]
        gen = PRESETS[preset]
    except (OSError, ValueError, KeyError, TypeError) as e:
        raise DataError(f"{record}: no generator preset recorded ({e})") from None
    return gen.initial_depth[0] - gen.move_max[2], gen.initial_depth[1] + gen.move_max[2]


def _sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def _recorded_sha256(record: Path) -> str:
    try:
        value = json.loads(record.read_text(encoding="utf-8")).get("weights_sha256")
    except (OSError, ValueError, AttributeError) as e:
        raise DataError(f"cannot read the weights record {record}: {type(e).__name__}: {e}") from None
    if not isinstance(value, str) or not _SHA256.fullmatch(value):
        raise DataError(f"the weights record {record} has no valid weights_sha256 (64 hex digits)")
    return value


def _release_checkpoints() -> dict[str, str]:
    """``{file name: SHA-256}`` of the original release's DBox checkpoints, as pinned."""
    return {
        Path(e["path"]).name: sha
        for sha, e in known_originals().items()
        if e.get("kind") == "dbox-checkpoint"
    }


def verify_weights(
    path: str | os.PathLike[str], weights_sha256: str | None = None, require_record: bool = False
) -> tuple[bytes, str]:
    """Read a checkpoint's bytes and check them against their recorded SHA-256.

    Args:
        path: the checkpoint.
        weights_sha256: the expected hash (64 hex digits); default: the
            ``weights_sha256`` of the JSON record beside the file (same name, ``.json``),
            when there is one.
        require_record: refuse a file with neither (for the shipped weights).

    Returns:
        (the file's bytes, their SHA-256).

    Raises:
        DataError: the file is missing, too large or unreadable, has no record when one
            is required, or its hash differs from the record's.
    """
    path = Path(path)
    record = path.with_suffix(".json")
    stored = stored_at(path)  # a shipped checkpoint kept once for two names: checked against this record
    if not stored.is_file():
        raise DataError(f"DBox weights not found: {stored}")
    if stored.stat().st_size > MAX_WEIGHTS_BYTES:
        raise DataError(
            f"{stored} is {stored.stat().st_size} bytes, more than a DBox checkpoint "
            f"({MAX_WEIGHTS_BYTES >> 20} MB at most): not read"
        )
    try:
        data = stored.read_bytes()
    except OSError as e:
        raise DataError(f"cannot read DBox weights {stored}: {e.strerror or e}") from None
    actual = _sha256(data)
    source = "the given weights_sha256"
    if weights_sha256 is not None:
        expected = weights_sha256.lower()
        if not _SHA256.fullmatch(expected):
            raise UsageError(f"weights_sha256 must be 64 hex digits, got {weights_sha256!r}")
    elif record.is_file():
        expected, source = _recorded_sha256(record), f"its record {record}"
    elif record.exists() or record.is_symlink():  # a folder, a pipe, a link to nothing
        raise DataError(
            f"the record {record} beside the DBox weights {path} is not a regular file, so the "
            "weights cannot be checked against it; remove it, or make it the record of these weights"
        )
    elif (pinned := _release_checkpoints().get(path.name)) is not None:
        # The original release's own checkpoint, known by its name: its pinned hash.
        expected, source = pinned, "the release's hash in splits/odmd-original.json"
    elif require_record:
        raise DataError(
            f"the shipped weights {path} have no record {record.name} beside them to check "
            "them against; reinstall odmd-bench"
        )
    else:
        return data, actual
    if actual != expected:
        if path.parent == WEIGHTS_DIR or path.parent.parent == WEIGHTS_DIR:
            fix = "reinstall odmd-bench to restore the shipped weights"
        elif source.startswith("the release's"):
            fix = "copy the file again from the original release (results/model/DBox_pretrained/)"
        else:
            fix = "restore the file (or retrain it with odmd-bench train-dbox); if it was changed on purpose, record its new hash"
        raise DataError(
            f"DBox weights {path} do not match {source}",
            [f"expected SHA-256 {expected}", f"actual SHA-256   {actual}", f"fix: {fix}"],
        )
    return data, actual


def shipped_config(path: Path, sha: str) -> str | None:
    """The configuration of a shipped checkpoint: by its place and name, or by its hash."""
    here = path.resolve().parent
    if here in _shipped_folders():
        name = path.name.removeprefix("dbox_").split(".")[0]
        if name in CONFIGS:
            return name
    for rec in WEIGHTS_DIR.rglob("dbox_*.json"):
        try:
            if json.loads(rec.read_text(encoding="utf-8")).get("weights_sha256") == sha:
                name = rec.name.removeprefix("dbox_").split(".")[0]
                return name if name in CONFIGS else None
        except (OSError, ValueError, AttributeError):
            continue
    return None


def shipped_name(path: Path) -> str:
    """``path`` inside the shipped weights folder, as provenance names it (``selected-on-odmd-v1/dbox_p-z.pt``)."""
    return path.relative_to(WEIGHTS_DIR).as_posix()
