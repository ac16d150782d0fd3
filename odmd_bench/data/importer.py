"""Import of the original 2021 release's ``.pk`` files into the HDF5 layout.

The files are pickles, and unpickling can run arbitrary code, so they are read with
:class:`RestrictedUnpickler`, which resolves only the three numpy globals these files
use and refuses everything else before anything runs. Every known original file is
pinned by SHA-256 in ``splits/odmd-original.json``; a file with another hash is refused
unless the caller explicitly allows unknown files. The numbers are copied exactly:
boxes, camera positions and depths come back bit for bit; a missing detection (stored as
a box of width 0) becomes ``detected = False`` with the stored zeros kept.
"""

from __future__ import annotations

import io
import logging
import os
import pickle
import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from odmd_bench.data.config import HSR_GRASP_CAMERA
from odmd_bench.data.examples import Examples, set_problems
from odmd_bench.data.hashing import group_attrs
from odmd_bench.data.io import set_names, write_sets
from odmd_bench.data.loading import read_checked
from odmd_bench.data.manifests import known_originals, pin_problem
from odmd_bench.data.registry import Benchmark, get_benchmark, set_file
from odmd_bench.errors import DataError, ImportRefused, StorageError, show_value
from odmd_bench.inputs.source import MAX_ORIGINAL_BYTES, cap_advice, input_limit, read_at_most
from odmd_bench.outputs import clean_stale_temps, locked

log = logging.getLogger("odmd_bench")

_ODMD_SETS = {"normal": "normal", "perturb_motion": "camera", "perturb_detection": "object", "robot": "robot"}
_ODMS_SETS = ("normal", "perturb", "robot", "driving")


def _numpy_reconstruct() -> Callable[..., Any]:
    try:
        from numpy._core.multiarray import _reconstruct  # numpy >= 2
    except ImportError:  # pragma: no cover - numpy 1.x
        from numpy.core.multiarray import _reconstruct  # type: ignore[no-redef]
    return _reconstruct


_ALLOWED: dict[tuple[str, str], Callable[[], Any]] = {
    ("numpy.core.multiarray", "_reconstruct"): _numpy_reconstruct,
    ("numpy._core.multiarray", "_reconstruct"): _numpy_reconstruct,
    ("numpy", "ndarray"): lambda: np.ndarray,
    ("numpy", "dtype"): lambda: np.dtype,
}


class RestrictedUnpickler(pickle.Unpickler):
    """An unpickler that can build dicts, lists, strings, numbers and numpy arrays only."""

    def find_class(self, module: str, name: str) -> Any:
        """The allowed factory for ``module.name``; raise :class:`ImportRefused` for any other."""
        factory = _ALLOWED.get((module, name))
        if factory is None:
            raise ImportRefused(
                f"the pickle asks for {module}.{name}, which an ODMD file never needs; "
                "refused before anything ran (allowed: numpy arrays and dtypes only)"
            )
        return factory()

    def persistent_load(self, pid: Any) -> Any:
        """Refuse persistent ids (:class:`ImportRefused`): an ODMD file never has them."""
        raise ImportRefused("the pickle uses persistent ids, which an ODMD file never does; refused")


def safe_unpickle(data: bytes, origin: str = "<bytes>") -> Any:
    """Unpickle ``data`` allowing only numpy arrays; raise :class:`ImportRefused` otherwise."""
    try:
        return RestrictedUnpickler(io.BytesIO(data)).load()
    except ImportRefused as e:
        raise ImportRefused(f"{origin}: {e.message}") from None
    except Exception as e:  # truncated or malformed pickles raise many types
        raise ImportRefused(f"{origin}: not a readable pickle ({type(e).__name__}: {e})") from None


@dataclass(frozen=True)
class Target:
    """Where an original file goes: a set of a benchmark split."""

    benchmark: str
    split: str
    set: str


def target_from_name(path: Path) -> Target | None:
    """Guess benchmark, split and set from an original file name (for unknown files)."""
    stem = path.stem
    m = re.fullmatch(r"(val|test)_odms_detect_(normal|perturb|robot|driving)", stem)
    if m:
        return Target("odms-detection", m.group(1), m.group(2))
    m = re.fullmatch(r"(val|test)_(normal|perturb_motion|perturb_detection|robot)", stem)
    if m:
        return Target("odmd-paper", m.group(1), _ODMD_SETS[m.group(2)])
    return None


