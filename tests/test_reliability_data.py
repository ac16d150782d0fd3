"""Reliability of the data folder (issue 16, items 1-4, 6 and 11).

Each test reproduces one way a hostile or unlucky user breaks the data files, and
asserts the outcome: a clear package error (exit 2, the fixing command named), a
rebuild by ``generate``/``import``, or the right data. Never a wrong score.
"""

from __future__ import annotations

import errno
import os
import shutil
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import h5py
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import odmd_bench
from odmd_bench.data.hashing import content_sha256, meta_sha256
from odmd_bench.data.io import read_set, write_sets
from odmd_bench.data.manifests import manifest
from odmd_bench.data.registry import get_benchmark, set_file
from odmd_bench.data.store import ensure_generated
from odmd_bench.errors import DataError, MissingDataError, StorageError
from odmd_bench.outputs import atomic_path, clean_stale_temps, locked

ODMD_SETS = ("normal", "camera", "object", "robot")


@pytest.fixture(scope="module")
def v1(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A pristine generated data folder (copied by each test that damages it)."""
    d = tmp_path_factory.mktemp("v1")
    ensure_generated("odmd-v1", ("val", "test"), d)
    return d


def _copy(src: Path, dst: Path) -> Path:
    shutil.copytree(src, dst)
    return dst


def _cli(*args: str, env_data: Path | None = None, **kw: object) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ)
    if env_data is not None:
        env["ODMD_BENCH_DATA"] = str(env_data)
    return subprocess.run(
        [sys.executable, "-m", "odmd_bench", *args],
        capture_output=True,
        text=True,
        env=env,
        check=False,
        **kw,
    )  # type: ignore[call-overload]


def _clear_error(done: subprocess.CompletedProcess[str], *needles: str) -> None:
    assert done.returncode == 2, done.stderr
    assert "Traceback" not in done.stderr and "internal error" not in done.stderr
    for n in needles:
        assert n in done.stderr, done.stderr


def _robust_like(ex: odmd_bench.Examples) -> float:
    """A number that depends on the intrinsics, as the robust and parallax methods do."""
    fx, fy, cx, cy, w, h = ex.intrinsics()
    return float(np.mean(ex.boxes[:, -1, 0] * w - cx) / fx)


# ---------------------------------------------------------------- 1: metadata


def test_edited_intrinsics_are_refused_then_rebuilt(v1: Path, tmp_path: Path) -> None:
    d = _copy(v1, tmp_path / "d")
    right = _robust_like(odmd_bench.load("test", "normal", data_dir=d))
    path = set_file(get_benchmark("odmd-v1"), "test", d)
    with h5py.File(path, "r+") as f:
        for g in f.values():
            g.attrs["fx"] = 411.0
    with pytest.raises(DataError, match=r"altered: its attributes .*odmd-bench generate --data-dir"):
        odmd_bench.load("test", "normal", data_dir=d)
    messages: list[str] = []
    result = ensure_generated("odmd-v1", ["test"], d, progress=messages.append)
    assert result["test"]["replaced"] and not result["test"]["reused"]
    assert any(m.startswith(f"replacing {path}") and "altered" in m for m in messages)
    assert _robust_like(odmd_bench.load("test", "normal", data_dir=d)) == right


@pytest.mark.parametrize(
    ("key", "value"),
    [("image_width", 1280), ("cy", 0.0), ("generator_version", 2), ("set", "camera"), ("extra_note", "x")],
)
def test_every_attribute_is_covered(v1: Path, tmp_path: Path, key: str, value: object) -> None:
    d = _copy(v1, tmp_path / "d")
    with h5py.File(set_file(get_benchmark("odmd-v1"), "val", d), "r+") as f:
        f["normal"].attrs[key] = value
    with pytest.raises(DataError):
        odmd_bench.load("val", "normal", data_dir=d)


def test_meta_hash_is_canonical() -> None:
    a = {"fx": 205.5, "image_width": 640, "set": "normal", "content_sha256": "x"}
    assert meta_sha256(a) == meta_sha256({**a, "content_sha256": "y", "meta_sha256": "z"})
    assert meta_sha256(a) == meta_sha256({k: a[k] for k in reversed(list(a))})
    assert meta_sha256(a) == meta_sha256({**a, "fx": np.float64(205.5), "image_width": np.int64(640)})
    assert meta_sha256(a) != meta_sha256({**a, "fx": float(np.nextafter(205.5, 300))})
    assert meta_sha256(a) != meta_sha256({**a, "image_width": 640.0})


# ------------------------------------------------------------ 2: identity, pins


def test_a_file_of_another_benchmark_is_refused(v1: Path, tmp_path: Path) -> None:
    d = tmp_path / "d"
    set_file(get_benchmark("odmd-paper"), "test", d).parent.mkdir(parents=True)
    shutil.copy(
        set_file(get_benchmark("odmd-v1"), "test", v1), set_file(get_benchmark("odmd-paper"), "test", d)
    )
    with pytest.raises(DataError, match="found as benchmark 'odmd-paper'") as info:
        odmd_bench.load("test", "normal", "odmd-paper", d)
    assert "odmd-bench import" in info.value.render()
    set_file(get_benchmark("odmd-v1"), "test", d).parent.mkdir(parents=True)
    shutil.copy(set_file(get_benchmark("odmd-v1"), "val", v1), set_file(get_benchmark("odmd-v1"), "test", d))
    with pytest.raises(DataError, match="found as split 'test'"):
        odmd_bench.load("test", "normal", data_dir=d)


def test_a_renamed_group_is_refused(v1: Path, tmp_path: Path) -> None:
    d = _copy(v1, tmp_path / "d")
    with h5py.File(set_file(get_benchmark("odmd-v1"), "val", d), "r+") as f:
        f.move("normal", "tmp")
        f.move("camera", "normal")
        f.move("tmp", "camera")
    with pytest.raises(DataError, match="says it is set 'camera'"):
        odmd_bench.load("val", "normal", data_dir=d)


@pytest.fixture()
def paper_copy(paper_data_dir: Path, tmp_path: Path) -> Path:
    return _copy(paper_data_dir, tmp_path / "paper")


def test_imported_sets_are_pinned(paper_data_dir: Path) -> None:
    for bench in ("odmd-paper", "odms-detection"):
        for split in ("val", "test"):
            for s, entry in manifest(get_benchmark(bench))["splits"][split].items():
                ex = odmd_bench.load(split, s, bench, paper_data_dir)
                assert ex.attrs["content_sha256"] == entry["sha256"]
                assert ex.attrs["meta_sha256"] == entry["meta_sha256"]
                assert ex.attrs["source_sha256"] == entry["source_sha256"]


@pytest.mark.parametrize("recompute_meta", [False, True])
def test_an_edited_imported_set_is_refused_even_with_its_hashes_recomputed(
    paper_copy: Path, recompute_meta: bool
) -> None:
    path = set_file(get_benchmark("odmd-paper"), "test", paper_copy)
    with h5py.File(path, "r+") as f:
        g = f["object"]
        depth = g["depth"][()]
        depth[:100] *= 2
        g["depth"][...] = depth
        g.attrs["content_sha256"] = content_sha256({k: g[k][()] for k in g})
        if recompute_meta:
            attrs = {k: v for k, v in g.attrs.items()}
            g.attrs["meta_sha256"] = meta_sha256(attrs)
    with pytest.raises(DataError, match=r"differs from the pinned .* splits/odmd-paper.json"):
        odmd_bench.load("test", "object", "odmd-paper", paper_copy)
    odmd_bench.load("test", "camera", "odmd-paper", paper_copy)  # the other sets are fine


def test_a_set_from_the_wrong_original_is_refused(paper_copy: Path) -> None:
    src = set_file(get_benchmark("odmd-paper"), "val", paper_copy)
    dst = set_file(get_benchmark("odmd-paper"), "test", paper_copy)
    ex = read_set(src, "robot")
    ex.attrs.update(split="test")
    sets = {s: read_set(dst, s) for s in ODMD_SETS if s != "robot"}
    write_sets(dst, {**sets, "robot": ex}, file_attrs={"benchmark": "odmd-paper", "split": "test"})
    with pytest.raises(DataError, match="conversion of data/odmd/val/val_robot.pk"):
        odmd_bench.load("test", "robot", "odmd-paper", paper_copy)


def test_pins_are_reproducible(original_release: Path) -> None:
    script = Path(__file__).resolve().parents[1] / "scripts" / "pin_splits.py"
    done = subprocess.run(
        [sys.executable, str(script), "--original", str(original_release), "--check"],
        capture_output=True,
        text=True,
        check=False,
    )
    assert done.returncode == 0, done.stderr


# ----------------------------------------------------- 3: damaged HDF5 metadata


def _flip(path: Path, pos: int) -> None:
    data = bytearray(path.read_bytes())
    data[pos] ^= 0x80
    path.write_bytes(bytes(data))


def test_a_flipped_header_byte_is_a_clear_error_and_generate_rebuilds(v1: Path, tmp_path: Path) -> None:
    d = _copy(v1, tmp_path / "d")
    path = set_file(get_benchmark("odmd-v1"), "test", d)
    _flip(path, 499)
    done = _cli("baseline", "box-ls", "-o", str(tmp_path / "p.csv"), env_data=d)
    _clear_error(done, str(path), "odmd-bench generate")
    done = _cli("generate", env_data=d)
    assert done.returncode == 0, done.stderr
    assert f"replacing {path}" in done.stderr and "damaged" in done.stderr
    assert "test.h5 (rebuilt;" in done.stdout
    assert len(odmd_bench.load("test", "normal", data_dir=d)) == 3000


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(pos=st.integers(min_value=0, max_value=4095), bit=st.integers(min_value=0, max_value=7))
def test_any_flipped_bit_gives_the_right_set_or_a_data_error(tmp_path: Path, pos: int, bit: int) -> None:
    src = tmp_path / "src.h5"
    if not src.exists():
        sets = {s: odmd_bench.generate(20, rng=i) for i, s in enumerate(("normal", "camera"))}
        write_sets(src, sets, file_attrs={"benchmark": "odmd-v1", "split": "val"})
    want = {s: read_set(src, s).attrs["content_sha256"] for s in ("normal", "camera")}
    data = bytearray(src.read_bytes())
    data[pos % len(data)] ^= 1 << bit
    bad = tmp_path / "bad.h5"
    bad.write_bytes(bytes(data))
    for s in ("normal", "camera"):
        try:
            ex = read_set(bad, s)
        except DataError:
            continue
        assert ex.attrs["content_sha256"] == want[s]


def test_import_rebuilds_an_unreadable_file(paper_copy: Path, original_release: Path) -> None:
    path = set_file(get_benchmark("odmd-paper"), "test", paper_copy)
    with open(path, "r+b") as fh:
        fh.write(b"\0" * 8)  # no HDF5 signature: nothing of the file can be read
    messages: list[str] = []
    from odmd_bench.data.importer import import_release

    import_release(
        original_release / "odmd" / "test" / "test_normal.pk", paper_copy, progress=messages.append
    )
    assert any("cannot be read and is replaced" in m for m in messages), messages
    assert len(odmd_bench.load("test", "normal", "odmd-paper", paper_copy)) == 3000
    with pytest.raises(DataError, match="holds no set 'robot'"):
        odmd_bench.load("test", "robot", "odmd-paper", paper_copy)


def test_import_keeps_the_good_sets_of_a_damaged_split(paper_copy: Path, original_release: Path) -> None:
    path = set_file(get_benchmark("odmd-paper"), "test", paper_copy)
    with h5py.File(path, "r+") as f:
        f["robot/depth"][0] += 1.0
    messages: list[str] = []
    from odmd_bench.data.importer import import_release

    import_release(
        original_release / "odmd" / "test" / "test_normal.pk", paper_copy, progress=messages.append
    )
    assert len(messages) == 1 and "dropped the set 'robot'" in messages[0] and "corrupt" in messages[0]
    with h5py.File(path, "r") as f:
        assert list(f) == ["normal", "camera", "object"]
    for s in ("normal", "camera", "object"):
        odmd_bench.load("test", s, "odmd-paper", paper_copy)


# ------------------------------------------------------------ 4: OS failures


def _no_temp_left(folder: Path) -> None:
    assert not [p for p in folder.rglob("*") if p.name.endswith(".tmp")]


def test_a_file_size_limit_is_a_clear_error(tmp_path: Path) -> None:
    import resource

    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (2_000_000, resource.RLIM_INFINITY))

    done = _cli("generate", env_data=tmp_path / "d", preexec_fn=limit)
    _clear_error(done, "cannot write", "File too large", "ulimit -f")
    errors = [line for line in done.stderr.splitlines() if line.startswith("error:")]
    assert len(errors) == 1 and len(errors[0]) < 300, done.stderr
    _no_temp_left(tmp_path / "d")
    assert not (tmp_path / "d" / "odmd-v1" / "val.h5").exists()


@pytest.fixture()
def small_tmpfs(tmp_path: Path) -> object:
    """A 3 MB tmpfs (root only, where mounting is allowed), else skip."""
    mnt = tmp_path / "mnt"
    mnt.mkdir()
    if os.geteuid() != 0 or shutil.which("mount") is None:
        pytest.skip("mounting a small tmpfs needs root")
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=3m", "tmpfs", str(mnt)], capture_output=True)
    if done.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {done.stderr!r}")
    yield mnt
    subprocess.run(["umount", str(mnt)], check=True)


def test_a_full_disk_is_a_clear_error(small_tmpfs: Path) -> None:
    done = _cli("generate", env_data=small_tmpfs)
    _clear_error(done, "No space left on device", "free space")
    _no_temp_left(small_tmpfs)


def test_write_errors_are_storage_errors(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The same, for each cause, by making the final rename fail."""
    import odmd_bench.outputs.atomic as atomic_mod

    for code, fix in ((errno.ENOSPC, "free space"), (errno.EACCES, "writable"), (errno.EROFS, "read-only")):

        def fail(src: str, dst: str, code: int = code) -> None:
            raise OSError(code, os.strerror(code), dst)

        monkeypatch.setattr(atomic_mod.os, "replace", fail)
        with pytest.raises(StorageError, match=fix) as info:
            write_sets(tmp_path / "x.h5", {"normal": odmd_bench.generate(3)})
        assert isinstance(info.value, OSError) and info.value.errno == code
        assert str(tmp_path / "x.h5") in str(info.value)
        _no_temp_left(tmp_path)
        monkeypatch.undo()


def test_a_read_only_folder_is_a_clear_error(tmp_path: Path) -> None:
    d = tmp_path / "ro"
    d.mkdir()
    if os.geteuid() == 0:
        mounted = subprocess.run(
            ["mount", "-t", "tmpfs", "-o", "ro,size=1m", "tmpfs", str(d)], capture_output=True
        )
        if mounted.returncode != 0:
            pytest.skip("root ignores permissions and cannot mount a read-only tmpfs here")
        try:
            done = _cli("generate", env_data=d)
        finally:
            subprocess.run(["umount", str(d)], check=True)
        _clear_error(done, str(d), "read-only")
    else:
        d.chmod(0o555)
        try:
            done = _cli("generate", env_data=d)
        finally:
            d.chmod(0o755)
        _clear_error(done, str(d), "writable")


def test_a_data_folder_that_is_a_file(tmp_path: Path) -> None:
    f = tmp_path / "file"
    f.write_text("x")
    for args in (["generate"], ["baseline", "box-ls", "-o", str(tmp_path / "p.csv")]):
        _clear_error(_cli(*args, env_data=f), str(f), "ODMD_BENCH_DATA")
    with pytest.raises(StorageError, match="Not a directory"):
        odmd_bench.load("val", "normal", data_dir=f)


def test_a_data_file_that_is_a_folder(tmp_path: Path) -> None:
    path = set_file(get_benchmark("odmd-v1"), "test", tmp_path)
    path.mkdir(parents=True)
    with pytest.raises(StorageError, match=r"it is a folder.*rm -r") as info:
        odmd_bench.load("test", "normal", data_dir=tmp_path)
    assert isinstance(info.value, IsADirectoryError | OSError) and info.value.errno == errno.EISDIR
    _clear_error(_cli("generate", "--split", "test", env_data=tmp_path), f"rm -r {path}")


def test_a_missing_imported_file_is_a_file_not_found_error(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError, match="odmd-bench import"):
        odmd_bench.load("test", "normal", "odmd-paper", tmp_path)
    with pytest.raises(MissingDataError):
        read_set(tmp_path / "none.h5", "normal")


def test_errors_subclass_the_builtins() -> None:
    from odmd_bench import errors

    assert issubclass(errors.DataError, ValueError) and issubclass(errors.ConfigError, ValueError)
    assert issubclass(errors.ValidationError, ValueError) and issubclass(errors.UsageError, ValueError)
    assert issubclass(errors.StorageError, OSError) and issubclass(errors.StorageError, errors.DataError)
    assert issubclass(errors.MissingDataError, FileNotFoundError)
    long = errors.DataError("x" * 100_000, ["y" * 100_000])
    assert len(str(long)) < 2 * errors.MAX_LINE + 100


# ------------------------------------------------------ 6: concurrent writers


def test_concurrent_imports_keep_both_sets(original_release: Path, tmp_path: Path) -> None:
    files = [original_release / "odmd" / "val" / f"val_{n}.pk" for n in ("normal", "robot")]
    script = textwrap.dedent(
        """
        import sys, time
        from odmd_bench.data.importer import import_release
        start = float(sys.argv[3])
        while time.time() < start:
            time.sleep(0.001)
        import_release(sys.argv[1], sys.argv[2])
        """
    )
    for trial in range(10):
        d = tmp_path / str(trial)
        start = time.time() + 0.5  # both processes start importing together
        procs = [
            subprocess.Popen(
                [sys.executable, "-c", script, str(f), str(d), repr(start)], stderr=subprocess.PIPE
            )
            for f in files
        ]
        for p in procs:
            _, err = p.communicate()
            assert p.returncode == 0, err
        with h5py.File(set_file(get_benchmark("odmd-paper"), "val", d), "r") as f:
            assert sorted(f) == ["normal", "robot"], f"trial {trial} lost a set"


def test_concurrent_generates_write_once(tmp_path: Path) -> None:
    procs = [
        subprocess.Popen(
            [sys.executable, "-m", "odmd_bench", "generate", "--split", "val", "--out", str(tmp_path)],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for _ in range(2)
    ]
    outs = [p.communicate()[0] for p in procs]
    assert all(p.returncode == 0 for p in procs)
    assert sum("(written;" in o for o in outs) >= 1
    odmd_bench.load("val", "robot", data_dir=tmp_path)


# -------------------------------------------------- 11: SIGKILL's temporary files


def test_a_sigkilled_writer_leaves_a_temp_file_that_the_next_write_removes(tmp_path: Path) -> None:
    target = tmp_path / "odmd-v1" / "val.h5"
    script = textwrap.dedent(
        """
        import sys, time
        from odmd_bench.outputs import atomic_path
        with atomic_path(sys.argv[1]) as tmp:
            tmp.write_bytes(b"half" * 1000)
            print(tmp, flush=True)
            time.sleep(3600)
        """
    )
    child = subprocess.Popen([sys.executable, "-c", script, str(target)], stdout=subprocess.PIPE, text=True)
    assert child.stdout is not None
    tmp = Path(child.stdout.readline().strip())
    # A live writer's file is not touched by another writer's clean-up.
    assert clean_stale_temps(target) == [] and tmp.exists()
    child.send_signal(signal.SIGKILL)
    child.wait()
    child.stdout.close()
    assert tmp.exists() and not target.exists()
    messages: list[str] = []
    ensure_generated("odmd-v1", ["val"], tmp_path, progress=messages.append)
    assert not tmp.exists() and any(str(tmp) in m for m in messages)
    _no_temp_left(tmp_path)


def test_a_sigkilled_lock_holder_leaves_the_lock_free(tmp_path: Path) -> None:
    """The lock dies with its holder: the next writer takes it (it would wait forever if not)."""
    target = tmp_path / "odmd-v1" / "val.h5"
    script = textwrap.dedent(
        """
        import sys, time
        from odmd_bench.outputs import locked
        with locked(sys.argv[1]):
            print("held", flush=True)
            time.sleep(3600)
        """
    )
    child = subprocess.Popen([sys.executable, "-c", script, str(target)], stdout=subprocess.PIPE, text=True)
    assert child.stdout is not None
    assert child.stdout.readline().strip() == "held"
    child.send_signal(signal.SIGKILL)
    child.wait()
    child.stdout.close()
    lock = target.parent / ".val.h5.lock"
    assert lock.exists()  # a killed writer's lock file stays...
    with locked(target) as held:
        assert held == lock
    assert not lock.exists()  # ...until the next writer of that file removes it


def test_writers_leave_no_lock_file_in_the_data_folder(v1: Path) -> None:
    """``generate`` held a lock on each split's file while it wrote it; none is left."""
    assert sorted(p.name for p in v1.rglob("*.h5")) == ["test.h5", "val.h5"]
    assert [p.name for p in v1.rglob("*.lock")] == []


def test_only_stale_temp_files_of_the_target_are_removed(tmp_path: Path) -> None:
    """A dead local writer's file goes; a live one's never; others' only when old."""
    from odmd_bench.outputs.temps import _host

    target = tmp_path / "test.h5"
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    here = _host()
    files = {
        "dead": tmp_path / f".test.h5.{here}-{dead.pid}.abcd1234.tmp",
        "live": tmp_path / f".test.h5.{here}-{os.getppid()}.abcd1234.tmp",
        "old_live": tmp_path / f".test.h5.{here}-{os.getppid()}.efgh5678.tmp",
        "other_host_new": tmp_path / f".test.h5.elsewhere-{dead.pid}.abcd1234.tmp",
        "other_host_old": tmp_path / f".test.h5.elsewhere-{os.getppid()}.efgh5678.tmp",
        "legacy_old": tmp_path / ".test.h5.k2j3h4g5.tmp",
        "legacy_new": tmp_path / ".test.h5.q1w2e3r4.tmp",
        "other_target": tmp_path / f".val.h5.{here}-{dead.pid}.abcd1234.tmp",
        "not_ours": tmp_path / "test.h5.tmp",
    }
    for p in files.values():
        p.write_text("x")
    old = time.time() - 2 * 3600
    for k in ("old_live", "other_host_old", "legacy_old"):
        os.utime(files[k], (old, old))
    removed = set(clean_stale_temps(target))
    assert removed == {files["dead"], files["other_host_old"], files["legacy_old"]}


def test_text_is_written_as_utf8_whatever_the_locale(tmp_path: Path) -> None:
    """atomic_write in text mode writes UTF-8 even where the locale's encoding is ASCII."""
    out = tmp_path / "t.md"
    code = f"from odmd_bench.outputs import atomic_write\nwith atomic_write({str(out)!r}, 'w') as f: f.write('\\u2265 5')"
    env = {**os.environ, "LC_ALL": "C", "LANG": "C", "PYTHONUTF8": "0", "PYTHONCOERCECLOCALE": "0"}
    subprocess.run([sys.executable, "-X", "utf8=0", "-c", code], env=env, check=True)
    assert out.read_bytes() == "≥ 5".encode()


def test_file_attributes_other_than_identity_reach_no_set(paper_copy: Path) -> None:
    # No hash covers the file's own attributes: an intrinsics injected there must not give
    # the uncalibrated ODMS sets a camera, nor relabel the data's version.
    path = set_file(get_benchmark("odms-detection"), "val", paper_copy)
    with h5py.File(path, "r+") as f:
        f.attrs.update({"fx": 205.5, "fy": 205.5, "cx": 320.5, "cy": 240.5, "generator_version": 99})
    ex = odmd_bench.load("val", "normal", "odms-detection", paper_copy)
    assert "fx" not in ex.attrs and "generator_version" not in ex.attrs
    with pytest.raises(DataError, match="no camera intrinsics"):
        ex.intrinsics()
    assert ex.attrs["benchmark"] == "odms-detection" and ex.attrs["split"] == "val"


def test_an_array_larger_than_the_set_is_refused_before_it_is_read(v1: Path, tmp_path: Path) -> None:
    d = _copy(v1, tmp_path / "d")
    path = set_file(get_benchmark("odmd-v1"), "val", d)
    with h5py.File(path, "r+") as f:  # 80 TB of zeros, a few hundred bytes on disk
        f["normal"].create_dataset("zzz", shape=(10**13,), dtype="f8", chunks=(10**6,), compression="gzip")
        f["camera"].create_group("sub")
    with pytest.raises(DataError, match="is not a set of examples") as info:
        read_set(path, "normal")
    assert (
        "'zzz' has shape (10000000000000,); every array has one row per example (2400)" in info.value.render()
    )
    with pytest.raises(DataError, match="'sub' is a Group, not an array"):
        read_set(path, "camera")
    _clear_error(_cli("info", "--stats", str(path)), "is not a set of examples")


def test_a_pipe_in_a_data_file_place_is_an_error_not_a_wait(tmp_path: Path) -> None:
    path = set_file(get_benchmark("odmd-v1"), "val", tmp_path)
    path.parent.mkdir(parents=True)
    os.mkfifo(path)
    with pytest.raises(DataError, match="not a regular file"):
        read_set(path, "normal")  # h5py would wait for a writer forever
    _clear_error(_cli("info", str(path)), "not a regular file")


def test_generating_more_than_memory_holds_is_a_usage_error() -> None:
    with pytest.raises(odmd_bench.UsageError, match=r"do not fit in memory; generate fewer at a time"):
        odmd_bench.generate(10**12)


def test_a_fix_given_by_the_caller_is_kept_as_written() -> None:
    from odmd_bench.os_errors import storage_error

    e = storage_error(
        PermissionError(errno.EACCES, "denied"), "/d/x.h5", "read", "run `import PATH/TO/original`"
    )
    assert str(e).endswith("; run `import PATH/TO/original`")  # not /d/x.h5/TO/original
    e = storage_error(IsADirectoryError(errno.EISDIR, "dir"), "/d/x.h5", "write")
    assert "rm -r /d/x.h5" in str(e)


def test_a_dangling_link_as_the_data_folder_is_named_as_such(tmp_path: Path) -> None:
    link = tmp_path / "data"
    link.symlink_to(tmp_path / "gone")
    _clear_error(_cli("generate", "--split", "val", env_data=link), f"a symbolic link to {tmp_path / 'gone'}")


def test_a_pipe_in_a_data_file_place_is_replaced_by_the_writer_not_written_into(tmp_path: Path) -> None:
    """Writing the set into the pipe would block until a reader came: forever."""
    path = set_file(get_benchmark("odmd-v1"), "val", tmp_path)
    path.parent.mkdir(parents=True)
    os.mkfifo(path)
    ex = odmd_bench.generate(5, rng=0)
    ex.attrs.update(benchmark="odmd-v1", split="val", set="normal")
    write_sets(path, {"normal": ex})
    assert path.is_file() and len(read_set(path, "normal")) == 5


def _two_files(tmp_path: Path) -> tuple[Path, Path]:
    a, b = tmp_path / "a.txt", tmp_path / "b.txt"
    a.write_text("old a")
    b.write_text("old b")
    return a, b


def test_several_files_are_replaced_all_or_none_when_a_move_fails(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The second file cannot be replaced (an immutable file, say): the first gets its old text back."""
    from odmd_bench.outputs import atomic

    a, b = _two_files(tmp_path)
    real = os.replace

    def refuse_b(src: str | os.PathLike[str], dst: str | os.PathLike[str]) -> None:
        if Path(dst) == b:
            raise PermissionError(errno.EPERM, "Operation not permitted")
        real(src, dst)

    monkeypatch.setattr(atomic.os, "replace", refuse_b)
    with (
        pytest.raises(StorageError, match=r"cannot write .*b\.txt: Operation not permitted"),
        atomic.atomic_texts([(a, "new a"), (b, "new b")]),
    ):
        pass
    monkeypatch.undo()
    assert (a.read_text(), b.read_text()) == ("old a", "old b")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.txt", "b.txt"]  # no temp, no backup left
    # A file that did not exist before is removed again.
    c = tmp_path / "c.txt"
    monkeypatch.setattr(atomic.os, "replace", refuse_b)
    with pytest.raises(StorageError), atomic.atomic_texts([(c, "new c"), (b, "new b")]):
        pass
    monkeypatch.undo()
    assert not c.exists() and b.read_text() == "old b"


def test_a_folder_in_the_place_of_one_file_stops_every_file_before_any_moves(tmp_path: Path) -> None:
    from odmd_bench.outputs import atomic_paths, atomic_texts

    a, b = _two_files(tmp_path)
    b.unlink()
    b.mkdir()
    with (
        pytest.raises(StorageError, match="a folder stands where the file belongs"),
        atomic_texts([(a, "new a"), (b, "new b")], also=[tmp_path / "fig.png"]) as (fig,),
    ):
        fig.write_bytes(b"png")
    assert a.read_text() == "old a" and not (tmp_path / "fig.png").exists()
    with atomic_paths([a, tmp_path / "fig.png"]) as (ta, tf):
        ta.write_text("new a")
        tf.write_bytes(b"png")
    assert a.read_text() == "new a" and (tmp_path / "fig.png").read_bytes() == b"png"


def test_a_link_to_a_pipe_is_written_into_through_the_link() -> None:
    """/dev/stdout leads to a pipe with no path of its own (/proc/self/fd/1 -> pipe:[N])."""
    code = (
        "from odmd_bench.outputs import atomic_write, atomic_texts\n"
        "with atomic_write('/dev/stdout', 'w') as f: f.write('one\\n')\n"
        "with atomic_texts([('/dev/stdout', 'two\\n')]): pass\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert done.stdout == "one\ntwo\n"


def test_a_file_name_that_is_not_utf8_is_written_back_as_its_bytes(tmp_path: Path) -> None:
    from odmd_bench.outputs import atomic_texts, atomic_write

    name = os.fsdecode(b"bad\xff.csv")  # as Python gets it from the command line
    with atomic_write(tmp_path / "r.txt", "w") as fh:
        fh.write(f"scored {name}\n")
    with atomic_texts([(tmp_path / "s.txt", name)]):
        pass
    assert (tmp_path / "r.txt").read_bytes() == b"scored bad\xff.csv\n"
    assert (tmp_path / "s.txt").read_bytes() == b"bad\xff.csv"


def test_storage_errors_give_the_fix_of_the_kind_of_file() -> None:
    from odmd_bench.os_errors import storage_error

    full = OSError(errno.ENOSPC, "No space left on device")
    assert "the data folder: --data-dir" in str(storage_error(full, "/d/odmd-v1/test.h5", "write"))
    report = str(storage_error(full, "/tmp/report.txt", "write"))
    assert report.endswith("free space on that disk, or write to another folder")
    # A data file another process holds open for writing (HDF5's lock) is in use, not damaged.
    busy = OSError(errno.EAGAIN, "Resource temporarily unavailable")
    text = str(storage_error(busy, "/d/odmd-v1/test.h5", "read", "run `odmd-bench generate` to rebuild it"))
    assert "another process has it open for writing" in text and "rebuild" not in text


def _damage(data: dict, how: str) -> None:
    test = data["splits"]["test"] if "splits" in data else None
    if how == "pin without sha256":
        del test["normal"]["sha256"]
    elif how == "split as a list":
        data["splits"]["test"] = []
    elif how == "n as text":
        test["normal"]["n"] = "3000"
    elif how == "unknown kind":
        test["camera"]["kind"] = "magic"
    elif how == "files as a list":
        data["files"] = []


@pytest.mark.parametrize(
    ("name", "how", "problem"),
    [
        ("odmd-v1", "pin without sha256", "test normal: sha256 must be text"),
        ("odmd-v1", "split as a list", "splits['test'] must map each set to its pin"),
        ("odmd-v1", "n as text", "test normal: n must be an integer"),
        ("odmd-v1", "unknown kind", "test camera: kind must be one of generated, import, file"),
        ("odmd-original", "files as a list", "files must map each file of the release to its pin"),
    ],
)
def test_a_damaged_pinned_manifest_is_named_not_a_traceback(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, name: str, how: str, problem: str
) -> None:
    """A damaged installation: every command that reads the manifest says so, exit 2."""
    import json

    from click.testing import CliRunner

    from odmd_bench.cli.main import cli
    from odmd_bench.data import manifests

    splits = tmp_path / "splits"
    shutil.copytree(manifests.splits_dir(), splits)
    data = json.loads((splits / f"{name}.json").read_text())
    _damage(data, how)
    (splits / f"{name}.json").write_text(json.dumps(data))
    monkeypatch.setattr(manifests, "splits_dir", lambda: splits)
    manifests.read_manifest.cache_clear()
    try:
        with pytest.raises(DataError) as info:
            manifests.read_manifest(name)
        assert info.value.message == f"pinned manifest {splits / name}.json is damaged; reinstall odmd-bench"
        assert problem in info.value.problems
        preds = tmp_path / "p.csv"
        preds.write_text("split,set,index,depth\ntest,normal,0,1.0\n")
        (tmp_path / "test_normal.pk").write_bytes(b"not a pickle")
        args = (
            ["import", str(tmp_path / "test_normal.pk")]
            if name == "odmd-original"
            else ["evaluate", str(preds)]
        )
        r = CliRunner().invoke(cli, args)
        assert r.exit_code == 2 and "is damaged; reinstall odmd-bench" in r.output, r.output
    finally:
        manifests.read_manifest.cache_clear()


def test_a_killed_nested_writer_leaves_nothing_that_the_next_writer_keeps(tmp_path: Path) -> None:
    """The plot is written through a temporary file of the board's; both are the target's, however nested."""
    target = tmp_path / "leaderboard.png"
    script = textwrap.dedent(
        """
        import sys, time
        from odmd_bench.outputs import atomic_path
        with atomic_path(sys.argv[1]) as outer, atomic_path(outer) as inner:
            outer.write_bytes(b"x")
            inner.write_bytes(b"half")
            print(outer, inner, sep="\\n", flush=True)
            time.sleep(3600)
        """
    )
    child = subprocess.Popen([sys.executable, "-c", script, str(target)], stdout=subprocess.PIPE, text=True)
    assert child.stdout is not None
    outer, inner = Path(child.stdout.readline().strip()), Path(child.stdout.readline().strip())
    child.send_signal(signal.SIGKILL)
    child.wait()
    child.stdout.close()
    assert outer.exists() and inner.exists() and inner.name.startswith(".leaderboard.png.")
    from odmd_bench.outputs.temps import _host

    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    older = tmp_path / f"..leaderboard.png.{_host()}-{dead.pid}.ab12.tmp.{_host()}-{dead.pid}.cd34.tmp"
    older.write_bytes(b"as 0.1.0 named a nested temporary file")
    with atomic_path(target) as tmp:
        tmp.write_bytes(b"new")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["leaderboard.png"]


def test_temporary_files_elsewhere_are_removed_by_the_next_writer(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A device's output goes through the system's temporary folder, as leaderboard add's staging."""
    import tempfile

    from odmd_bench.outputs.temps import _host, temp_folder

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    left_file = tmp_path / f"odmd-bench.{_host()}-{dead.pid}.ab12.tmp"
    left_file.write_text("x")
    left_folder = tmp_path / f"odmd-bench.{_host()}-{dead.pid}.cd34.tmp"
    (left_folder / "m" / "odmd-v1-test").mkdir(parents=True)
    live = tmp_path / f"odmd-bench.{_host()}-{os.getppid()}.ef56.tmp"
    live.write_text("a live writer's")
    with temp_folder() as mine:
        assert mine.is_dir() and mine.parent == tmp_path
    assert sorted(p.name for p in tmp_path.iterdir()) == [live.name]
