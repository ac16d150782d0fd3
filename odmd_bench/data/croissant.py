"""A benchmark as a Croissant 1.0 dataset (JSON-LD) that ``mlcroissant`` validates and loads.

:func:`croissant` describes every split and set of a benchmark: a record set per set (one
record per example: ``index``, ``boxes``, ``detected``, ``camera``, ``depth`` and the set's
other arrays), a ``sets`` record set with each set's provenance (generator version and
seed, or the original file and its SHA-256; content hashes; licence; camera), and a file
per set. The files are what :func:`set_file_bytes` writes: the set's arrays as JSON.

Why JSON files beside the HDF5 ones: Croissant has no HDF5 encoding, and ``mlcroissant``
reads only CSV, TSV, JSON, JSON Lines, Parquet, text, images and audio. Of those, JSON is
read by Python's own parser, whose floats round-trip exactly (CSV and JSON Lines go through
pandas' parsers, which are not exact to the last bit, and Parquet would need pyarrow). The
JSON is written with sorted keys, no whitespace and the shortest exact form of each float,
so its bytes, and the SHA-256 each file object records, depend only on the verified arrays:
the same on every machine. A NaN (an unknown observation depth) is written as ``null``.

No library writes Croissant from arrays (``mlcroissant`` reads it; its writer takes its own
node objects and a runtime dependency we do not want), so the JSON-LD is built here as plain
dicts; the tests validate it with ``mlcroissant`` and load every set through it.
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from odmd_bench._version import __version__
from odmd_bench.data.examples import Examples
from odmd_bench.data.hashing import set_arrays
from odmd_bench.data.manifests import read_manifest
from odmd_bench.data.registry import Benchmark
from odmd_bench.errors import DataError
from odmd_bench.outputs import atomic_paths, ensure_folder
from odmd_bench.project import PAPER_BIBTEX, card_url, repository_url, site_url

#: What the description conforms to.
CONFORMS_TO = "http://mlcommons.org/croissant/1.0"

#: The JSON-LD context of Croissant 1.0 (as its specification and ``mlcroissant`` write it).
CONTEXT: dict[str, Any] = {
    "@language": "en",
    "@vocab": "https://schema.org/",
    "citeAs": "cr:citeAs",
    "column": "cr:column",
    "conformsTo": "dct:conformsTo",
    "cr": "http://mlcommons.org/croissant/",
    "rai": "http://mlcommons.org/croissant/RAI/",
    "data": {"@id": "cr:data", "@type": "@json"},
    "dataType": {"@id": "cr:dataType", "@type": "@vocab"},
    "dct": "http://purl.org/dc/terms/",
    "equivalentProperty": "cr:equivalentProperty",
    "examples": {"@id": "cr:examples", "@type": "@json"},
    "extract": "cr:extract",
    "field": "cr:field",
    "fileProperty": "cr:fileProperty",
    "fileObject": "cr:fileObject",
    "fileSet": "cr:fileSet",
    "format": "cr:format",
    "includes": "cr:includes",
    "isLiveDataset": "cr:isLiveDataset",
    "jsonPath": "cr:jsonPath",
    "key": "cr:key",
    "md5": "cr:md5",
    "parentField": "cr:parentField",
    "path": "cr:path",
    "recordSet": "cr:recordSet",
    "references": "cr:references",
    "regex": "cr:regex",
    "repeated": "cr:repeated",
    "replace": "cr:replace",
    "samplingRate": "cr:samplingRate",
    "sc": "https://schema.org/",
    "separator": "cr:separator",
    "source": "cr:source",
    "subField": "cr:subField",
    "transform": "cr:transform",
}

#: The licence of what odmd-bench generates (the package's own).
MIT = "https://spdx.org/licenses/MIT.html"
#: The original release's terms ("available for non-commercial research purposes only"),
#: which the imported sets and the committed robot sets keep (splits/ATTRIBUTION.md).
ORIGINAL_TERMS = "https://github.com/griffbr/ODMD"
ORIGINAL_TERMS_TEXT = "non-commercial research use only, the terms of the original ODMD release"

#: The file name of a benchmark's description.
SUFFIX = ".croissant.json"

#: How the known arrays are described (shape after the example axis, meaning).
ARRAY_DESCRIPTIONS: dict[str, str] = {
    "boxes": "(n_obs, 4) per example: the bounding box x, y, w, h at each observation, x and w divided by "
    "the image width, y and h by its height; meaningless where detected is false",
    "detected": "(n_obs,) per example: false where the detector found nothing",
    "camera": "(n_obs, 3) per example: the camera position at each observation relative to the last one, "
    "metres, camera axes (the last row is zero)",
    "depth": "the object's depth Z_n at the last observation, metres (the target)",
    "observation_depth": "(n_obs,) per example: the object's depth at each observation, metres; null where "
    "unknown",
    "positions": "(n_obs, 3) per example: the object's position in the camera frame at each observation, metres",
    "size": "(2,) per example: the object's width and height, metres",
    "camera_clean": "(n_obs, 3) per example: the camera positions before the camera perturbation, metres",
    "replaced": "(n_obs,) per example: true where the object perturbation replaced the box by another "
    "example's",
}

#: Croissant data types by numpy kind.
_DATA_TYPES = {"f": "cr:Float64", "b": "sc:Boolean", "i": "sc:Integer", "u": "sc:Integer"}


def set_file_name(benchmark: Benchmark, split: str, set_name: str) -> str:
    """Where a set's JSON file lies, relative to the description: ``BENCHMARK/SPLIT/SET.json``."""
    return f"{benchmark.name}/{split}/{set_name}.json"


