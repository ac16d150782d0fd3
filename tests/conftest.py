"""Shared fixtures.

Tests that need the original release (``../shared/odmd-original``) skip when it is
missing on a developer's machine, and fail loudly when ``CI`` is set: CI has the files,
so their absence there is a broken set-up, never a reason to pass.

The data folders every test file reads (the imported release, the generated odmd-v1 sets)
are made once per run, not once per process: the first pytest-xdist worker that needs one
makes it under a lock, in a folder all the run's processes share (:func:`made_once`), and
the others read it; a pytest run that a test starts (tests/test_contributing.py) finds the
same folder through ``$ODMD_TEST_SHARED``. They are read-only to the tests: a test that
changes data copies it first.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
from filelock import FileLock

ORIGINAL = Path(__file__).resolve().parents[2] / "shared" / "odmd-original"
KITTI = Path(__file__).resolve().parents[2] / "shared" / "kitti-tracking"


def shared_dir(default: Path, variable: str, marker: str, what: str) -> Path:
    """A folder of ``../shared`` (or ``$variable``) holding ``marker``, or skip (outside CI) / fail (in CI)."""
    override = os.environ.get(variable)
    path = Path(override) if override else default
    if not (path / marker).is_dir():
        message = f"{what} not at {path} (set {variable})"
        if os.environ.get("CI"):
            pytest.fail(message + "; CI must have it", pytrace=False)
        pytest.skip(message)
    return path


def original_dir() -> Path:
    """The original release's folder, or skip (outside CI) / fail (in CI)."""
    return shared_dir(ORIGINAL, "ODMD_ORIGINAL", "odmd", "the original ODMD release is")


def kitti_dir() -> Path:
    """The raw KITTI tracking files, or skip (outside CI) / fail (in CI)."""
    return shared_dir(KITTI, "ODMD_KITTI_TRACKING", "label_02", "the KITTI tracking files are")


#: Where a run's processes find the folders made once for the run (set by the first
#: process that needs it; a child process, a pytest run a test starts among them, inherits it).
SHARED_VARIABLE = "ODMD_TEST_SHARED"


def run_folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The folder all the processes of this test run share: the xdist workers' common parent."""
    inherited = os.environ.get(SHARED_VARIABLE)
    if inherited:
        return Path(inherited)
    base = tmp_path_factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):  # each worker's basetemp is <the run's>/popen-gwN
        base = base.parent
    folder = base / "made-once"
    folder.mkdir(exist_ok=True)
    os.environ[SHARED_VARIABLE] = str(folder)
    return folder


def made_once(tmp_path_factory: pytest.TempPathFactory, name: str, make: Callable[[Path], None]) -> Path:
    """The folder ``name`` of this run, filled by ``make(folder)`` once for all its processes.

    The first process to ask makes it under a lock; the others wait, then read it. A
    ``make`` that failed leaves no folder marked done: the next one to ask makes it again
    (and fails the same way, in its own test).
    """
    root = run_folder(tmp_path_factory)
    folder, done = root / name, root / f"{name}.done"
    with FileLock(root / f"{name}.lock"):
        if not done.exists():
            shutil.rmtree(folder, ignore_errors=True)
            folder.mkdir()
            make(folder)
            done.touch()
    return folder


@pytest.fixture(scope="session", autouse=True)
def _shared_with_child_runs(tmp_path_factory: pytest.TempPathFactory) -> None:
    """Set ``$ODMD_TEST_SHARED`` from the start, so a pytest run a test starts shares the folders."""
    run_folder(tmp_path_factory)


@pytest.fixture(scope="session")
def original_release() -> Path:
    return original_dir()


@pytest.fixture(scope="session")
def paper_data_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A data folder holding the imported ``odmd-paper`` and ``odms-detection`` benchmarks."""
    from odmd_bench.data.importer import import_release

    src = original_dir()
    return made_once(tmp_path_factory, "paper-data", lambda data: import_release(src, data))


@pytest.fixture(scope="session")
def v1_data_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A data folder holding the generated ``odmd-v1`` val and test files."""
    from odmd_bench.data.store import ensure_generated

    return made_once(
        tmp_path_factory, "v1-data", lambda data: ensure_generated("odmd-v1", ("val", "test"), data)
    )


@pytest.fixture(autouse=True)
def _isolated_data_dir(tmp_path_factory: pytest.TempPathFactory, monkeypatch: pytest.MonkeyPatch) -> None:
    """Never let a test read or write the user's real data folder by accident."""
    if "ODMD_BENCH_DATA" not in os.environ:
        monkeypatch.setenv("ODMD_BENCH_DATA", str(tmp_path_factory.getbasetemp() / "default-data"))


