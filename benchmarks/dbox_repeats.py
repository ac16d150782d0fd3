r"""How much of the test suite's DBox inference repeats a call already made: a pytest plug-in.

    OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 PYTHONPATH=benchmarks \
        pytest -p dbox_repeats -p no:cacheprovider -n 2 --dist loadfile -q

Every call of ``predict_depth`` in every worker is logged (the test, the SHA-256 of the
network's parameters and of its inputs, the formulation, the chunk, its CPU time) under
``$DBOX_REPEATS_DIR`` (default: a new temporary folder). At the end the run prints the CPU
time of all calls and of the repeats (every call of a content beyond its cheapest one), in
all and among the tests that use ``dbox_depths_made_once`` or ``dbox_scores``
(tests/conftest.py). Where that sharing is open, a repeat is read from the run's folder and
never reaches this log: run it on a checkout from before the sharing (``b2772d3``, with
``PYTHONPATH`` naming this folder) to see what the sharing saves, on this one to see what
is left.
"""

from __future__ import annotations

import json
import os
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

_FOLDER = Path(os.environ.get("DBOX_REPEATS_DIR") or tempfile.mkdtemp(prefix="dbox-repeats-"))
os.environ["DBOX_REPEATS_DIR"] = str(_FOLDER)  # the workers write where the controller reads
_calls: list[tuple[str, str, bool, float]] = []
_test: list[Any] = [None]


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item: pytest.Item, nextitem: pytest.Item | None) -> Any:
    _test[0] = item
    yield
    _test[0] = None


def _shares(item: Any) -> bool:
    names = getattr(item, "fixturenames", ())
    return "dbox_depths_made_once" in names or "dbox_scores" in names


def pytest_configure(config: pytest.Config) -> None:
    try:
        from odmd_bench_baselines.dbox import formulations
    except ImportError:  # no torch: nothing to log
        return
    from odmd_bench.data.hashing import content_sha256

    real = formulations.predict_depth

    def logged(model: Any, examples: Any, formulation: str, device: Any, chunk: int = 4096) -> Any:
        start = time.process_time()
        depths = real(model, examples, formulation, device, chunk)
        took = time.process_time() - start
        inputs = formulations.make_inputs(examples, formulation)
        arrays = {f"parameter {n}": t.detach().cpu().numpy() for n, t in model.state_dict().items()}
        arrays.update({"x": inputs.x, "call": np.array(repr((formulation, chunk)))})
        item = _test[0]
        _calls.append((getattr(item, "nodeid", "?"), content_sha256(arrays), _shares(item), took))
        return depths

    formulations.predict_depth = logged


def pytest_sessionfinish(session: pytest.Session) -> None:
    (_FOLDER / f"{os.environ.get('PYTEST_XDIST_WORKER', 'main')}.json").write_text(json.dumps(_calls))


def _repeats(calls: list[list[Any]]) -> tuple[float, float]:
    """CPU of all ``calls``, and of those beyond the cheapest one of each content."""
    by_key: dict[str, list[float]] = {}
    for _, key, _, took in calls:
        by_key.setdefault(key, []).append(took)
    total = sum(sum(t) for t in by_key.values())
    return total, total - sum(min(t) for t in by_key.values())


def pytest_terminal_summary(terminalreporter: Any) -> None:
    if os.environ.get("PYTEST_XDIST_WORKER"):
        return
    calls = [c for f in sorted(_FOLDER.glob("*.json")) for c in json.loads(f.read_text())]
    total, repeats = _repeats(calls)
    shared_total, shared_repeats = _repeats([c for c in calls if c[2]])
    terminalreporter.write_line(
        f"dbox_repeats: {len(calls)} predict_depth calls, CPU {total:.1f} s, of which repeats "
        f"{repeats:.1f} s; in the tests that share: {shared_total:.1f} s, repeats {shared_repeats:.1f} s "
        f"(log: {_FOLDER})"
    )
