"""`odmd-bench describe --format croissant`, read back by mlcroissant.

mlcroissant validates every benchmark's description, and reading a split through it gives
load_split's arrays, bit for bit.
"""

from __future__ import annotations

import functools
import hashlib
import json
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from click.testing import CliRunner

import odmd_bench
from odmd_bench import Examples
from odmd_bench.cli.main import cli
from odmd_bench.data.croissant import MIT, ORIGINAL_TERMS, SUFFIX, croissant, set_file_bytes
from odmd_bench.data.manifests import read_manifest
from odmd_bench.data.registry import BENCHMARKS, get_benchmark
from odmd_bench.errors import DataError

if os.environ.get("CI"):  # in the dev extra: CI must have it
    import mlcroissant as mlc
else:
    mlc = pytest.importorskip("mlcroissant")

# mlcroissant (1.1) builds its graph with rdflib's ConjunctiveGraph, which rdflib 7.1+ deprecates:
# their warning, not ours.
pytestmark = pytest.mark.filterwarnings("ignore:ConjunctiveGraph is deprecated:DeprecationWarning")


@pytest.fixture(scope="module", autouse=True)
def _set_files_once(croissant_set_files_made_once: None) -> None:
    """Each set's JSON file made once in the run (tests/conftest.py); set_file_bytes is tested directly."""


def _describe(benchmark: str, data_dir: Path, out: Path) -> Path:
    result = CliRunner().invoke(
        cli, ["describe", "--format", "croissant", benchmark, "-o", str(out), "--data-dir", str(data_dir)]
    )
    assert result.exit_code == 0, result.output + result.stderr
    path = out / f"{benchmark}{SUFFIX}"
    assert result.stdout.splitlines()[0] == str(path)
    return path


@pytest.fixture(scope="module")
def described(tmp_path_factory: pytest.TempPathFactory, request: pytest.FixtureRequest) -> dict[str, Any]:
    """``{"get": benchmark -> (description path, data folder)}``, each made once, when asked.

    odmd-v1 always; the others from the original release (skipped without it outside CI).
    """
    out = tmp_path_factory.mktemp("croissant")
    made: dict[str, tuple[Path, Path]] = {}

    def get(benchmark: str) -> tuple[Path, Path]:
        if benchmark not in made:
            fixture = "v1_data_dir" if benchmark == "odmd-v1" else "paper_data_dir"
            data = request.getfixturevalue(fixture)
            made[benchmark] = (_describe(benchmark, data, out), data)
        return made[benchmark]

    return {"get": get}


def _records(ds: Any, record_set: str) -> list[dict[str, Any]]:
    return list(ds.records(record_set))


@functools.cache
def _read(path: Path) -> Any:
    """The description as mlcroissant reads it, once per module (the tests only read from it)."""
    return mlc.Dataset(str(path))


@pytest.fixture(scope="module", autouse=True)
def _readings_forgotten() -> Iterator[None]:
    yield
    _read.cache_clear()


def _dataset(path: Path) -> Any:
    """The description read by mlcroissant; it raises on any error of the description."""
    ds = _read(path)
    assert not ds.metadata.ctx.issues.errors
    return ds


@pytest.mark.parametrize("bench", sorted(BENCHMARKS))
def test_mlcroissant_validates_each_description_and_every_file_is_as_described(
    described: dict[str, Any], bench: str
) -> None:
    benchmark = bench
    path, _ = described["get"](benchmark)
    ds = _dataset(path)
    doc = json.loads(path.read_text())
    assert doc["conformsTo"] == "http://mlcommons.org/croissant/1.0"
    meta = ds.metadata  # the responsible-AI summary of the card, as mlcroissant reads it
    assert meta.data_biases and meta.data_limitations and meta.personal_sensitive_information
    assert "maintenance.md" in meta.data_release_maintenance_plan
    b = get_benchmark(benchmark)
    pins = read_manifest(benchmark)["splits"]
    files = {f["@id"]: f for f in doc["distribution"]}
    assert len(files) == len(b.splits) * len(b.sets)
    for split in b.splits:
        for name in b.sets:
            f = files[f"{benchmark}/{split}/{name}.json"]
            data = (path.parent / f["contentUrl"]).read_bytes()
            assert f["sha256"] == hashlib.sha256(data).hexdigest()
            generated = pins[split][name]["kind"] == "generated"
            assert f["license"] == (MIT if generated else ORIGINAL_TERMS)
    sets = {(r["sets/split"], r["sets/set"]): r for r in _records(ds, "sets")}
    assert set(sets) == {(s, n) for s in b.splits for n in b.sets}
    for (split, name), row in sets.items():
        pin = pins[split][name]
        assert row["sets/content_sha256"] == pin["sha256"]
        assert row["sets/kind"] == pin["kind"]
        if pin["kind"] == "generated":
            assert (int(row["sets/seed"]), int(row["sets/generator_version"])) == (
                pin["seed"],
                pin["generator_version"],
            )
            assert row["sets/license"] == MIT
        else:
            assert row["sets/source_sha256"] == pin["source_sha256"]
            assert row["sets/license"] == ORIGINAL_TERMS


