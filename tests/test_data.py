"""Pinned sets, the data folder, atomic writes and verification."""

from __future__ import annotations

import os

import numpy as np
import pytest

import odmd_bench
from odmd_bench.data.hashing import content_sha256, set_arrays
from odmd_bench.data.io import read_set
from odmd_bench.data.manifests import manifest
from odmd_bench.data.registry import get_benchmark, set_file
from odmd_bench.data.store import build_set, ensure_generated
from odmd_bench.outputs import atomic_write


@pytest.mark.parametrize("split", ["val", "test"])
def test_every_pinned_set_regenerates_to_its_hash(split) -> None:
    entries = manifest(get_benchmark("odmd-v1"))["splits"][split]
    assert {k: e["n"] for k, e in entries.items()} == dict.fromkeys(
        ("normal", "camera", "object", "robot"), {"val": 2400, "test": 3000}[split]
    )
    for set_name, entry in entries.items():
        ex = build_set(get_benchmark("odmd-v1"), split, set_name)
        assert len(ex) == entry["n"]
        assert content_sha256(set_arrays(ex)) == entry["sha256"], f"{split} {set_name} changed"


def test_generated_files_load_with_the_pinned_content(v1_data_dir) -> None:
    for split in ("val", "test"):
        for set_name, entry in manifest(get_benchmark("odmd-v1"))["splits"][split].items():
            ex = odmd_bench.load(split, set_name, data_dir=v1_data_dir)
            assert ex.attrs["content_sha256"] == entry["sha256"]
            assert ex.attrs["benchmark"] == "odmd-v1" and ex.attrs["split"] == split


def test_content_hash_ignores_the_container_but_not_the_numbers() -> None:
    a = {"x": np.arange(6.0).reshape(2, 3)}
    assert content_sha256(a) == content_sha256({"x": np.asfortranarray(a["x"])})
    assert content_sha256(a) == content_sha256({"x": a["x"].astype(">f8")})
    b = {"x": a["x"].copy()}
    b["x"][1, 2] = np.nextafter(5.0, 6.0)
    assert content_sha256(a) != content_sha256(b)
    assert content_sha256(a) != content_sha256({"y": a["x"]})


def test_content_hash_is_the_documented_one_for_every_kind_of_array() -> None:
    """The hash reads the arrays' bytes in place; the reference copies them, as the docstring says."""
    import hashlib
    import json

    def reference(arrays: dict[str, np.ndarray]) -> str:
        h = hashlib.sha256()
        for name in sorted(arrays):
            a = np.asarray(arrays[name])
            dt = a.dtype.newbyteorder("<")
            a = np.ascontiguousarray(a, dtype=dt)
            h.update(json.dumps([name, dt.str, list(a.shape)], separators=(",", ":")).encode() + b"\n")
            h.update(a.tobytes())
        return h.hexdigest()

    kinds = {
        "empty": np.zeros((0, 10, 4)),
        "empty_middle": np.zeros((3, 0, 4), np.float32),
        "scalar": np.array(2.5),
        "bool": np.array([[True, False, True]]),
        "big_endian": np.arange(12, dtype=">i4").reshape(3, 4),
        "strided": np.arange(40.0).reshape(5, 8)[::2, 1::3],
        "fortran": np.asfortranarray(np.arange(6.0).reshape(2, 3)),
        "text": np.array(["ab", "c"]),
        "uint8": np.arange(7, dtype=np.uint8),
    }
    for name, a in kinds.items():
        assert content_sha256({name: a}) == reference({name: a}), name
    assert content_sha256(kinds) == reference(kinds)
    objects = {"o": np.array([1.5, "x"], dtype=object)}  # its "bytes" are pointers: hashed as copied
    assert content_sha256(objects) == reference(objects)


def test_existing_right_files_are_reused(tmp_path) -> None:
    first = ensure_generated("odmd-v1", ["val"], tmp_path)
    mtime = os.stat(first["val"]["path"]).st_mtime_ns
    second = ensure_generated("odmd-v1", ["val"], tmp_path)
    assert second["val"]["reused"] and os.stat(second["val"]["path"]).st_mtime_ns == mtime