def _plain(a: np.ndarray) -> Any:
    """An array as nested lists of Python values, NaN as None (JSON null)."""
    if a.dtype.kind == "f":
        if np.isinf(a).any():
            raise DataError("an array holds an infinite value, which JSON cannot carry")
        nan = np.isnan(a)
        if nan.any():  # only then the slower object array: None where NaN
            obj = a.astype(object)
            obj[nan] = None
            return obj.tolist()
    return a.tolist()


def set_file_bytes(examples: Examples) -> bytes:
    """The JSON file of one set: ``{"index": [...], ARRAY: [one value per example], ...}``.

    Each array is a list with one item per example (nested lists for the per-observation
    arrays); keys are sorted, there is no whitespace, floats are written exactly (Python's
    shortest round-trip form) and NaN as null, so the bytes are the same on every machine.

    Raises:
        DataError: an array of a kind JSON cannot carry exactly (complex, text, infinite values).
    """
    arrays = set_arrays(examples)
    body: dict[str, Any] = {"index": list(range(len(examples)))}
    for name, a in arrays.items():
        if a.dtype.kind not in _DATA_TYPES:
            raise DataError(f"array {name!r} has dtype {a.dtype}, which the Croissant export does not carry")
        body[name] = _plain(np.asarray(a))
    return json.dumps(body, sort_keys=True, separators=(",", ":"), allow_nan=False).encode("ascii")


def _licence(pin: Mapping[str, Any]) -> str:
    return MIT if pin.get("kind") == "generated" else ORIGINAL_TERMS


def _provenance(pin: Mapping[str, Any]) -> str:
    if pin.get("kind") == "generated":
        return (
            f"generated by odmd-bench generator version {pin['generator_version']} (preset {pin['preset']}, "
            f"perturbation {pin['perturbation']}, seed {pin['seed']})"
        )
    if pin.get("kind") == "file":
        return (
            f"the original release's set (SHA-256 {pin['source_sha256']}), committed as {pin['file']} in the "
            "repository"
        )
    return (
        f"converted bit for bit from the original release's {pin['source']} (SHA-256 {pin['source_sha256']})"
    )


def _field(rs: str, name: str, a: np.ndarray, file_id: str) -> dict[str, Any]:
    shape = tuple(a.shape[1:])
    what = ARRAY_DESCRIPTIONS.get(name, f"an array of the source, shape {shape} per example")
    f: dict[str, Any] = {
        "@type": "cr:Field",
        "@id": f"{rs}/{name}",
        "name": f"{rs}/{name}",
        "description": f"{what} ({a.dtype}, shape {shape} per example)",
        "dataType": _DATA_TYPES[a.dtype.kind],
        "source": {"fileObject": {"@id": file_id}, "extract": {"jsonPath": f"$.{name}[*]"}},
    }
    if shape:
        f["repeated"] = True
    return f