def _as_arrays(records: list[dict[str, Any]], record_set: str, like: Examples) -> dict[str, np.ndarray]:
    names = ["boxes", "detected", "camera", "depth", "observation_depth", *like.extras]
    out = {}
    for name in names:
        key = f"{record_set}/{name}"
        if key not in records[0]:
            continue
        values = [r[key] for r in records]
        ref = getattr(like, name, None) if name in Examples.__dataclass_fields__ else like.extras[name]
        out[name] = np.array(values, dtype=ref.dtype if ref.dtype.kind != "f" else np.float64)  # None -> NaN
    out["index"] = np.array([r[f"{record_set}/index"] for r in records])
    return out


def _assert_same(loaded: dict[str, np.ndarray], ex: Examples) -> None:
    expected = {
        "boxes": ex.boxes,
        "detected": ex.detected,
        "camera": ex.camera,
        "depth": ex.depth,
        **({"observation_depth": ex.observation_depth} if ex.observation_depth is not None else {}),
        **ex.extras,
    }
    assert set(loaded) - {"index"} == set(expected)
    np.testing.assert_array_equal(loaded["index"], np.arange(len(ex)))
    for name, want in expected.items():
        got = loaded[name]
        assert got.dtype == want.dtype and got.shape == want.shape, name
        # bit for bit: equal values, NaN where NaN (an unknown depth)
        assert np.array_equal(got, want, equal_nan=want.dtype.kind == "f"), name


def _check_split(path: Path, benchmark: str, split: str, data_dir: Path) -> None:
    ds = _dataset(path)
    for name, ex in odmd_bench.load_split(split, benchmark, data_dir).items():
        rs = f"{split}/{name}"
        _assert_same(_as_arrays(_records(ds, rs), rs, ex), ex)


def test_loading_odmd_v1_test_through_mlcroissant_equals_load_split(described: dict[str, Any]) -> None:
    """Generated sets (with every extra) and the committed robot set (unknown depths as NaN)."""
    path, data = described["get"]("odmd-v1")
    _check_split(path, "odmd-v1", "test", data)


@pytest.mark.slow
@pytest.mark.parametrize("bench", sorted(BENCHMARKS))
@pytest.mark.parametrize("split", ["val", "test"])
def test_loading_every_split_through_mlcroissant_equals_load_split(
    described: dict[str, Any], bench: str, split: str
) -> None:
    path, data = described["get"](bench)
    _check_split(path, bench, split, data)


def _tricky() -> Examples:
    """Floats whose shortest form is long or extreme, and an unknown observation depth."""
    boxes = np.array(
        [[[0.1 + 0.2, 5e-324, 1e308, 1 / 3], [2.0**-1074 * 3, 0.5, 0.25, 123456789.12345679]]],
    )
    camera = np.array([[[np.nextafter(0.0, 1.0), -0.0, 1e-300], [0.0, 0.0, 0.0]]])
    od = np.array([[np.nan, 1.0000000000000002]])
    return Examples(
        boxes=boxes,
        detected=np.array([[True, False]]),
        camera=camera,
        depth=np.array([np.pi]),
        observation_depth=od,
        extras={"count": np.array([[7, -3]], dtype=np.int64)},
    )


def test_the_json_of_a_set_carries_every_float_exactly_and_nan_as_null() -> None:
    ex = _tricky()
    text = set_file_bytes(ex)
    assert set_file_bytes(ex) == text  # the same bytes each time: a stable SHA-256
    body = json.loads(text)
    assert list(body) == sorted(body) and body["observation_depth"] == [[None, 1.0000000000000002]]
    for name in ("boxes", "camera", "depth"):
        back = np.array(body[name], dtype=np.float64)
        assert back.tobytes() == getattr(ex, name).tobytes(), name  # -0.0 and subnormals too
    assert body["count"] == [[7, -3]] and body["detected"] == [[True, False]]


