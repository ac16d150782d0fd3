"""Direct tests of the defences a mutation run found guarded only by chance (issue 38, item 8).

Each pins one rule so that a hand-made bug in it fails a test named for it: the safe
unpickler's allow-list exactly, the rank-group chain rule, statistics whose extreme is
the last example, a predictions file with exactly one row missing, the hash checks.
"""

from __future__ import annotations

import io
import pickle
from pathlib import Path

import numpy as np
import pytest

import odmd_bench
from odmd_bench import ImportRefused, ValidationError
from odmd_bench.data import importer
from odmd_bench.data.importer import RestrictedUnpickler, safe_unpickle
from odmd_bench.evaluation.compare import A_BETTER, TIE, compare_errors
from odmd_bench.evaluation.metrics import set_metrics, summarize
from odmd_bench.leaderboard.ranking import rank_groups

# --- the safe unpickler -------------------------------------------------------------------

#: Exactly what an ODMD pickle needs, and nothing more.
ALLOWED = {
    ("numpy.core.multiarray", "_reconstruct"),
    ("numpy._core.multiarray", "_reconstruct"),
    ("numpy", "ndarray"),
    ("numpy", "dtype"),
}


def test_the_allow_list_is_exactly_what_an_odmd_pickle_needs() -> None:
    assert set(importer._ALLOWED) == ALLOWED
    for module, name in ALLOWED:
        got = RestrictedUnpickler(io.BytesIO(b"")).find_class(module, name)
        assert got is {"ndarray": np.ndarray, "dtype": np.dtype}.get(name, got)
        assert callable(got)


def _global(module: str, name: str, protocol: int) -> bytes:
    """A pickle whose only content is the global ``module.name`` (then called with no argument)."""
    if protocol >= 4:  # STACK_GLOBAL: two strings on the stack
        m, n = module.encode(), name.encode()
        body = b"\x8c" + bytes([len(m)]) + m + b"\x8c" + bytes([len(n)]) + n + b"\x93"
    else:  # GLOBAL: "module\nname\n"
        body = b"c" + module.encode() + b"\n" + name.encode() + b"\n"
    return b"\x80" + bytes([protocol]) + body + b")R."


HOSTILE = [
    ("builtins", "getattr"),
    ("builtins", "eval"),
    ("builtins", "exec"),
    ("builtins", "__import__"),
    ("os", "system"),
    ("posix", "system"),
    ("subprocess", "Popen"),
    ("numpy", "load"),
    ("numpy", "frombuffer"),
    ("numpy", "fromfile"),
    ("numpy", "save"),
    ("numpy.core.multiarray", "scalar"),
    ("numpy._core.multiarray", "scalar"),
    ("numpy.lib.npyio", "load"),
    ("numpy.testing", "assert_equal"),
    ("numpy.ndarray", "tofile"),
    ("numpy", "_reconstruct"),  # an allowed name under another module
    ("numpy.core.multiarray", "ndarray"),  # and an allowed module with another name
    ("numpy ", "ndarray"),
    ("Numpy", "ndarray"),
]


@pytest.mark.parametrize("protocol", [2, 4])
@pytest.mark.parametrize(("module", "name"), HOSTILE, ids=[f"{m}.{n}" for m, n in HOSTILE])
def test_a_pickle_naming_any_other_global_is_refused_before_it_runs(
    module: str, name: str, protocol: int
) -> None:
    with pytest.raises(ImportRefused) as info:
        safe_unpickle(_global(module, name, protocol), "evil.pk")
    assert info.value.message == (
        f"evil.pk: the pickle asks for {module}.{name}, which an ODMD file never needs; refused before "
        "anything ran (allowed: numpy arrays and dtypes only)"
    )