def _baseline_dbox_scores(
    data_dir: Path, out: Path, benchmark: str, split: str, *weights: str
) -> dict[str, float]:
    """``baseline dbox`` + ``evaluate --format json``, as a user runs them: mean % error per set and All."""
    from click.testing import CliRunner

    from odmd_bench.cli.main import cli

    preds = out / "dbox.csv"
    common = ["--benchmark", benchmark, "--data-dir", str(data_dir)]
    run = CliRunner().invoke(cli, ["baseline", "dbox", "--split", split, "-o", str(preds), *weights, *common])
    assert run.exit_code == 0, run.output
    scored = CliRunner().invoke(cli, ["evaluate", str(preds), "--format", "json", *common])
    assert scored.exit_code == 0, scored.output
    result = json.loads(scored.stdout)
    means = {k: v["percent_error"]["mean"] for k, v in result["sets"].items()}
    return {**means, "all": result["all"]["percent_error_mean"]}


DboxScores = Callable[..., dict[str, float]]


@pytest.fixture(scope="session")
def dbox_scores(tmp_path_factory: pytest.TempPathFactory) -> DboxScores:
    """``dbox_scores(data_dir, out, benchmark, split, *weights)``: ``baseline dbox`` + ``evaluate``.

    The network's depths are those of the run (:func:`dbox_depths_shared`): the tests that
    use this compare shipped or released weights with the numbers recorded for them.
    """

    def scores(*args: Any) -> dict[str, float]:
        with dbox_depths_shared(tmp_path_factory):
            return _baseline_dbox_scores(*args)

    return scores


@contextlib.contextmanager
def dbox_depths_shared(tmp_path_factory: pytest.TempPathFactory) -> Iterator[None]:
    """While it is open, DBox's depths for one network and one input are computed once per run.

    The tests that re-run the committed entries' commands (tests/test_leaderboard_commands.py)
    and those that check the numbers recorded for shipped or released weights run the same
    networks on the same sets (odmd-paper and odmd-v1 share theirs; a per-set selection runs
    the overall weights on some sets): ``predict_depth`` is a function of the network's
    parameters, its inputs (``make_inputs``), the device, the chunk, the thread count, the
    kernel setting and the torch version, so its depths are kept under the SHA-256 of all
    of them (``content_sha256``, as the sets' files are), in a folder of the run's
    (:func:`made_once`), and a call met again gets them from there, bit for bit (``.npy``). The first call with each content runs the package's
    code. Only for tests that compare one computation with a recorded number: a test that
    compares two ways of computing the same depths, or changes a kernel, never opens it.
    Without torch it does nothing (the tests that need DBox skip).
    """
    import importlib.util

    if importlib.util.find_spec("torch") is None:
        yield
        return
    import numpy as np
    import torch
    from odmd_bench_baselines.dbox import formulations

    from odmd_bench.data.hashing import content_sha256

    real = formulations.predict_depth
    if getattr(real, "shared_by_the_run", False):  # opened already (a test of a fixture that opens it)
        yield
        return

    def shared(model: Any, examples: Any, formulation: str, device: Any, chunk: int = 4096) -> Any:
        inputs = formulations.make_inputs(examples, formulation)  # refuses what the real call refuses
        call = (type(model).__qualname__, formulation, str(torch.device(device)), chunk)
        call += (torch.get_num_threads(), os.environ.get("ODMD_BENCH_ONEDNN"), torch.__version__)
        arrays = {f"parameter {n}": t.detach().cpu().numpy() for n, t in model.state_dict().items()}
        arrays.update(
            {"input x": inputs.x, "input scale": np.asarray(inputs.scale), "call": np.array(repr(call))}
        )

        def compute(folder: Path) -> None:
            np.save(folder / "depths.npy", real(model, examples, formulation, device, chunk))

        made = made_once(tmp_path_factory, f"dbox-depths-{content_sha256(arrays)}", compute)
        return np.load(made / "depths.npy")

    shared.shared_by_the_run = True  # type: ignore[attr-defined]
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(formulations, "predict_depth", shared)
        yield


@pytest.fixture
def dbox_depths_made_once(tmp_path_factory: pytest.TempPathFactory) -> Iterator[None]:
    """:func:`dbox_depths_shared` for the length of a test."""
    with dbox_depths_shared(tmp_path_factory):
        yield