def test_an_infinite_value_is_refused_not_written() -> None:
    ex = _tricky()
    bad = Examples(
        boxes=ex.boxes,
        detected=ex.detected,
        camera=ex.camera,
        depth=ex.depth,
        extras={"weird": np.array([[np.inf, 0.0]])},
    )
    with pytest.raises(DataError, match="infinite"):
        set_file_bytes(bad)


def _reference_set_file_bytes(examples: Examples) -> bytes:
    """set_file_bytes as it was written first, the reference the faster one must equal byte for byte.

    Each array as nested lists, NaN as None through an object array, then one json.dumps of
    the whole with sorted keys.
    """
    from odmd_bench.data.croissant.set_files import DATA_TYPES
    from odmd_bench.data.hashing import set_arrays

    def plain(a: np.ndarray) -> Any:
        if a.dtype.kind == "f":
            if np.isinf(a).any():
                raise DataError("an array holds an infinite value, which JSON cannot carry")
            nan = np.isnan(a)
            if nan.any():
                obj = a.astype(object)
                obj[nan] = None
                return obj.tolist()
        return a.tolist()

    body: dict[str, Any] = {"index": list(range(len(examples)))}
    for name, a in set_arrays(examples).items():
        if a.dtype.kind not in DATA_TYPES:
            raise DataError(f"array {name!r} has dtype {a.dtype}, which the Croissant export does not carry")
        body[name] = plain(np.asarray(a))
    return json.dumps(body, sort_keys=True, separators=(",", ":"), allow_nan=False).encode("ascii")


def _edge_sets() -> dict[str, Examples]:
    """Small sets at the edges: NaN in every float array, -0.0, other dtypes, odd names, no example."""
    ex = _tricky()
    nan_everywhere = Examples(
        boxes=np.where(np.eye(4, dtype=bool)[:2], np.nan, -0.0)[None],
        detected=ex.detected,
        camera=np.full((1, 2, 3), np.nan),
        depth=np.array([np.nan]),
        observation_depth=np.array([[np.nan, np.nan]]),
        extras={
            "index": np.array([[np.nan, 5e-324]]),  # an extra named as the index column replaces it
            'é"\\ NaN': np.array([[1.5, np.nan]], dtype=np.float32),  # a key to escape, holding "NaN"
            "u": np.array([[255, 0]], dtype=np.uint8),
            "nested": np.full((1, 2, 2, 2), np.nan),
        },
    )
    empty = Examples(
        boxes=np.zeros((0, 2, 4)),
        detected=np.zeros((0, 2), dtype=bool),
        camera=np.zeros((0, 2, 3)),
        depth=np.zeros(0),
        extras={"none_per_example": np.zeros((0, 0))},
    )
    hollow = Examples(
        boxes=ex.boxes, detected=ex.detected, camera=ex.camera, depth=ex.depth, extras={"e": np.zeros((1, 0))}
    )
    return {"tricky": ex, "nan everywhere": nan_everywhere, "empty": empty, "hollow": hollow}


def _assert_reference_bytes(sets: dict[str, Examples]) -> None:
    for name, ex in sets.items():
        assert set_file_bytes(ex) == _reference_set_file_bytes(ex), name


def test_the_json_of_a_set_is_the_reference_s_byte_for_byte_and_so_are_its_refusals(
    v1_data_dir: Path, tmp_path: Path
) -> None:
    """Generated sets (every extra), the committed robot sets (NaN depths), KITTI (integer arrays), edges."""
    v1 = odmd_bench.load_split("val", "odmd-v1", v1_data_dir, sets=["normal", "robot"])
    sets = {f"odmd-v1 val {k}": v for k, v in v1.items()}
    kitti = odmd_bench.load_split("test", "kitti-tracking", tmp_path)  # (copied there from splits/)
    sets |= {f"kitti {k}": v for k, v in kitti.items()}
    _assert_reference_bytes(sets | _edge_sets())
    ex = _tricky()
    for extras in (
        {"weird": np.array([[np.inf, 0.0]])},
        {"c": np.array([[1j, 0]]), "weird": np.array([[-np.inf, 0.0]])},  # the first problem is said
        {"weird": np.array([[np.nan, -np.inf]]), "c": np.array([[1j, 0]])},
        {"s": np.array([["a", "b"]])},
    ):
        bad = Examples(boxes=ex.boxes, detected=ex.detected, camera=ex.camera, depth=ex.depth, extras=extras)
        with pytest.raises(DataError) as want:
            _reference_set_file_bytes(bad)
        with pytest.raises(DataError) as got:
            set_file_bytes(bad)
        assert str(got.value) == str(want.value)