def _array(obj: Any, where: str, shape: tuple[int | None, ...], problems: list[str]) -> np.ndarray | None:
    if not isinstance(obj, np.ndarray):
        problems.append(f"{where}: expected a numpy array, got {type(obj).__name__}")
        return None
    if obj.dtype != np.float64:
        problems.append(f"{where}: expected float64, got {obj.dtype}")
        return None
    if obj.ndim != len(shape) or any(
        s is not None and s != g for s, g in zip(shape, obj.shape, strict=False)
    ):
        problems.append(f"{where}: expected shape {shape} (None = any), got {obj.shape}")
        return None
    return obj


def _number(value: Any) -> float | None:
    """``value`` as a finite float, or None (a string, a list, NaN...)."""
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        return None
    try:
        v = float(value)
    except OverflowError:  # an integer too large for a float
        return None
    return v if np.isfinite(v) else None


def _source_name(value: Any) -> str:
    """The release's own name for the set (``test_name``): text, at most 200 characters."""
    return value[:200] if isinstance(value, str) else ""


def convert(obj: Any, origin: str, target: Target) -> Examples:
    """Turn one unpickled original file into :class:`Examples` (numbers copied exactly)."""
    problems: list[str] = []
    if (
        not isinstance(obj, dict)
        or not isinstance(obj.get("bb"), dict)
        or not isinstance(obj.get("bb_3D"), dict)
    ):
        raise ImportRefused(f"{origin}: expected a dict with 'bb' and 'bb_3D' dicts (the ODMD layout)")
    bb, bb3 = obj["bb"], obj["bb_3D"]
    bboxes = _array(bb.get("bboxes"), "bb.bboxes", (None, 5, None), problems)
    moves = _array(bb3.get("camera_movement"), "bb_3D.camera_movement", (None, 3, None), problems)
    if bboxes is not None and moves is not None:
        n_obs, _, n = bboxes.shape
        if moves.shape != (n_obs - 1, 3, n):
            problems.append(f"bb_3D.camera_movement: expected {(n_obs - 1, 3, n)}, got {moves.shape}")
    if problems:
        raise ImportRefused(f"{origin}: not an ODMD file", problems)
    assert bboxes is not None and moves is not None  # for mypy; checked above
    n_obs, _, n = bboxes.shape

    boxes = np.ascontiguousarray(bboxes[:, :4, :].transpose(2, 0, 1))
    detected = boxes[:, :, 2] != 0
    camera = np.zeros((n, n_obs, 3))
    camera[:, :-1, :] = moves.transpose(2, 0, 1)
    z = np.ascontiguousarray(bboxes[:, 4, :].T)
    depth = z[:, -1].copy()
    # The release stores 0 where the depth at an observation is unknown (robot sets).
    observation_depth = np.where(z == 0, np.nan, z)

    extras: dict[str, np.ndarray] = {}
    positions = bb3.get("positions")
    if positions is not None:
        p = _array(positions, "bb_3D.positions", (n_obs, 3, n), problems)
        if p is not None:
            extras["positions"] = np.ascontiguousarray(p.transpose(2, 0, 1))
    sizes = bb3.get("sizes")
    if sizes is not None:
        if isinstance(sizes, list | tuple) and len(sizes) == 2:
            w = _array(sizes[0], "bb_3D.sizes[0]", (n,), problems)
            h = _array(sizes[1], "bb_3D.sizes[1]", (n,), problems)
            if w is not None and h is not None:
                extras["size"] = np.stack([w, h], axis=1)
        else:
            problems.append("bb_3D.sizes: expected two arrays (W, H)")
    if problems:
        raise ImportRefused(f"{origin}: not an ODMD file", problems)

    attrs: dict[str, Any] = {
        "benchmark": target.benchmark,
        "split": target.split,
        "set": target.set,
        "source": "import",
        "source_name": _source_name(obj.get("test_name")),
    }
    image_dim = bb.get("image_dim")
    if isinstance(image_dim, list | tuple) and len(image_dim) == 2:
        dims = [_number(v) for v in image_dim]
        if not all(d is not None and d > 0 and d == int(d) for d in dims):
            raise ImportRefused(
                f"{origin}: image_dim = {show_value(image_dim)} is not two positive whole numbers"
            )
        attrs["image_height"], attrs["image_width"] = int(dims[0]), int(dims[1])  # type: ignore[arg-type]
    if target.benchmark == "odmd-paper":
        # All ODMD sets (generated and robot) use the HSR grasp camera (paper, sec. 3.3);
        # the generated files record fx/W and fy/H, which must agree.
        cam = HSR_GRASP_CAMERA
        for key, value in (("fx_norm", cam.fx / cam.image_width), ("fy_norm", cam.fy / cam.image_height)):
            if key not in bb:
                continue
            got = _number(bb[key])
            if got is None or not np.isclose(got, value, rtol=0, atol=1e-12):
                raise ImportRefused(
                    f"{origin}: {key} = {show_value(bb[key])} does not match the HSR camera ({value})"
                )
        attrs.update(
            fx=cam.fx,
            fy=cam.fy,
            cx=cam.cx,
            cy=cam.cy,
            image_width=cam.image_width,
            image_height=cam.image_height,
        )
    return Examples(
        boxes=boxes,
        detected=detected,
        camera=camera,
        depth=depth,
        observation_depth=observation_depth,
        extras=extras,
        attrs=attrs,
    )