def recorded_plot(root: Path) -> None:
    """A leaderboard.png that records the current leaderboard.json (what check reads; no pixels).

    Drawing the real plot is slow; ``leaderboard check`` reads only the JSON's SHA-256 the
    PNG records, and requires the file.
    """
    import struct
    import zlib

    from odmd_bench import leaderboard as lb

    digest = lb.board_digest((root / lb.JSON_FILE).read_text(encoding="utf-8"))
    text = lb.PLOT_SOURCE_KEY.encode("latin-1") + b"\0" + digest.encode()

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    (root / lb.PLOT).write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"tEXt", text) + chunk(b"IEND", b""))


def add_entry(root: Path, data_dir: Path, preds: Path, method: str, **over: Any) -> Any:
    """``leaderboard.add_entry`` of ``preds`` as an odmd-v1 test entry ``method`` with test metadata.

    Any field (or option of ``add_entry``) may be given in ``over``.
    """
    from odmd_bench import leaderboard as lb

    kwargs: dict[str, Any] = {
        "method": method,
        "name": method.upper(),
        "description": "a test entry",
        "paper": "none",
        "code": "https://example.org/code",
        "training_data": "none",
        "training_kind": "none",
        "selected_on": "nothing",
        "uses_test_labels": False,
        "command": f"odmd-bench baseline {method}",
        "benchmark": "odmd-v1",
        "split": "test",
        "calibrated": False,
        "date": "2026-01-02",
        "data_dir": data_dir,
    }
    kwargs.update(over)
    return lb.add_entry(root, preds, **kwargs)


def boards_data(folder: Path, paper_data_dir: Path, v1_data_dir: Path) -> Path:
    """``folder`` (made if missing) as the data folder of every board's benchmarks.

    Links to the shared imported (``odmd-paper``, ``odms-detection``) and generated
    (``odmd-v1``) ones.
    """
    folder.mkdir(exist_ok=True)
    for bench, source in (
        ("odmd-paper", paper_data_dir),
        ("odms-detection", paper_data_dir),
        ("odmd-v1", v1_data_dir),
    ):
        (folder / bench).symlink_to(source / bench)
    return folder


def two_entry_board(tmp: Path, data_dir: Path, **expansion_fields: Any) -> Path:
    """``tmp/leaderboard`` with the odmd-v1 test entries of Box_LS and expansion (:func:`add_entry`).

    ``expansion_fields`` go to the expansion entry's :func:`add_entry`.
    """
    from odmd_bench_baselines import box_ls, expansion

    from odmd_bench import leaderboard as lb
    from odmd_bench import load_split
    from odmd_bench.evaluation.predictions import write_predictions

    root = tmp / "leaderboard"
    (root / lb.ENTRIES).mkdir(parents=True)
    sets = load_split("test", "odmd-v1", data_dir)
    for method, module in (("box-ls", box_ls), ("expansion", expansion)):
        preds = tmp / f"{method}.csv"
        write_predictions(
            preds, "test", {s: module.predict(ex) for s, ex in sets.items()}, benchmark="odmd-v1"
        )
        add_entry(root, data_dir, preds, method, **(expansion_fields if method == "expansion" else {}))
    return root


