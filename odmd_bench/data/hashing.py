"""What a set is in a file (its arrays and attributes) and the hashes that pin it.

Two hashes make a set's integrity (docs/integrity.md):

- ``content_sha256``, over its arrays (names, dtypes, shapes and little-endian
  bytes, in name order), never over the container's bytes, so it is the same
  whatever HDF5 library version or compression wrote the file;
- ``meta_sha256``, over every other attribute of its group (intrinsics, image size,
  identity, generator version, source...), as canonical JSON.
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Mapping
from typing import Any

import numpy as np

from odmd_bench.data.examples import Examples
from odmd_bench.errors import DataError

#: The arrays every set has.
CORE_ARRAYS = ("boxes", "detected", "camera", "depth")

#: Group attributes that are not covered by ``meta_sha256`` (the two hashes).
HASH_ATTRS = ("content_sha256", "meta_sha256")

#: The separators of the canonical JSON both hashes write: no whitespace.
_COMPACT = (",", ":")


def set_arrays(ex: Examples) -> dict[str, np.ndarray]:
    """All arrays of a set by their name in the file."""
    arrays = {name: getattr(ex, name) for name in CORE_ARRAYS}
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
        dt = a.dtype.newbyteorder("<")  # native ("="), big-endian (">") or none ("|"): little-endian
        a = np.ascontiguousarray(a, dtype=dt)
        header = json.dumps([name, dt.str, list(a.shape)], separators=_COMPACT)
        h.update(header.encode() + b"\n")
        # the bytes in place (a flat byte view of the contiguous array), not a copy; an
        # object array's "bytes" are its pointers, which no file's hash matches
        h.update(a.tobytes() if a.dtype.hasobject else a.reshape(-1).view(np.uint8).data)
    return h.hexdigest()


def plain_value(v: Any) -> Any:
    """An attribute value as plain Python (what reading it back gives)."""
    if isinstance(v, bytes):
        return v.decode()
    if isinstance(v, np.ndarray):
        return v.tolist()
    if isinstance(v, np.generic):
        return v.item()
    return v


def attr_value(v: Any) -> Any:
    """An attribute value as HDF5 stores it: dicts, lists and tuples as sorted-key JSON."""
    if isinstance(v, dict | list | tuple):
        return json.dumps(v, sort_keys=True)
    return v


def meta_sha256(attrs: Mapping[str, Any]) -> str:
    """SHA-256 of a set's attributes other than its two hashes, as canonical JSON.

    The JSON object has sorted keys, plain Python values (what reading the file
    back gives: ``int``, ``float``, ``bool``, ``str``), no whitespace, and ASCII only
    (other characters escaped, as JSON does). Float values are written exactly
    (shortest round-trip form), so ``fx = 205.5`` and ``fx = 205.50000000000003`` hash
    differently.
    """
    body = {k: plain_value(v) for k, v in attrs.items() if k not in HASH_ATTRS}
    text = json.dumps(body, sort_keys=True, separators=_COMPACT, default=repr)  # ASCII: json's default
    return hashlib.sha256(text.encode()).hexdigest()


def group_attrs(ex: Examples, name: str, digest: str | None = None) -> dict[str, Any]:
    """The attributes :func:`write_sets` stores for set ``name`` of ``ex``, hashes included.

    ``digest`` is the content hash if already computed.
    """
    digest = digest or content_sha256(set_arrays(ex))
    raw = {**ex.attrs, "set": name, "n": len(ex), "n_obs": ex.n_obs}
    attrs = {k: plain_value(attr_value(v)) for k, v in raw.items() if v is not None and k not in HASH_ATTRS}
    attrs["content_sha256"] = digest
    attrs["meta_sha256"] = meta_sha256(attrs)
    return attrs


def file_sha256(path: str | os.PathLike[str]) -> str:
    """SHA-256 of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


__all__ = [
    "CORE_ARRAYS",
    "HASH_ATTRS",
    "attr_value",
    "content_sha256",
    "file_sha256",
    "group_attrs",
    "meta_sha256",
    "plain_value",
    "set_arrays",
]
