"""DBox's weights: registry, verification, loading.

The shipped checkpoints and which one runs on which data; a checkpoint's hash checked
against its record; the file read and checked key by key, with its input formulation.
Nothing here imports torch at import time; loading does.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import re
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from odmd_bench_baselines.dbox.configs import CONFIGS as TRAIN_CONFIGS

from odmd_bench import MAX_ABS_WEIGHT, DataError, Examples, UsageError, known_originals

if TYPE_CHECKING:
    from odmd_bench_baselines.dbox.model import DBox

WEIGHTS_DIR = Path(__file__).resolve().parent / "weights"
#: The paper's six training configurations.
CONFIGS = ("p", "abs", "ns", "p-z", "ns-z", "abs-z")
#: ``overall``: one network chosen on val All; ``per-set``: one per set, chosen on that set.
SELECTIONS = ("overall", "per-set")
#: Benchmarks whose camera moves along z only.
Z_ONLY_BENCHMARKS = ("odms-detection",)
#: The benchmark whose val split selects each configuration's top-level shipped weights.
VAL_BENCHMARK = {c: ("odms-detection" if c.endswith("-z") else "odmd-v1") for c in CONFIGS}
#: Camera motion is z-only when no x or y offset exceeds this fraction of the largest z offset.
Z_ONLY_RATIO = 0.1
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


def selection_benchmark(examples: Examples) -> str | None:
    """The benchmark whose val split selects weights for ``examples``, when it is known.

    ``odms-detection`` for the z-only benchmarks, ``odmd-v1`` for the ODMD ones
    (``odmd-paper``'s sets are the same task), None for data that name no benchmark.
    """
    benchmark = examples.attrs.get("benchmark")
    if benchmark in Z_ONLY_BENCHMARKS:
        return str(benchmark)
    if isinstance(benchmark, str) and benchmark.startswith("odmd"):
        return "odmd-v1"
    return None


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


def lateral_examples(examples: Examples) -> np.ndarray:
    """(N,) bool: the camera moves sideways (an x or y offset above :data:`Z_ONLY_RATIO` of the z offsets)."""
    cam = np.asarray(examples.camera, dtype=np.float64)
    if cam.size == 0:
        return np.zeros(len(examples), dtype=bool)
    z = np.abs(cam[..., 2]).max(axis=1)
    return np.asarray(np.abs(cam[..., :2]).max(axis=(1, 2)) > Z_ONLY_RATIO * z, dtype=bool)


def is_z_only(examples: Examples) -> bool:
    """Whether the camera moves along z only (x, y offsets at most 10 % of the z offsets)."""
    if len(examples) == 0:
        return False
    cam = np.asarray(examples.camera, dtype=np.float64)
    z = float(np.abs(cam[..., 2]).max())
    return z > 0 and float(np.abs(cam[..., :2]).max()) <= Z_ONLY_RATIO * z


def default_config(examples: Examples) -> str:
    """``p-z`` for a z-only benchmark or z-only camera motion, else ``p``.

    The benchmark named in ``examples.attrs["benchmark"]`` decides when it is known
    (``odms-detection`` is z-only, ``odmd-*`` is not); other data are judged by their
    camera motion (:func:`is_z_only`).
    """
    benchmark = examples.attrs.get("benchmark")
    if benchmark in Z_ONLY_BENCHMARKS:
        return "p-z"
    if isinstance(benchmark, str) and benchmark.startswith("odmd"):
        return "p"
    return "p-z" if is_z_only(examples) else "p"


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


def load_model(
    weights: str | os.PathLike[str] | None = None,
    weights_sha256: str | None = None,
    require_record: bool = False,
) -> tuple[DBox, str]:
    """The DBox network with the given weights, and its input formulation.

    Args:
        weights: a checkpoint file in the original key layout; default: the shipped
            ``dbox_p.pt`` (whose record is then required). The formulation is ``rel``
            unless a JSON record beside the file (same name, ``.json``) names another.
        weights_sha256: expected hash of the file (see :func:`verify_weights`).
        require_record: refuse a file without a record to check it against.

    Returns:
        (model in eval mode on the CPU, formulation).

    Raises:
        DataError: the file is missing, fails its hash check, is not a torch checkpoint,
            or its keys or shapes are not the original layout (every difference is named).
    """
    model, form, _ = _load(weights, weights_sha256, require_record or weights is None)
    return model, form


def _load(
    weights: str | os.PathLike[str] | None,
    weights_sha256: str | None,
    require_record: bool,
    keep: bool = False,
) -> tuple[DBox, str, str]:
    """(network, formulation, SHA-256); ``keep``: reuse and keep the network (for prediction only)."""
    import torch
    from odmd_bench_baselines.dbox.model import DBox

    path = Path(weights) if weights is not None else DEFAULT_WEIGHTS
    data, sha = verify_weights(path, weights_sha256, require_record)
    model = _LOADED.get(sha) if keep else None
    if model is None:
        try:
            state = torch.load(io.BytesIO(data), map_location="cpu", weights_only=True)
        except Exception as e:  # torch/pickle raise many kinds for a damaged or foreign file
            raise DataError(
                f"{path} is not a loadable DBox checkpoint (read with weights_only=True): {load_failure(e)}"
            ) from None
        check_state_dict(state, str(path))
        model = DBox()
        model.load_state_dict({k: v.to(torch.float32) for k, v in state.items()})
        model.eval()
        if keep:
            # For prediction only (which never changes a network): kept by the SHA-256 of
            # the bytes just verified (always read and hashed again), so that runs of one
            # checkpoint on several sets or entries (leaderboard audit) build it once.
            while len(_LOADED) >= _KEEP_LOADED:
                _LOADED.pop(next(iter(_LOADED)))
            _LOADED[sha] = model
    return model, _formulation(path, sha), sha


#: Built networks by checkpoint SHA-256 (at most ``_KEEP_LOADED``, the oldest dropped first).
_LOADED: dict[str, DBox] = {}
_KEEP_LOADED = 8


def load_failure(e: BaseException) -> str:
    """Why ``torch.load(..., weights_only=True)`` failed, in one line.

    torch's own text advises loading again with ``weights_only=False``, which runs any
    code the file holds; it is replaced by what it means.
    """
    text = str(e).strip()
    if "Weights only load failed" in text:
        return "it holds Python objects besides tensors, which a safe load refuses (a DBox checkpoint holds tensors only)"
    first = text.splitlines()[0][:200] if text else "the file ends early or is empty"
    return f"{type(e).__name__}: {first}"


def check_state_dict(state: Any, where: str = "checkpoint") -> None:
    """Raise :class:`DataError` naming every key or shape that is not the original layout."""
    import torch
    from odmd_bench_baselines.dbox.model import checkpoint_shapes

    if not isinstance(state, dict):
        raise DataError(
            f"{where} is not a DBox state dict (got {type(state).__name__}); expected a dict "
            "with keys W, U, bias, V, linears.0.weight ... linears.6.bias"
        )
    expected = checkpoint_shapes()
    problems = []
    missing = [k for k in expected if k not in state]
    unexpected = [str(k) for k in state if k not in expected]
    if missing:
        problems.append(f"missing keys: {', '.join(missing)}")
    if unexpected:
        problems.append(f"unexpected keys: {', '.join(unexpected[:10])}")
    for key, shape in expected.items():
        value = state.get(key)
        if value is None:
            continue
        if not isinstance(value, torch.Tensor):
            problems.append(f"{key}: expected a tensor, got {type(value).__name__}")
        elif tuple(value.shape) != shape:
            problems.append(f"{key}: expected shape {shape}, got {tuple(value.shape)}")
        elif not value.is_floating_point():
            problems.append(f"{key}: expected floating point values, got {value.dtype}")
        elif not bool(torch.isfinite(value).all()):
            problems.append(f"{key}: contains NaN or infinite values")
        elif value.numel() and float(value.abs().max()) > MAX_ABS_WEIGHT:
            problems.append(
                f"{key}: holds values up to {float(value.abs().max()):.3g}, beyond {MAX_ABS_WEIGHT:g} "
                "(the bound on a weight; trained DBox weights stay below 10)"
            )
    if problems:
        raise DataError(f"{where} is not a DBox checkpoint in the original layout", problems)


def _formulation(path: Path, sha: str) -> str:
    """The input formulation of the checkpoint at ``path`` (SHA-256 ``sha``).

    A shipped checkpoint's comes from its configuration, named by its file name, never
    from its record alone; a copy of one, found by its hash, likewise. Any other's comes
    from the record beside it, which must name a formulation its configuration trains;
    without a record it is ``rel`` (the original release's checkpoint is f_Rel).

    Raises:
        DataError: a record that names no valid formulation, or one that disagrees with
            its configuration or with the shipped file's.
    """
    from odmd_bench_baselines.dbox.model import FORMULATIONS

    shipped = _shipped_config(path, sha)
    record = path.with_suffix(".json")
    named = None
    if record.is_file():
        try:
            config = json.loads(record.read_text(encoding="utf-8")).get("config")
        except (OSError, ValueError, AttributeError) as e:
            raise DataError(f"cannot read the record {record}: {type(e).__name__}") from None
        named = config.get("formulation") if isinstance(config, dict) else None
        name = config.get("name") if isinstance(config, dict) else None
        problems = []
        if named not in FORMULATIONS:
            problems.append(f"config.formulation is {named!r}, not one of {', '.join(FORMULATIONS)}")
        elif name in TRAIN_CONFIGS and TRAIN_CONFIGS[name].formulation != named:
            problems.append(
                f"configuration {name} trains formulation {TRAIN_CONFIGS[name].formulation}, not {named}"
            )
        elif shipped is not None and TRAIN_CONFIGS[shipped].formulation != named:
            problems.append(
                f"these are the shipped {shipped} weights, of formulation {TRAIN_CONFIGS[shipped].formulation}"
            )
        if problems:
            raise DataError(
                f"the record {record} does not fit its weights; restore it or reinstall odmd-bench", problems
            )
    if shipped is not None:
        return TRAIN_CONFIGS[shipped].formulation
    return str(named) if named is not None else "rel"


def _shipped_config(path: Path, sha: str) -> str | None:
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


def resolve_weights(
    examples: Examples,
    config: str | None = None,
    weights: str | os.PathLike[str] | None = None,
    selection: str = "overall",
) -> tuple[Path, dict[str, str]]:
    """The checkpoint to run on ``examples`` and how it was chosen.

    Args:
        examples: one set (``selection="per-set"`` reads its name from ``attrs["set"]``).
        config: a shipped configuration (default: :func:`default_config`); not with
            ``weights``.
        weights: a checkpoint file of one's own.
        selection: ``overall`` or ``per-set`` (with ``weights``: the file's per-set
            sibling ``<stem>.<set>.pt``, as ``train-dbox`` writes them).

    Returns:
        (checkpoint path, provenance: ``config``, ``selection``, ``weights`` (the path
        inside the shipped weights folder, or one's own file's path)).

    Raises:
        UsageError: an unknown configuration or selection, or both ``config`` and
            ``weights``.
        DataError: no shipped weights for the configuration (the shipped ones are
            listed), or no per-set checkpoint for the set.
    """
    problems = []
    if selection not in SELECTIONS:
        problems.append(f"unknown DBox selection {selection!r}; expected one of {', '.join(SELECTIONS)}")
    if config is not None and weights is not None:
        problems.append("give DBox either a configuration or a weights file, not both")
    if config is not None and config not in CONFIGS:
        problems.append(f"unknown DBox configuration {config!r}; expected one of {', '.join(CONFIGS)}")
    set_name = examples.attrs.get("set")
    if selection == "per-set" and not isinstance(set_name, str):
        problems.append(
            "per-set selection needs to know which set the examples are (examples.attrs['set']): "
            "use it with odmd-bench baseline, or load them with odmd_bench.load_split"
        )
    if len(problems) == 1:
        raise UsageError(problems[0])
    if problems:
        raise UsageError("DBox cannot run with these options", problems)
    if weights is not None:
        path = Path(weights)
        if selection == "per-set":
            path = per_set_path(path, str(set_name))
            if not path.is_file():
                raise DataError(f"no per-set checkpoint for set {set_name!r} beside {weights}: {path}")
        return path, {"config": "custom", "selection": selection, "weights": str(path)}
    name = config if config is not None else default_config(examples)
    available = shipped()
    if name not in available:
        listed = ", ".join(available) or "none"
        raise DataError(
            f"no shipped weights for DBox configuration {name!r} (shipped: {listed})",
            [f"train them with: odmd-bench train-dbox --config {name} --out DIR, then pass --weights"],
        )
    path = weights_path(name)
    on = selection_benchmark(examples)
    if weights_path(name, selected_on=on).is_file():
        path = weights_path(name, selected_on=on)  # selected on the val of the data's benchmark
    if selection == "per-set":
        # the per-set files selected on the same val as the overall one, beside it
        sets = per_set_names(path, name)
        if str(set_name) not in sets:
            where = path.parent.relative_to(WEIGHTS_DIR).as_posix()
            raise DataError(
                f"DBox configuration {name!r} has no per-set checkpoint for set {set_name!r} "
                f"(per-set checkpoints{'' if where == '.' else ' in ' + where + '/'}: "
                f"{', '.join(sets) or 'none'}); use selection 'overall'"
            )
        path = per_set_path(path, str(set_name))
    return path, {"config": name, "selection": selection, "weights": path.relative_to(WEIGHTS_DIR).as_posix()}