_SET_COLUMNS: dict[str, tuple[str, str]] = {
    "split": ("sc:Text", "the split (val: for choosing, test: for reporting)"),
    "set": ("sc:Text", "the set"),
    "record_set": ("sc:Text", "the record set holding its examples"),
    "kind": (
        "sc:Text",
        "generated (by odmd-bench), file (committed original data) or import (original file)",
    ),
    "n": ("sc:Integer", "number of examples"),
    "n_obs": ("sc:Integer", "observations per example"),
    "generator_version": ("sc:Integer", "the generator version of a generated set (else null)"),
    "preset": ("sc:Text", "the generator preset of a generated set"),
    "perturbation": ("sc:Text", "the generator perturbation of a generated set"),
    "seed": ("sc:Integer", "the seed of a generated set"),
    "source_file": ("sc:Text", "the original release's file of an imported set"),
    "source_sha256": ("sc:Text", "the SHA-256 of that original file"),
    "content_sha256": (
        "sc:Text",
        "odmd-bench's hash of the set's arrays (docs/integrity.md), pinned in splits/",
    ),
    "meta_sha256": ("sc:Text", "odmd-bench's hash of the set's attributes, pinned in splits/"),
    "license": ("sc:URL", "the set's licence"),
    "fx": ("sc:Float", "focal length x, pixels (null where the source gives none)"),
    "fy": ("sc:Float", "focal length y, pixels"),
    "cx": ("sc:Float", "principal point x, pixels"),
    "cy": ("sc:Float", "principal point y, pixels"),
    "image_width": ("sc:Integer", "image width, pixels"),
    "image_height": ("sc:Integer", "image height, pixels"),
}


