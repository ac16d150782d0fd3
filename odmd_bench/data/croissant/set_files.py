"""A set as the JSON file a Croissant description points to: the same bytes on every machine.

Why JSON files beside the HDF5 ones: Croissant has no HDF5 encoding, and ``mlcroissant``
reads only CSV, TSV, JSON, JSON Lines, Parquet, text, images and audio. Of those, JSON is
read by Python's own parser, whose floats round-trip exactly (CSV and JSON Lines go through
pandas' parsers, which are not exact to the last bit, and Parquet would need pyarrow). The
JSON is written with sorted keys, no whitespace and the shortest exact form of each float,
so its bytes, and the SHA-256 each file object records, depend only on the verified arrays:
the same on every machine. A NaN (an unknown observation depth) is written as ``null``.
"""

from __future__ import annotations

import json

import numpy as np

from odmd_bench.data.examples import Examples
from odmd_bench.data.hashing import set_arrays
from odmd_bench.data.registry import Benchmark
from odmd_bench.errors import DataError

#: Croissant data types by numpy kind.
DATA_TYPES = {"f": "cr:Float64", "b": "sc:Boolean", "i": "sc:Integer", "u": "sc:Integer"}

#: JSON without whitespace.
_COMPACT = (",", ":")


def set_file_name(benchmark: Benchmark, split: str, set_name: str) -> str:
    """Where a set's JSON file lies, relative to the description: ``BENCHMARK/SPLIT/SET.json``."""
    return f"{benchmark.name}/{split}/{set_name}.json"


def _text(name: str, a: np.ndarray) -> str:
    """An array as JSON text, one item per example (nested lists), NaN as null.

    NaN is written as the token ``NaN`` first (``allow_nan``), then replaced by ``null``: in the
    text of one array that token can stand nowhere else (numbers, ``true``, ``false``, brackets
    and commas only; infinite values are refused before, so no ``Infinity`` token exists). This
    writes the same bytes as turning NaN into None in an object array, without that array.
    """
    if a.dtype.kind not in DATA_TYPES:
        raise DataError(f"array {name!r} has dtype {a.dtype}, which the Croissant export does not carry")
    if a.dtype.kind == "f" and np.isinf(a).any():
        raise DataError("an array holds an infinite value, which JSON cannot carry")
    text = json.dumps(a.tolist(), separators=_COMPACT, allow_nan=True, check_circular=False)
    return text.replace("NaN", "null") if a.dtype.kind == "f" else text


def set_file_bytes(examples: Examples) -> bytes:
    """The JSON file of one set: ``{"index": [...], ARRAY: [one value per example], ...}``.

    Each array is a list with one item per example (nested lists for the per-observation
    arrays); keys are sorted, there is no whitespace, floats are written exactly (Python's
    shortest round-trip form) and NaN as null, so the bytes are the same on every machine.

    Raises:
        DataError: an array of a kind JSON cannot carry exactly (complex, text, infinite values).
    """
    texts = {"index": json.dumps(list(range(len(examples))), separators=_COMPACT)}
    for name, a in set_arrays(examples).items():
        texts[name] = _text(name, np.asarray(a))
    # json.dumps(..., sort_keys=True) of the whole: keys in sorted order, each as JSON (ASCII)
    body = ",".join(f"{json.dumps(key)}:{texts[key]}" for key in sorted(texts))
    return ("{" + body + "}").encode("ascii")
