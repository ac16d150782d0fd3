"""The HDF5 schema: writing, reading and hashing sets; atomic file writes.

One file per benchmark and split; one group per set holding at least ``boxes``,
``detected``, ``camera`` and ``depth`` (CONTRACT section 3) plus whatever else the
source knew. The content SHA-256 of a set is computed from its arrays (names, dtypes,
shapes and little-endian bytes, in name order), never from the container's bytes, so
it is the same whatever HDF5 library version or compression wrote the file.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import tempfile
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import IO, Any

import numpy as np

from odmd_bench.data.examples import Examples
from odmd_bench.errors import DataError

#: Version of the file layout written here (an attribute of every file).
FORMAT_VERSION = 1

_CORE = ("boxes", "detected", "camera", "depth")


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _temp_beside(target: Path) -> tuple[int, str]:
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600; give the file normal permissions
    return fd, tmp


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike[str]) -> Iterator[Path]:
    """A temporary file name beside ``path``; on success, the file is moved over ``path``.

    If the body raises (or the process dies), ``path`` is untouched: an existing good
    file is never lost and no half-written file is left under the final name. For
    writers that want a file name (h5py, savefig); see also :func:`atomic_write`.
    """
    target = Path(path)
    fd, tmp = _temp_beside(target)
    os.close(fd)
    try:
        yield Path(tmp)
        with open(tmp, "rb+") as fh:
            os.fsync(fh.fileno())
        os.replace(tmp, target)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


@contextlib.contextmanager
def atomic_write(path: str | os.PathLike[str], mode: str = "wb") -> Iterator[IO[Any]]:
    """Open a temporary file beside ``path`` for writing; on success it replaces ``path``
    (see :func:`atomic_path`)."""
    with atomic_path(path) as tmp, open(tmp, mode) as fh:
        yield fh


def set_arrays(ex: Examples) -> dict[str, np.ndarray]:
    """All arrays of a set by their name in the file."""
    arrays = {name: getattr(ex, name) for name in _CORE}
    if ex.observation_depth is not None:
        arrays["observation_depth"] = ex.observation_depth
    for k, v in ex.extras.items():
        if k in arrays:
            raise DataError(f"extra array {k!r} clashes with a core array")
        arrays[k] = v
    return arrays


def content_sha256(arrays: Mapping[str, np.ndarray]) -> str:
    """SHA-256 of a set's arrays, independent of how they are stored.

    For each array in name order: its name, little-endian dtype string and shape as
    one JSON line, then its C-order little-endian bytes.
    """
    h = hashlib.sha256()
    for name in sorted(arrays):
        a = np.asarray(arrays[name])
        dt = a.dtype.newbyteorder("<") if a.dtype.byteorder == ">" else a.dtype
        a = np.ascontiguousarray(a, dtype=dt)
        header = json.dumps([name, dt.str, list(a.shape)], separators=(",", ":"))
        h.update(header.encode() + b"\n")
        h.update(a.tobytes())
    return h.hexdigest()


def file_sha256(path: str | os.PathLike[str]) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def _attr_value(v: Any) -> Any:
    if isinstance(v, dict | list | tuple):
        return json.dumps(v, sort_keys=True)
    return v


def write_sets(
    path: str | os.PathLike[str],
    sets: Mapping[str, Examples],
    *,
    file_attrs: Mapping[str, Any] | None = None,
    compress: bool = False,
) -> dict[str, str]:
    """Write ``{set name: examples}`` to one HDF5 file, atomically.

    Each group gets the examples' ``attrs`` plus ``set``, ``n``, ``n_obs`` and
    ``content_sha256``. Data-folder files are stored uncompressed (reading them is
    twice as fast, for about 30% more disk); ``compress`` (gzip) is for files that are
    committed. Returns ``{set name: content hash}``.
    """
    options: dict[str, Any] = (
        {"compression": "gzip", "compression_opts": 4, "shuffle": True} if compress else {}
    )
    import h5py

    hashes: dict[str, str] = {}
    with atomic_path(path) as tmp, h5py.File(tmp, "w", track_order=True) as f:
        f.attrs["format_version"] = FORMAT_VERSION
        for k, v in (file_attrs or {}).items():
            if v is not None:
                f.attrs[k] = _attr_value(v)
        for name, ex in sets.items():
            arrays = set_arrays(ex)
            digest = content_sha256(arrays)
            hashes[name] = digest
            g = f.create_group(name, track_order=True)
            for k, a in arrays.items():
                g.create_dataset(k, data=a, **options)
            attrs = {**ex.attrs, "set": name, "n": len(ex), "n_obs": ex.n_obs, "content_sha256": digest}
            for k, v in attrs.items():
                if v is not None:
                    g.attrs[k] = _attr_value(v)
    return hashes


def _py(v: Any) -> Any:
    if isinstance(v, bytes):
        return v.decode()
    if isinstance(v, np.generic):
        return v.item()
    return v


def read_set(path: str | os.PathLike[str], set_name: str, *, verify: bool = True) -> Examples:
    """Read one set back; with ``verify``, its arrays must match its stored content hash."""
    import h5py

    p = Path(path)
    try:
        f = h5py.File(p, "r")
    except FileNotFoundError:
        raise DataError(f"no data file at {p}") from None
    except OSError as e:
        raise DataError(f"{p} is not a readable HDF5 file ({e})") from None
    with f:
        if set_name not in f:
            raise DataError(f"{p} holds no set {set_name!r} (it has: {', '.join(f.keys()) or 'none'})")
        g = f[set_name]
        missing = [k for k in _CORE if k not in g]
        if missing:
            raise DataError(f"{p}:{set_name} lacks the arrays {', '.join(missing)}")
        arrays = {k: g[k][()] for k in g}
        attrs = {k: _py(v) for k, v in g.attrs.items()}
        for k, v in f.attrs.items():
            attrs.setdefault(k, _py(v))
    if verify:
        stored = attrs.get("content_sha256")
        actual = content_sha256(arrays)
        if stored != actual:
            raise DataError(
                f"{p}:{set_name} is corrupt: its arrays hash to {actual[:16]}..., "
                f"the file records {str(stored)[:16]}...; delete it and generate or import again"
            )
    return Examples(
        boxes=arrays.pop("boxes"),
        detected=arrays.pop("detected"),
        camera=arrays.pop("camera"),
        depth=arrays.pop("depth"),
        observation_depth=arrays.pop("observation_depth", None),
        extras=arrays,
        attrs=attrs,
    )


def file_summary(path: str | os.PathLike[str]) -> dict[str, Any]:
    """What a file holds: its attributes and, per set, size, arrays and attributes."""
    import h5py

    p = Path(path)
    try:
        f = h5py.File(p, "r")
    except OSError as e:
        raise DataError(f"{p} is not a readable HDF5 file ({e})") from None
    with f:
        out: dict[str, Any] = {"path": str(p), "attrs": {k: _py(v) for k, v in f.attrs.items()}, "sets": {}}
        for name, g in f.items():
            out["sets"][name] = {
                "arrays": {k: (str(d.dtype), list(d.shape)) for k, d in g.items()},
                "attrs": {k: _py(v) for k, v in g.attrs.items()},
            }
    return out