def read_original(path: str | os.PathLike[str], *, allow_unknown: bool = False) -> Examples:
    """Read one original ``.pk`` file, checking its hash against the pinned list.

    At most :data:`~odmd_bench.inputs.source.MAX_ORIGINAL_BYTES` (64 MiB) are read;
    ``ODMD_BENCH_MAX_INPUT_MIB`` sets another cap.
    """
    p = Path(path)
    limit = input_limit(MAX_ORIGINAL_BYTES)
    try:
        with p.open("rb") as fh:  # at most the cap plus one byte: /dev/zero ends too
            data = read_at_most(fh.read, limit, os.fstat(fh.fileno()).st_size) or b""
    except OSError as e:
        raise ImportRefused(f"{p}: cannot read ({e.strerror})") from None
    if len(data) > limit:
        raise ImportRefused(
            f"{p}: larger than {limit / 2**20:g} MiB, {cap_advice('an original release file')} "
            "(the release's largest file is 2.6 MB)"
        )
    import hashlib

    digest = hashlib.sha256(data).hexdigest()
    known = known_originals().get(digest)
    if known is not None and "benchmark" in known:
        target = Target(known["benchmark"], known["split"], known["set"])
    elif known is not None:
        raise ImportRefused(f"{p}: this is the release's {known['path']}, not a data set")
    elif not allow_unknown:
        raise ImportRefused(
            f"{p}: unknown file (SHA-256 {digest[:16]}...) — not one of the original release's "
            "pinned files in splits/odmd-original.json; it may be altered. Pass --allow-unknown "
            "to import it anyway (its results will not be comparable with the paper)"
        )
    else:
        guess = target_from_name(p)
        if guess is None:
            raise ImportRefused(
                f"{p}: unknown file whose name says neither split nor set; an unknown file is "
                "imported by the original release's name for it: SPLIT_SET.pk (SPLIT val or test, "
                "SET normal, perturb_motion, perturb_detection or robot; e.g. test_robot.pk) or "
                "SPLIT_odms_detect_SET.pk (SET normal, perturb, robot or driving)"
            )
        target = guess
    ex = convert(safe_unpickle(data, str(p)), str(p), target)
    unusable = set_problems(ex)
    if unusable:
        raise ImportRefused(f"{p}: not usable as a benchmark set", unusable)
    ex.attrs["source_file"] = known["path"] if known else p.name
    ex.attrs["source_sha256"] = digest
    ex.attrs["source_known"] = known is not None
    return ex


def find_originals(source: str | os.PathLike[str]) -> list[Path]:
    """The ``.pk`` files of ``source`` (a file, or a folder searched recursively)."""
    p = Path(source)
    if p.is_file():
        return [p]
    if p.is_dir():
        files = sorted(q for q in p.rglob("*.pk") if q.is_file())
        if not files:
            raise ImportRefused(f"{p}: no .pk files found")
        return files
    if p.exists():
        raise ImportRefused(f"{p}: not a regular file nor a folder (a pipe, socket or device)")
    raise ImportRefused(f"{p}: no such file or folder")