def croissant(
    benchmark: Benchmark, splits: Mapping[str, Mapping[str, Examples]]
) -> tuple[dict[str, Any], dict[str, bytes]]:
    """The Croissant description of a benchmark and the data files it describes.

    Args:
        benchmark: the benchmark.
        splits: ``{split: {set: examples}}``, every split and set of it, loaded and
            verified (:func:`odmd_bench.load_split`).

    Returns:
        ``(description, {path relative to the description: bytes})``: the JSON-LD as a dict
        and each set's JSON file (:func:`set_file_bytes`).

    Raises:
        DataError: a split or set is missing from ``splits``, or is not its pinned version.
    """
    pins = read_manifest(benchmark.name)["splits"]
    files: dict[str, bytes] = {}
    distribution: list[dict[str, Any]] = []
    record_sets: list[dict[str, Any]] = []
    rows: list[dict[str, Any]] = []
    problems = []
    for split in benchmark.splits:
        for set_name in benchmark.sets:
            ex = splits.get(split, {}).get(set_name)
            pin = pins.get(split, {}).get(set_name, {})
            if ex is None:
                problems.append(f"{split} {set_name}: not given")
                continue
            if ex.attrs.get("content_sha256") != pin.get("sha256"):
                problems.append(f"{split} {set_name}: its content hash is not the one pinned in splits/")
                continue
            path = set_file_name(benchmark, split, set_name)
            data = set_file_bytes(ex)
            files[path] = data
            rs = f"{split}/{set_name}"
            licence = _licence(pin)
            distribution.append(
                {
                    "@type": "cr:FileObject",
                    "@id": path,
                    "name": path,
                    "description": f"The {split} {set_name} set of {benchmark.name}, {len(ex)} examples: "
                    f"{_provenance(pin)}. Its arrays as JSON, written from the verified HDF5 set by "
                    f"`odmd-bench describe --format croissant {benchmark.name} -o DIR`. Licence: "
                    + ("MIT." if licence == MIT else ORIGINAL_TERMS_TEXT + "."),
                    "contentUrl": path,
                    "encodingFormat": "application/json",
                    "contentSize": f"{len(data)} B",
                    "sha256": hashlib.sha256(data).hexdigest(),
                    "license": licence,
                }
            )
            fields = [
                {
                    "@type": "cr:Field",
                    "@id": f"{rs}/index",
                    "name": f"{rs}/index",
                    "description": "the example's row in the set (what a predictions file's index column names)",
                    "dataType": "sc:Integer",
                    "source": {"fileObject": {"@id": path}, "extract": {"jsonPath": "$.index[*]"}},
                }
            ]
            fields += [_field(rs, name, a, path) for name, a in set_arrays(ex).items()]
            record_sets.append(
                {
                    "@type": "cr:RecordSet",
                    "@id": rs,
                    "name": rs,
                    "description": f"{benchmark.name} {split} {set_name}: one record per example "
                    f"({len(ex)}, {ex.n_obs} observations each); {_provenance(pin)}.",
                    "key": {"@id": f"{rs}/index"},
                    "field": fields,
                }
            )
            a = ex.attrs
            row = {
                "split": split,
                "set": set_name,
                "record_set": rs,
                "kind": pin.get("kind"),
                "n": len(ex),
                "n_obs": ex.n_obs,
                "generator_version": pin.get("generator_version"),
                "preset": pin.get("preset"),
                "perturbation": pin.get("perturbation"),
                "seed": pin.get("seed"),
                "source_file": a.get("source_file", pin.get("source", pin.get("file"))),
                "source_sha256": pin.get("source_sha256"),
                "content_sha256": a.get("content_sha256"),
                "meta_sha256": a.get("meta_sha256"),
                "license": licence,
                **{k: a.get(k) for k in ("fx", "fy", "cx", "cy", "image_width", "image_height")},
            }
            rows.append({f"sets/{k}": v for k, v in row.items()})
    if problems:
        raise DataError(
            f"cannot describe {benchmark.name}: every split and set must be given, verified", problems
        )
    record_sets.insert(
        0,
        {
            "@type": "cr:RecordSet",
            "@id": "sets",
            "name": "sets",
            "description": "One record per split and set: how it was made, its hashes, licence and camera.",
            "key": [{"@id": "sets/split"}, {"@id": "sets/set"}],
            "field": [
                {
                    "@type": "cr:Field",
                    "@id": f"sets/{k}",
                    "name": f"sets/{k}",
                    "dataType": t,
                    "description": d,
                }
                for k, (t, d) in _SET_COLUMNS.items()
            ],
            "data": rows,
        },
    )
    licences = sorted({d["license"] for d in distribution})
    doc: dict[str, Any] = {
        "@context": CONTEXT,
        "@type": "sc:Dataset",
        "conformsTo": CONFORMS_TO,
        "name": benchmark.name,
        "description": _description(benchmark, licences),
        "url": site_url(),
        "sameAs": [repository_url(), card_url()],
        "version": __version__,
        "citeAs": PAPER_BIBTEX,
        "license": licences if len(licences) > 1 else licences[0],
        "creator": [
            {"@type": "sc:Person", "name": "Brent A. Griffin"},
            {"@type": "sc:Person", "name": "Jason J. Corso"},
            {"@type": "sc:Organization", "name": "The odmd-bench authors", "url": repository_url()},
        ],
        "keywords": ["depth estimation", "object detection", "camera motion", "benchmark", "ODMD"],
        "isLiveDataset": False,
        **_rai(benchmark),
        "distribution": distribution,
        "recordSet": record_sets,
    }
    return doc, files