def test_persistent_ids_are_refused() -> None:
    evil = b"\x80\x02X\x03\x00\x00\x00abcQ."  # BINPERSID of the string 'abc'
    with pytest.raises(ImportRefused) as info:
        safe_unpickle(evil, "evil.pk")
    assert (
        info.value.message
        == "evil.pk: the pickle uses persistent ids, which an ODMD file never does; refused"
    )
    with pytest.raises(ImportRefused) as info:
        safe_unpickle(_global("os", "system", 4))  # named "<bytes>" when no origin is given
    assert info.value.message.startswith("<bytes>: the pickle asks for os.system,")


def test_arrays_dicts_and_numbers_still_load() -> None:
    obj = {"a": np.arange(6, dtype=np.float64).reshape(2, 3), "b": [1, 2.5, "x"], "c": np.dtype("<i4")}
    for protocol in (3, 4):  # protocol 2 pickles bytes through _codecs.encode: refused, rightly
        back = safe_unpickle(pickle.dumps(obj, protocol=protocol))
        assert back["b"] == [1, 2.5, "x"] and back["c"] == np.dtype("<i4")
        assert np.array_equal(back["a"], obj["a"]) and back["a"].dtype == np.float64


def test_a_broken_pickle_is_refused_naming_it() -> None:
    with pytest.raises(ImportRefused, match=r"^x.pk: not a readable pickle \(EOFError"):
        safe_unpickle(b"\x80\x02}q\x00", "x.pk")  # ends before STOP


# --- rank groups ----------------------------------------------------------------------------


def same_comparison(got: object, want: object) -> bool:
    """The same verdict, test and means; the interval to rounding.

    The ranking draws each method's resamples once per set (``compare.Resampled``):
    the same draws as :func:`compare_errors`, summed in another order.
    """
    g, w = vars(got), vars(want)
    exact = {k: v for k, v in w.items() if k not in ("ci_low", "ci_high", "difference")}
    return all(g[k] == v for k, v in exact.items()) and all(
        np.isclose(g[k], w[k], rtol=1e-12, atol=1e-12) for k in ("ci_low", "ci_high", "difference")
    )


def test_a_group_is_made_by_its_leader_not_by_a_chain() -> None:
    """B ties the leader A and C ties B, but C is worse than A: C leads group 2."""
    rng = np.random.default_rng(48)
    x = rng.gamma(2.0, 5.0, 400)
    a = {"s": x}
    b = {"s": x + 0.25 + rng.normal(0.0, 3.0, 400)}
    c = {"s": x + 0.6 + rng.normal(0.0, 0.5, 400)}
    n = 2000
    assert compare_errors(a, b, n_resamples=n).all.verdict == TIE
    assert compare_errors(b, c, n_resamples=n).all.verdict == TIE
    assert compare_errors(a, c, n_resamples=n).all.verdict == A_BETTER
    ranked = rank_groups({"c": c, "a": a, "b": b}, n_resamples=n)
    assert [(r.key, r.group, r.leader) for r in ranked] == [("a", 1, "a"), ("b", 1, "a"), ("c", 2, "c")]
    assert same_comparison(ranked[1].versus_leader, compare_errors(a, b, n_resamples=n).all)
    assert same_comparison(
        ranked[2].versus_previous, compare_errors(a, c, n_resamples=n).all
    )  # against A, not B
    assert ranked[0].versus_leader is None and ranked[1].versus_previous is None


def test_rank_groups_use_the_settings_they_are_given(monkeypatch: pytest.MonkeyPatch) -> None:
    from odmd_bench.leaderboard import ranking

    assert ranking.resamples(None) == ranking.RANK_RESAMPLES == 2000 and ranking.resamples(77) == 77
    monkeypatch.setattr(ranking, "RANK_RESAMPLES", 123)
    assert ranking.resamples(None) == 123  # read when called, so that tests can patch it
    rng = np.random.default_rng(1)
    a = {"s": rng.gamma(2.0, 5.0, 300)}
    b = {"s": a["s"] + rng.normal(0.0, 2.0, 300)}
    for kw in (
        {"n_resamples": 50, "seed": 3, "confidence": 0.9},
        {"n_resamples": 60, "seed": 4, "confidence": 0.8},
    ):
        (_, second) = rank_groups({"a": a, "b": b}, **kw)  # type: ignore[arg-type]
        first_key = "a" if np.mean(a["s"]) <= np.mean(b["s"]) else "b"
        lead, other = (a, b) if first_key == "a" else (b, a)
        expected = compare_errors(lead, other, **kw).all  # type: ignore[arg-type]
        assert same_comparison(second.versus_leader or second.versus_previous, expected)
    (_, second) = rank_groups({"a": a, "b": b})
    assert same_comparison(
        second.versus_leader or second.versus_previous,
        compare_errors(*((a, b) if np.mean(a["s"]) <= np.mean(b["s"]) else (b, a)), n_resamples=123).all,
    )


