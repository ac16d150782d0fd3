"""A benchmark as a Croissant 1.0 dataset (JSON-LD) that ``mlcroissant`` validates and loads.

:func:`croissant` describes every split and set of a benchmark: a record set per set (one
record per example: ``index``, ``boxes``, ``detected``, ``camera``, ``depth`` and the set's
other arrays), a ``sets`` record set with each set's provenance (generator version and
seed, or the original file and its SHA-256; content hashes; licence; camera), and a file
per set. The files are what :func:`set_file_bytes` writes: the set's arrays as JSON.

Its rooms: :mod:`~odmd_bench.data.croissant.vocabulary` (the fixed words: context,
licences, what each array and column means), :mod:`~odmd_bench.data.croissant.set_files`
(a set's JSON file), :mod:`~odmd_bench.data.croissant.description` (the JSON-LD) and
:mod:`~odmd_bench.data.croissant.export` (from the data folder, to a folder). Their
public names are imported from here.
"""

from odmd_bench.data.croissant.description import croissant
from odmd_bench.data.croissant.export import croissant_text, describe_benchmark, write_croissant
from odmd_bench.data.croissant.set_files import set_file_bytes, set_file_name
from odmd_bench.data.croissant.vocabulary import (
    ARRAY_DESCRIPTIONS,
    CONFORMS_TO,
    CONTEXT,
    MIT,
    ORIGINAL_TERMS,
    SUFFIX,
)

__all__ = [
    "ARRAY_DESCRIPTIONS",
    "CONFORMS_TO",
    "CONTEXT",
    "MIT",
    "ORIGINAL_TERMS",
    "SUFFIX",
    "croissant",
    "croissant_text",
    "describe_benchmark",
    "set_file_bytes",
    "set_file_name",
    "write_croissant",
]