def import_release(
    source: str | os.PathLike[str],
    data_dir: str | os.PathLike[str] | None = None,
    *,
    benchmark: str | None = None,
    allow_unknown: bool = False,
    progress: Callable[[str], None] | None = None,
) -> dict[tuple[str, str], dict[str, str]]:
    """Import every original file under ``source`` into the data folder.

    Files are grouped by (benchmark, split) and merged into that benchmark's file.
    Every file is checked before anything is written, and a known original must
    convert to its pinned set (``splits/<benchmark>.json``); any refusal stops the
    import with all problems named. The read-merge-replace of each split's file holds
    the split's lock, so concurrent imports into one split keep each other's sets.
    Sets already in the file and not re-imported are kept when they pass every check
    of a load; a damaged, altered or unreadable one (or a whole unreadable file) is
    dropped, and ``progress`` (default: a logged warning) says what was replaced.

    Returns ``{(benchmark, split): {set: content hash}}`` of what the files now hold.

    Raises:
        ImportRefused: a file was refused (nothing written).
        StorageError: a file cannot be written (the message says why and what to do).
    """
    say = progress or log.warning
    if benchmark is not None:
        get_benchmark(benchmark)
    grouped: dict[tuple[str, str], dict[str, Examples]] = {}
    digests: dict[tuple[str, str, str], str] = {}  # content hashes of the converted sets
    problems: list[str] = []
    for f in find_originals(source):
        try:
            ex = read_original(f, allow_unknown=allow_unknown)
        except ImportRefused as e:
            problems.append(e.render())
            continue
        key = (ex.attrs["benchmark"], ex.attrs["split"])
        if benchmark is not None and key[0] != benchmark:
            continue
        if ex.attrs["set"] in grouped.get(key, {}):
            problems.append(f"{f}: a second file for {key[0]} {key[1]} {ex.attrs['set']}")
            continue
        attrs = group_attrs(ex, ex.attrs["set"])
        digests[(key[0], key[1], ex.attrs["set"])] = attrs["content_sha256"]
        problem = pin_problem(get_benchmark(key[0]), key[1], ex.attrs["set"], attrs)
        if problem:
            problems.append(
                f"{f}: its conversion is not the pinned set ({problem}); this odmd-bench converts differently"
            )
            continue
        grouped.setdefault(key, {})[ex.attrs["set"]] = ex
    if problems:
        raise ImportRefused("import refused; nothing was written", problems)
    if not grouped:
        raise ImportRefused(f"{source}: no files of benchmark {benchmark!r}")
    written: dict[tuple[str, str], dict[str, str]] = {}
    for (bench, split), sets in sorted(grouped.items()):
        b = get_benchmark(bench)
        path = set_file(b, split, data_dir)
        for p in clean_stale_temps(path):
            say(f"removed a dead writer's temporary file {p}")
        with locked(path):
            merged = _kept_sets(path, b, split, sets, data_dir, say)
            merged.update(sets)
            order = [s for s in b.sets if s in merged]
            written[(bench, split)] = write_sets(
                path,
                {s: merged[s] for s in order},
                file_attrs={"benchmark": bench, "split": split},
                digests={s: digests[(bench, split, s)] for s in sets}
                | {s: str(ex.attrs["content_sha256"]) for s, ex in merged.items() if s not in sets},
            )
        log.info("wrote %s (%s)", path, ", ".join(order))
    return written


def _kept_sets(
    path: Path,
    bench: Benchmark,
    split: str,
    new: dict[str, Examples],
    data_dir: str | os.PathLike[str] | None,
    say: Callable[[str], None],
) -> dict[str, Examples]:
    """The good sets of ``path`` that are not re-imported; reports the others."""
    if not path.exists() and not path.is_symlink():
        return {}
    try:
        names = set_names(path)
    except StorageError:
        raise  # the file may be fine (a permission, an I/O error): never replace it on a guess
    except DataError as e:
        say(f"{path} cannot be read and is replaced; only the sets imported now will be in it ({e.message})")
        return {}
    kept: dict[str, Examples] = {}
    known = set(bench.sets)
    for name in names:
        if name in new:
            continue
        if name not in known:
            say(f"{path}: dropped the set {name!r}, which {bench.name} does not have")
            continue
        try:
            kept[name] = read_checked(path, bench, split, name, data_dir, fix="import it again")
        except StorageError:
            raise
        except DataError as e:
            say(f"{path}: dropped the set {name!r}: {e.render()}")
    return kept