def test_all_is_the_float64_mean_of_the_set_means() -> None:
    e = np.random.default_rng(0).gamma(2.0, 5.0, 1001).astype(np.float32)
    assert float(np.mean(e)) != float(np.mean(e.astype(np.float64)))  # float32 means differ
    (row,) = rank_groups({"m": {"s": e, "t": e[:10]}}, n_resamples=50)
    assert (
        row.all_mean == (float(np.mean(e.astype(np.float64))) + float(np.mean(e[:10].astype(np.float64)))) / 2
    )


def test_rows_are_sorted_by_all_then_by_key() -> None:
    e = np.linspace(1.0, 2.0, 50)
    ranked = rank_groups({"zz": {"s": e}, "aa": {"s": e}, "mm": {"s": e - 0.5}}, n_resamples=200)
    assert [r.key for r in ranked] == ["mm", "aa", "zz"]
    assert [r.all_mean for r in ranked] == [pytest.approx(1.0), pytest.approx(1.5), pytest.approx(1.5)]


# --- statistics -----------------------------------------------------------------------------


def test_statistics_see_the_last_example() -> None:
    e = np.array([3.0, 1.0, 2.0, 9.0])  # the maximum is last
    assert summarize(e) == {"mean": 3.75, "median": 2.5, "min": 1.0, "max": 9.0, "std": float(np.std(e))}
    assert summarize(e[::-1] * -1 + 10)["min"] == 1.0  # the minimum last: [1, 8, 9, 7] reversed
    truth = np.array([1.0, 2.0, 4.0, 5.0])
    pred = np.array([1.0, 2.0, 4.0, 10.0])  # only the last is wrong
    m = set_metrics(truth, pred)
    assert m["n"] == 4
    assert m["percent_error"]["max"] == 100.0 and m["absolute_error"]["max"] == 5.0
    assert m["percent_error"]["mean"] == 25.0 and m["absolute_error"]["mean"] == 1.25


# --- predictions checks ---------------------------------------------------------------------