def content_memo(function: Callable[..., Any], keyed: Callable[..., Any] | None = None) -> Callable[..., Any]:
    """``function`` (pure: its result depends on its arguments only) computed once per distinct input.

    Work that several tests repeat on the same data, made once. The key is the content of
    every argument (bytes and text; numbers; a numpy array's bytes, dtype and shape; a
    random generator's state; a mapping's, sequence's or dataclass's items in order), never
    a name: a call with any other argument (a path, a file object) is made as it is, never
    kept. Each caller gets its own deep copy of the result, and a random generator it passed
    is left in the state the call left it in. A call that raises is not kept.

    ``keyed``, given the call's arguments, returns what the key is made of, where an
    argument does not change the result (a cache of draws that gives the numbers it was
    given): by default, all of them.
    """
    import copy
    import dataclasses
    import hashlib

    import numpy as np

    made: dict[str, tuple[Any, list[Any]]] = {}

    class NotContent(Exception):
        """An argument that is not its content (a path names a file; it does not hold it)."""

    def key(value: Any) -> bytes:
        if isinstance(value, np.ndarray):
            data = f"array {value.dtype.str}{value.shape}".encode() + np.ascontiguousarray(value).tobytes()
        elif isinstance(value, np.random.Generator):
            data = f"generator {value.bit_generator.state!r}".encode()
        elif isinstance(value, (bytes, bytearray)):
            data = b"bytes " + bytes(value)
        elif value is None or isinstance(value, (str, int, float, np.integer, np.floating)):
            data = f"{type(value).__qualname__} {value!r}".encode()
        elif isinstance(value, dict):
            data = b"dict" + b"".join(key(k) + key(v) for k, v in value.items())
        elif isinstance(value, (list, tuple)):
            data = type(value).__name__.encode() + b"".join(key(v) for v in value)
        elif dataclasses.is_dataclass(value) and not isinstance(value, type):
            fields = [(f.name, getattr(value, f.name)) for f in dataclasses.fields(value)]
            data = type(value).__qualname__.encode() + key(fields)
        else:
            raise NotContent
        return len(data).to_bytes(8, "little") + data

    def once(*args: Any, **kwargs: Any) -> Any:
        try:
            content = keyed(*args, **kwargs) if keyed is not None else (list(args), kwargs)
            k = hashlib.sha256(key(content)).hexdigest()
        except NotContent:
            return function(*args, **kwargs)
        generators = [a for a in [*args, *kwargs.values()] if isinstance(a, np.random.Generator)]
        if k not in made:
            result = function(*args, **kwargs)
            made[k] = (copy.deepcopy(result), [g.bit_generator.state for g in generators])
        result, states = made[k]
        for g, state in zip(generators, states, strict=True):
            g.bit_generator.state = state
        return copy.deepcopy(result)

    return once


def memo_each(patch: pytest.MonkeyPatch, *targets: tuple[Any, str]) -> None:
    """Replace each ``(module, name)`` function by its :func:`content_memo` (undone with ``patch``)."""
    for module, name in targets:
        patch.setattr(module, name, content_memo(getattr(module, name)))


@pytest.fixture(scope="module")
def entries_read_once() -> Iterator[None]:
    """Predictions files and entry metadata parsed once per distinct content in a module (:func:`content_memo`).

    The boards a module builds and checks again and again hold the same files (the
    committed board's 44 entries in each ``check`` of it): their bytes are parsed once.
    """
    from odmd_bench.evaluation import parse
    from odmd_bench.leaderboard import files

    with pytest.MonkeyPatch.context() as patch:
        memo_each(patch, (parse, "parse_predictions"), (files, "load_document"))
        yield


@pytest.fixture(scope="module")
def boards_ranked_once(entries_read_once: None) -> Iterator[None]:
    """:func:`entries_read_once`, and the rank groups' resampled means made once per distinct errors.

    ``paired_means`` is a pure function of the errors, the resamples, the seed and the set;
    the draws it is given (:class:`~odmd_bench.evaluation.resampling.SharedDraws`) hold the
    numbers it would draw (bit for bit), so they are no part of the key.
    """
    from odmd_bench.evaluation import compare

    def content(e: Any, n_resamples: Any, seed: Any, name: Any, draws: Any = None) -> Any:
        return (e, n_resamples, seed, name)

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(compare, "paired_means", content_memo(compare.paired_means, content))
        yield


@pytest.fixture(scope="module")
def croissant_set_files_made_once(tmp_path_factory: pytest.TempPathFactory) -> Iterator[None]:
    """While a module runs, :func:`~odmd_bench.data.croissant.croissant` makes each set's JSON file once per run.

    The JSON file of a set (0.2 to 0.6 s each, about 2.5 s for odmd-v1's eight) is a function
    of its arrays alone, so the bytes are kept under the SHA-256 of those arrays
    (``content_sha256``, computed here from the arrays, never read from an attribute), each in
    a folder of its own made once for the run (:func:`made_once`); a set met again (odmd-v1
    described by the CLI, by a site build, by the other benchmark that holds the same robot
    set) gets the bytes made the first time. ``set_file_bytes`` itself is tested directly
    (tests/test_croissant.py), never through this. What it refuses (an infinite value) is
    refused each time, never kept.
    """
    from odmd_bench.data.croissant import description
    from odmd_bench.data.hashing import content_sha256, set_arrays

    make = description.set_file_bytes

    def set_file_once(examples: Any) -> bytes:
        def write(folder: Path) -> None:
            (folder / "set.json").write_bytes(make(examples))

        key = content_sha256(set_arrays(examples))
        return (made_once(tmp_path_factory, f"croissant-set-{key}", write) / "set.json").read_bytes()

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(description, "set_file_bytes", set_file_once)
        yield