def test_the_json_of_an_imported_set_is_the_reference_s_byte_for_byte(paper_data_dir: Path) -> None:
    """Sets of the original release: odms-detection's driving set holds a few NaN depths, its robot set none."""
    sets = odmd_bench.load_split("val", "odms-detection", paper_data_dir, sets=["driving", "robot"])
    _assert_reference_bytes(sets)


def test_a_set_that_is_not_its_pinned_version_is_not_described(v1_data_dir: Path) -> None:
    b = get_benchmark("odmd-v1")
    splits = {s: odmd_bench.load_split(s, b, v1_data_dir) for s in b.splits}
    robot = splits["test"]["robot"]
    splits["test"]["robot"] = Examples(
        boxes=robot.boxes,
        detected=robot.detected,
        camera=robot.camera,
        depth=robot.depth,
        attrs={**robot.attrs, "content_sha256": "0" * 64},
    )
    del splits["val"]["camera"]
    with pytest.raises(DataError) as e:
        croissant(b, splits)
    assert e.value.problems == [
        "val camera: not given",
        "test robot: its content hash is not the one pinned in splits/",
    ]


def test_a_refused_description_writes_no_set_out(v1_data_dir: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Every set is checked before any is turned into JSON (seconds each): a refusal comes first."""
    from odmd_bench.data.croissant import description

    b = get_benchmark("odmd-v1")
    robot = odmd_bench.load_split("test", b, v1_data_dir, sets=["robot"])["robot"]

    def written(examples: Examples) -> bytes:
        raise AssertionError("a set was written out before the refusal")

    monkeypatch.setattr(description, "set_file_bytes", written)
    with pytest.raises(DataError) as e:
        croissant(b, {"test": {"robot": robot}})
    assert len(e.value.problems) == 7 and all(p.endswith(": not given") for p in e.value.problems)


def test_one_build_writes_a_set_it_meets_again_once_and_the_same(
    v1_data_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``made`` (what a site build passes for all its benchmarks): a set already made is not made again."""
    from odmd_bench.data.croissant import description

    b = get_benchmark("odmd-v1")
    splits = {s: odmd_bench.load_split(s, b, v1_data_dir) for s in b.splits}
    alone = croissant(b, splits)
    made: dict[str, bytes] = {}
    first = croissant(b, splits, made)
    assert first == alone and len(made) == 8
    make = description.set_file_bytes
    calls = []

    def counted(examples: Examples) -> bytes:
        calls.append(examples)
        return make(examples)

    monkeypatch.setattr(description, "set_file_bytes", counted)
    assert croissant(b, splits, made) == alone and calls == []


def test_cli_text_and_usage(v1_data_dir: Path, tmp_path: Path) -> None:
    runner = CliRunner()
    r = runner.invoke(cli, ["describe", "odmd-v1", "--data-dir", str(v1_data_dir)])
    assert r.exit_code == 0
    heads = [line for line in r.stdout.splitlines() if line.startswith("set ")]
    assert heads == [
        f"set {s} {n}: {k} examples x 10 observations"
        for s, k in (("val", 2400), ("test", 3000))
        for n in ("normal", "camera", "object", "robot")
    ]
    r = runner.invoke(cli, ["describe", "odmd-v1", "-o", str(tmp_path), "--data-dir", str(v1_data_dir)])
    assert r.exit_code == 2 and "--out is for --format croissant" in r.stderr
    assert not any(tmp_path.iterdir())
    r = runner.invoke(cli, ["describe", "--format", "croissant", "nope"])
    assert r.exit_code == 2 and "odmd-v1" in r.stderr
    printed = runner.invoke(
        cli, ["describe", "--format", "croissant", "odmd-v1", "--data-dir", str(v1_data_dir)]
    )
    assert printed.exit_code == 0
    doc = json.loads(printed.stdout)
    assert doc["name"] == "odmd-v1" and len(doc["recordSet"]) == 1 + 8