@pytest.fixture()
def data(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    from odmd_bench.data.io import write_sets
    from odmd_bench.data.registry import get_benchmark, set_file

    d = tmp_path / "data"
    sets = {s: odmd_bench.generate(4, rng=i) for i, s in enumerate(("normal", "camera", "object", "robot"))}
    write_sets(set_file(get_benchmark("odmd-paper"), "test", d), sets)
    monkeypatch.setenv("ODMD_BENCH_DATA", str(d))
    return d


@pytest.mark.parametrize("missing", ["test,normal,0,", "test,robot,3,"])
def test_a_file_with_exactly_one_row_missing_is_refused(data: Path, tmp_path: Path, missing: str) -> None:
    p = tmp_path / "p.csv"
    odmd_bench.write_predictions(
        p, "test", {s: ex.depth for s, ex in odmd_bench.load_split("test", "odmd-paper").items()}
    )
    lines = p.read_text().splitlines(keepends=True)
    assert odmd_bench.evaluate(p, benchmark="odmd-paper").all_percent_error_mean == 0.0
    p.write_text("".join(ln for ln in lines if not ln.startswith(missing)))
    with pytest.raises(ValidationError) as info:
        odmd_bench.evaluate(p, benchmark="odmd-paper")
    set_name, index = missing.split(",")[1:3]
    assert info.value.problems == [
        f"1 of the 4 examples of set {set_name!r} have no row (missing indices {index})"
    ]


# --- hash checks ----------------------------------------------------------------------------


def test_every_array_and_attribute_is_in_a_hash(tmp_path: Path) -> None:
    """A change to any array byte, dtype, shape or name, or to any attribute, changes a hash."""
    from odmd_bench.data.hashing import content_sha256, meta_sha256

    arrays = {"boxes": np.arange(8.0).reshape(2, 4), "depth": np.array([1.0, 2.0])}
    base = content_sha256(arrays)
    assert base == content_sha256({k: arrays[k] for k in ("depth", "boxes")})  # order-free
    big = {k: v.astype(v.dtype.newbyteorder(">")) for k, v in arrays.items()}
    assert content_sha256(big) == base  # byte order is not content
    changed = [
        {**arrays, "depth": np.array([1.0, 2.0000000000000004])},
        {**arrays, "depth": np.array([2.0, 1.0])},
        {**arrays, "depth": np.array([1.0, 2.0], dtype=np.float32)},
        {**arrays, "boxes": arrays["boxes"].reshape(4, 2)},
        {"boxez": arrays["boxes"], "depth": arrays["depth"]},
        {**arrays, "extra": np.zeros(0)},
        {"boxes": arrays["boxes"]},
    ]
    digests = [content_sha256(c) for c in changed]
    assert base not in digests and len(set(digests)) == len(digests)
    attrs = {"fx": 205.5, "benchmark": "odmd-v1", "set": "robot"}
    metas = [
        meta_sha256(attrs),
        meta_sha256({**attrs, "fx": 205.50000000000003}),
        meta_sha256({**attrs, "set": "camera"}),
    ]
    metas.append(meta_sha256({k: v for k, v in attrs.items() if k != "fx"}))
    assert len(set(metas)) == 4
    assert (
        meta_sha256({**attrs, "content_sha256": "x", "meta_sha256": "y"}) == metas[0]
    )  # the hashes themselves are not


def test_a_set_whose_array_or_attribute_changed_is_refused_on_load(tmp_path: Path) -> None:
    import h5py

    from odmd_bench.data.io import read_set, write_sets

    f = tmp_path / "x.h5"
    write_sets(f, {"normal": odmd_bench.generate(3, rng=0)})
    read_set(f, "normal")  # verifies
    with h5py.File(f, "r+") as h:
        h["normal/depth"][-1] += 1e-9  # the last value, changed in its last bits
    with pytest.raises(odmd_bench.DataError, match="is corrupt or altered: its arrays hash to"):
        read_set(f, "normal")
    write_sets(f, {"normal": odmd_bench.generate(3, rng=0)})
    with h5py.File(f, "r+") as h:
        h["normal"].attrs["image_width"] = h["normal"].attrs["image_width"] + 1
    with pytest.raises(odmd_bench.DataError, match="is altered: its attributes"):
        read_set(f, "normal")


def test_a_set_that_is_not_its_pinned_version_is_named() -> None:
    from odmd_bench.data.manifests import check_against_manifest, pin
    from odmd_bench.data.registry import get_benchmark

    right = pin(get_benchmark("odmd-v1"), "test", "robot")["sha256"]
    assert check_against_manifest(get_benchmark("odmd-v1"), "test", "robot", right) is None
    wrong = ("0" if right[0] != "0" else "1") + right[1:]
    said = check_against_manifest(get_benchmark("odmd-v1"), "test", "robot", wrong)
    assert said == (
        f"odmd-v1 test robot: content SHA-256 {wrong[:16]}... differs from the pinned {right[:16]}... "
        "in splits/odmd-v1.json"
    )
    last = right[:-1] + ("0" if right[-1] != "0" else "1")  # the last digit too
    assert check_against_manifest(get_benchmark("odmd-v1"), "test", "robot", last) is not None


def test_the_arrays_and_attributes_a_set_is_hashed_by() -> None:
    from odmd_bench.data.hashing import (
        CORE_ARRAYS,
        HASH_ATTRS,
        attr_value,
        content_sha256,
        group_attrs,
        meta_sha256,
        plain_value,
        set_arrays,
    )

    ex = odmd_bench.generate(3, perturbation="both", rng=0)
    arrays = set_arrays(ex)
    assert CORE_ARRAYS == ("boxes", "detected", "camera", "depth") and HASH_ATTRS == (
        "content_sha256",
        "meta_sha256",
    )
    assert set(arrays) == {*CORE_ARRAYS, "observation_depth", *ex.extras}
    assert all(arrays[k] is getattr(ex, k) for k in (*CORE_ARRAYS, "observation_depth"))
    clash = odmd_bench.Examples(ex.boxes, ex.detected, ex.camera, ex.depth, extras={"depth": ex.depth})
    with pytest.raises(odmd_bench.DataError, match="^extra array 'depth' clashes with a core array$"):
        set_arrays(clash)
    assert attr_value({"b": 1, "a": [2, 3]}) == '{"a": [2, 3], "b": 1}'
    assert attr_value([1, "x"]) == '[1, "x"]' and attr_value((1,)) == "[1]" and attr_value(2.5) == 2.5
    assert plain_value(b"odmd") == "odmd" and plain_value(np.array([1, 2])) == [1, 2]
    assert plain_value(np.float32(0.5)) == 0.5 and type(plain_value(np.int64(3))) is int
    assert plain_value("x") == "x"
    ex.attrs.update(content_sha256="stale", meta_sha256="stale", gone=None, nested={"k": [1]})
    attrs = group_attrs(ex, "robot")
    assert attrs["content_sha256"] == content_sha256(arrays)
    assert attrs["meta_sha256"] == meta_sha256(attrs) != "stale"
    assert (attrs["set"], attrs["n"], attrs["n_obs"], attrs["nested"]) == ("robot", 3, ex.n_obs, '{"k": [1]}')
    assert "gone" not in attrs
    assert group_attrs(ex, "robot", digest="d" * 64)["content_sha256"] == "d" * 64


def test_file_sha256_hashes_every_byte(tmp_path: Path) -> None:
    import hashlib

    from odmd_bench.data.hashing import file_sha256

    f = tmp_path / "f.bin"
    data = np.random.default_rng(0).bytes(5 * 2**20 // 2 + 7)  # more than two chunks of 1 MiB
    f.write_bytes(data)
    assert file_sha256(f) == hashlib.sha256(data).hexdigest()
    f.write_bytes(b"")
    assert file_sha256(str(f)) == hashlib.sha256(b"").hexdigest()


def test_metrics_are_float64_and_name_every_problem() -> None:
    from odmd_bench import UsageError
    from odmd_bench.evaluation.metrics import all_sets_mean, check_depths

    t32 = np.random.default_rng(0).gamma(2.0, 5.0, 1001).astype(np.float32) + np.float32(1)
    p32 = (t32 * np.float32(1.1)).astype(np.float32)
    t, p = check_depths(t32, p32)
    assert t.dtype == p.dtype == np.float64
    e = np.abs(p32.astype(np.float64) - t32.astype(np.float64))
    assert summarize(e.astype(np.float32))["mean"] == float(np.mean(e.astype(np.float32).astype(np.float64)))
    assert summarize(e.astype(np.float32))["mean"] != float(
        np.mean(e.astype(np.float32))
    )  # float32 would differ
    means = {str(i): np.float32(v) for i, v in enumerate(e)}
    e32 = e.astype(np.float32)
    assert all_sets_mean(means) == float(np.mean(e32.astype(np.float64))) != float(np.mean(e32))
    with pytest.raises(UsageError) as info:
        check_depths(np.ones((2, 2)), np.ones(4))
    assert info.value.message == "cannot compute depth errors"
    assert info.value.problems == ["depths must be 1-D, got shapes (2, 2) and (4,)"]
    with pytest.raises(UsageError) as info:
        check_depths(np.ones(4), np.ones((4, 1)))
    assert info.value.problems == ["depths must be 1-D, got shapes (4,) and (4, 1)"]
    with pytest.raises(UsageError) as info:
        check_depths([1.0, 0.0], [np.nan, 1.0])
    assert info.value.problems == ["true depths must be finite and > 0", "estimated depths must be finite"]
    with pytest.raises(UsageError) as info:
        summarize(np.zeros((0,)))
    assert info.value.message == "errors must be a non-empty 1-D array, got shape (0,)"
    with pytest.raises(UsageError) as info:
        all_sets_mean({})
    assert info.value.message == "All needs at least one set"


def test_file_sha256_reads_in_bounded_chunks(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A weights or original file is hashed 1 MiB at a time, never read whole into memory."""
    import builtins

    from odmd_bench.data import hashing

    sizes: list[object] = []

    class Recording(io.BufferedReader):
        def read(self, size: int | None = -1, /) -> bytes:
            sizes.append(size)
            return super().read(size)

    def recording_open(path: object, mode: str = "r", *args: object, **kw: object) -> object:
        raw = builtins.open(path, mode, *args, buffering=0, **kw)  # type: ignore[call-overload]  # noqa: SIM115
        return Recording(raw)

    monkeypatch.setattr(hashing, "open", recording_open, raising=False)
    f = tmp_path / "f.bin"
    f.write_bytes(b"x" * (3 * 2**20 + 5))
    import hashlib

    assert hashing.file_sha256(f) == hashlib.sha256(f.read_bytes()).hexdigest()
    assert sizes and all(s == 2**20 for s in sizes), sizes


def test_a_set_is_its_pinned_version_or_named() -> None:
    from odmd_bench.data.manifests import is_pinned, known_originals, pin, pin_problem
    from odmd_bench.data.registry import get_benchmark

    v1 = pin(get_benchmark("odmd-v1"), "test", "robot")
    good = {"content_sha256": v1["sha256"], "meta_sha256": v1["meta_sha256"]}
    assert (
        is_pinned(get_benchmark("odmd-v1"), {})
        and pin_problem(get_benchmark("odmd-v1"), "test", "robot", dict(good)) is None
    )
    content = {**good, "content_sha256": "f" * 64}
    assert pin_problem(get_benchmark("odmd-v1"), "test", "robot", content) == (
        f"odmd-v1 test robot: content SHA-256 ffffffffffffffff... differs from the pinned {v1['sha256'][:16]}... "
        "in splits/odmd-v1.json"
    )
    meta = {**good, "meta_sha256": "e" * 64}
    assert pin_problem(get_benchmark("odmd-v1"), "test", "robot", meta) == (
        f"odmd-v1 test robot: metadata SHA-256 eeeeeeeeeeeeeeee... differs from the pinned "
        f"{v1['meta_sha256'][:16]}... in splits/odmd-v1.json"
    )
    paper = pin(get_benchmark("odmd-paper"), "test", "camera")
    mine = {"content_sha256": paper["sha256"], "meta_sha256": paper["meta_sha256"]}
    assert not is_pinned(
        get_benchmark("odmd-paper"), mine
    )  # no source: imported with --allow-unknown, or written
    assert (
        pin_problem(get_benchmark("odmd-paper"), "test", "camera", {**mine, "content_sha256": "0" * 64})
        is None
    )
    assert not is_pinned(
        get_benchmark("odmd-paper"), {**mine, "source_sha256": "0" * 64}
    )  # an unknown source
    known = {**mine, "source_sha256": paper["source_sha256"]}
    assert (
        is_pinned(get_benchmark("odmd-paper"), known)
        and pin_problem(get_benchmark("odmd-paper"), "test", "camera", known) is None
    )
    other = pin(get_benchmark("odmd-paper"), "test", "robot")[
        "source_sha256"
    ]  # a known original, another set's
    assert pin_problem(get_benchmark("odmd-paper"), "test", "camera", {**known, "source_sha256": other}) == (
        f"odmd-paper test camera: the set is the conversion of {known_originals()[other]['path']}, not of "
        "the file pinned for it in splits/odmd-paper.json"
    )
    assert pin_problem(
        get_benchmark("odmd-paper"), "test", "camera", {**known, "meta_sha256": "1" * 64}
    ).startswith(  # type: ignore[union-attr]
        "odmd-paper test camera: metadata SHA-256 1111111111111111... differs"
    )


def test_the_hashes_of_a_committed_set_are_its_pins() -> None:
    """The hash formats themselves, checked against the manifest: a change of format fails."""
    import h5py

    from odmd_bench.data.hashing import content_sha256, meta_sha256
    from odmd_bench.data.manifests import pin
    from odmd_bench.data.registry import get_benchmark

    root = Path(__file__).resolve().parents[1]
    with h5py.File(root / "splits" / "odmd-v1" / "robot-test.h5", "r") as h:
        g = h["robot"]
        arrays = {k: g[k][()] for k in g}
        attrs = dict(g.attrs)
    pinned = pin(get_benchmark("odmd-v1"), "test", "robot")
    assert content_sha256(arrays) == pinned["sha256"] == attrs["content_sha256"]
    assert meta_sha256(attrs) == pinned["meta_sha256"] == attrs["meta_sha256"]


def test_meta_sha256_is_canonical_json() -> None:
    import hashlib

    from odmd_bench.data.hashing import meta_sha256

    attrs = {"b": 1, "a": "é", "c": [1.5, True]}
    text = '{"a":"\\u00e9","b":1,"c":[1.5,true]}'
    assert meta_sha256(attrs) == hashlib.sha256(text.encode()).hexdigest()
    assert meta_sha256(dict(reversed(attrs.items()))) == meta_sha256(attrs)
    odd = {"k": complex(1, 2)}  # not JSON: written as its repr
    assert meta_sha256(odd) == hashlib.sha256(b'{"k":"(1+2j)"}').hexdigest()


def test_a_verified_read_names_both_hashes_and_the_format_version(tmp_path: Path) -> None:
    import re

    import h5py

    from odmd_bench.data.hashing import content_sha256, meta_sha256
    from odmd_bench.data.io import FORMAT_VERSION, read_set, write_sets

    f = tmp_path / "x.h5"
    write_sets(f, {"normal": odmd_bench.generate(3, rng=0)})
    with h5py.File(f, "r+") as h:
        h["normal/depth"][-1] += 1e-9
        stored = h["normal"].attrs["content_sha256"]
        actual = content_sha256({k: h["normal"][k][()] for k in h["normal"]})
    with pytest.raises(odmd_bench.DataError) as info:
        read_set(f, "normal")
    said = re.search(r"(is corrupt.*?\.\.\.), the file records (\w+)\.\.\.; ", info.value.message)
    assert said is not None, info.value.message
    assert said.group(1) == f"is corrupt or altered: its arrays hash to {actual[:16]}..."
    assert said.group(2) == stored[:16]
    write_sets(f, {"normal": odmd_bench.generate(3, rng=0)})
    with h5py.File(f, "r+") as h:
        h["normal"].attrs["image_width"] = 641
        attrs = dict(h["normal"].attrs)
    with pytest.raises(odmd_bench.DataError) as info:
        read_set(f, "normal")
    assert (
        f"is altered: its attributes (intrinsics, image size, identity...) hash to {meta_sha256(attrs)[:16]}..., "
        f"the file records {attrs['meta_sha256'][:16]}...; "
    ) in info.value.message
    with h5py.File(f, "r+") as h:
        h.attrs["format_version"] = FORMAT_VERSION + 1
    with pytest.raises(odmd_bench.DataError) as info:
        read_set(f, "normal")
    assert (
        f"has file format version {FORMAT_VERSION + 1}, this odmd-bench reads version {FORMAT_VERSION} "
        "(it is stale); "
    ) in info.value.message