def _rai(benchmark: Benchmark) -> dict[str, Any]:
    """The Croissant RAI (responsible AI) properties: a summary of the benchmark card."""
    card = card_url()
    collection = (
        "Generated sets: generator version 1 of odmd-bench (a box-shaped object seen by a pinhole camera, from "
        "seeds pinned in splits/). Real sets: the original ODMD / ODMS release of Griffin and Corso (a mobile "
        "robot's end-effector camera locating YCB objects; for ODMS also a vehicle's camera), accepted only with "
        "the SHA-256 pinned in splits/odmd-original.json."
    )
    return {
        "rai:dataCollection": collection,
        "rai:dataCollectionType": ["Simulation", "Experiments"] if benchmark.generated else ["Experiments"],
        "rai:dataPreprocessingProtocol": [
            "None that changes a number: the importer keeps every value of the original files bit for bit (a "
            "missing detection becomes detected = false); the generator writes float64 arrays; each set is pinned "
            "by the SHA-256 of its arrays and of its attributes, checked on every load."
        ],
        "rai:dataUseCases": [
            "Scoring methods that estimate an object's depth from its bounding boxes and the camera's motion: "
            "choose on val, report on test. Not a measure of depth estimation from images (no image is given)."
        ],
        "rai:dataBiases": [
            "Short range (ODMD depths under 1.7 m), one robot's camera on YCB objects in one lab; ODMS-detection "
            "moves only forward along the optical axis. The Normal set is saturated (four methods score 0.00)."
        ],
        "rai:dataLimitations": [
            "Boxes, not pixels: the generated boxes are exact projections (plus noise on the perturbed sets); "
            f"the ODMS sets carry no camera intrinsics. See the benchmark card: {card}"
        ],
        "rai:personalSensitiveInformation": [
            "None: bounding boxes, camera positions and depths of objects; no people, images or identifiers."
        ],
        "rai:dataReleaseMaintenancePlan": (
            "A version never changes (its hashes are pinned); changes are new versions beside it; each version is "
            "scored for at least 24 months after its successor; errata are issues and CHANGELOG entries: "
            f"{repository_url()}/blob/main/docs/maintenance.md"
        ),
    }


def _description(benchmark: Benchmark, licences: list[str]) -> str:
    terms = (
        "The generated sets are MIT licensed; the sets from the original release keep its terms "
        f"({ORIGINAL_TERMS_TEXT}, {ORIGINAL_TERMS}); each file names its licence."
        if len(licences) > 1
        else "Licence: MIT."
        if licences == [MIT]
        else f"Licence: {ORIGINAL_TERMS_TEXT} ({ORIGINAL_TERMS})."
    )
    return (
        f"{benchmark.name}: {benchmark.description}. The ODMD task (Griffin and Corso, CVPR 2021): an object is "
        "seen from several camera positions; given its bounding box in each image and the camera's motion, "
        "estimate its depth at the last one. One record set per split and set (SPLIT/SET), one record per "
        "example; the record set `sets` says how each set was made (generator version and seed, or the "
        f"original file), with its hashes. {terms} How to load it: `pip install odmd-bench`, then "
        f"`odmd_bench.load_split(SPLIT, {benchmark.name!r})` (the verified HDF5 sets), or "
        f"`odmd-bench describe --format croissant {benchmark.name} -o DIR` writes this file with the JSON files "
        f"it describes, and `mlcroissant.Dataset('DIR/{benchmark.name}{SUFFIX}').records('test/SET')` reads "
        "them. The files are made on your machine from the verified sets (`odmd-bench generate` or "
        "`odmd-bench import`); their SHA-256 are the same everywhere. Benchmark card: " + card_url()
    )


def croissant_text(doc: Mapping[str, Any]) -> str:
    """The description as the file holds it: indented JSON, keys in the order built, a final newline."""
    return json.dumps(doc, indent=2, ensure_ascii=False) + "\n"


def write_croissant(
    out: str | os.PathLike[str], benchmark: Benchmark, doc: Mapping[str, Any], files: Mapping[str, bytes]
) -> list[Path]:
    """Write ``OUT/BENCHMARK.croissant.json`` and the files it describes, all or none.

    Returns:
        The paths written, the description first.

    Raises:
        StorageError: a file cannot be written (nothing is replaced then).
    """
    folder = Path(out)
    paths = [folder / f"{benchmark.name}{SUFFIX}", *(folder / rel for rel in files)]
    for p in paths:
        ensure_folder(p.parent)
    with atomic_paths(paths) as temps:
        temps[0].write_text(croissant_text(doc), encoding="utf-8")
        for tmp, data in zip(temps[1:], files.values(), strict=True):
            tmp.write_bytes(data)
    return paths


def describe_benchmark(
    benchmark: Benchmark, data_dir: str | os.PathLike[str] | None = None
) -> tuple[dict[str, Any], dict[str, bytes]]:
    """:func:`croissant` of a benchmark's sets as found in the data folder (each verified on load).

    A generated benchmark missing there is generated first; an imported one must have
    been imported (the error names the command).
    """
    from odmd_bench.data.store import load_split

    return croissant(benchmark, {s: load_split(s, benchmark, data_dir) for s in benchmark.splits})


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
