"""The fixed words of a Croissant description: the JSON-LD context, the licences, what each array and column means."""

from __future__ import annotations

from typing import Any

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

#: How each column of the record set ``sets`` is described: its Croissant data type and meaning.
SET_COLUMNS: dict[str, tuple[str, str]] = {
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