def test_a_corrupt_file_is_detected_and_replaced(tmp_path) -> None:
    import h5py

    ensure_generated("odmd-v1", ["val"], tmp_path)
    path = set_file(get_benchmark("odmd-v1"), "val", tmp_path)
    with h5py.File(path, "r+") as f:
        f["camera/depth"][0] += 1e-9
    with pytest.raises(odmd_bench.DataError, match="corrupt"):
        odmd_bench.load("val", "camera", data_dir=tmp_path)
    assert not ensure_generated("odmd-v1", ["val"], tmp_path)["val"]["reused"]
    odmd_bench.load("val", "camera", data_dir=tmp_path)


def test_interrupted_write_leaves_the_good_file(tmp_path) -> None:
    target = tmp_path / "f.txt"
    target.write_text("good")
    with pytest.raises(RuntimeError), atomic_write(target, "w") as fh:
        fh.write("half")
        raise RuntimeError("killed")
    assert target.read_text() == "good"
    assert [p.name for p in tmp_path.iterdir()] == ["f.txt"]


def test_interrupted_generation_leaves_nothing_half_written(tmp_path, monkeypatch) -> None:
    import odmd_bench.data.io as io_mod

    def boom(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(io_mod, "content_sha256", boom)
    with pytest.raises(KeyboardInterrupt):
        io_mod.write_sets(tmp_path / "x.h5", {"normal": odmd_bench.generate(5)})
    assert list(tmp_path.iterdir()) == []


def test_load_generates_a_missing_generated_benchmark(tmp_path) -> None:
    ex = odmd_bench.load("val", "robot", data_dir=tmp_path)
    assert len(ex) == 2400 and set_file(get_benchmark("odmd-v1"), "val", tmp_path).exists()


@pytest.mark.parametrize(
    ("call", "args", "meant"),
    [
        ("load", ("robot", "test"), "load('test', 'robot')"),
        ("load", ("driving", "val", "odms-detection"), "load('val', 'driving', 'odms-detection')"),
        ("load_split", ("odmd-paper", "test"), "load_split('test', 'odmd-paper')"),
    ],
)
def test_swapped_arguments_get_the_call_as_meant(call, args, meant, tmp_path) -> None:
    with pytest.raises(odmd_bench.UsageError, match="the split comes first") as info:
        getattr(odmd_bench, call)(*args, data_dir=tmp_path)
    assert str(info.value).endswith(meant)
    assert not list(tmp_path.iterdir())  # refused before anything is generated


def test_load_of_a_missing_imported_benchmark_says_what_to_run(tmp_path) -> None:
    with pytest.raises(odmd_bench.DataError, match="odmd-bench import"):
        odmd_bench.load("test", "normal", "odmd-paper", tmp_path)


def test_bad_names_list_the_valid_ones(tmp_path) -> None:
    with pytest.raises(odmd_bench.UsageError, match="odmd-paper"):
        odmd_bench.load("test", "normal", "odmd-v2", tmp_path)
    with pytest.raises(odmd_bench.UsageError, match="val, test"):
        odmd_bench.load("train", "normal", data_dir=tmp_path)
    with pytest.raises(odmd_bench.UsageError, match="normal, camera, object, robot"):
        odmd_bench.load("test", "driving", data_dir=tmp_path)


def test_data_dir_default_and_env(tmp_path, monkeypatch) -> None:
    from odmd_bench.data.registry import default_data_dir

    monkeypatch.setenv("ODMD_BENCH_DATA", str(tmp_path / "d"))
    assert default_data_dir() == tmp_path / "d"
    monkeypatch.delenv("ODMD_BENCH_DATA")
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "xdg"))
    assert default_data_dir() == tmp_path / "xdg" / "odmd-bench"


def test_read_set_round_trip(tmp_path) -> None:
    from odmd_bench.data.io import write_sets

    ex = odmd_bench.generate(50, perturbation="both", rng=2)
    write_sets(tmp_path / "x.h5", {"object": ex})
    back = read_set(tmp_path / "x.h5", "object")
    for k, v in set_arrays(ex).items():
        assert np.array_equal(set_arrays(back)[k], v)
    assert back.attrs["fx"] == 205.5


def test_import_does_not_pull_in_torch() -> None:
    import subprocess
    import sys

    code = "import sys, odmd_bench, odmd_bench.cli; print('torch' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
