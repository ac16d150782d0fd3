r"""``predict`` throughput: parsing a sequences CSV and solving Box_LS on it.

Run (one core: keep OpenBLAS to one thread):

    OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 .venv/bin/pytest benchmarks/bench_predict.py \
        --benchmark-only -p no:randomly --benchmark-columns=min,median,ops -s

The file: 100,000 sequences of 10 observations (1,000,000 rows, about 90 MB) made from
ODMD examples (preset odmd, perturbation both, seed 0), 2% of the boxes missed (and the
few boxes of width or height <= 0 made by the box noise missed too), numbers written with ``repr`` precision (:func:`~odmd_bench.predict.sequences.format_sequences`).
Rates are sequences per second = 100,000 / best time (``benchmarks/reader_before_after.py``
times the reader of an earlier commit against this one on the same file):

* ``test_parse``: :func:`read_sequences` on the file's bytes, strict checks and
  conversion to examples included (the vectorised path of a well-formed file);
* ``test_rows``: the reading alone (:func:`~odmd_bench.predict.sequence_rows.fast_rows`:
  the byte checks, pandas' C parser, numbers correctly rounded, names factorized and
  stripped), and ``test_rows_pandas_reference``, a bare ``read_csv`` of the same file with
  the reader's options and ``factorize``: the reference of the same run (what the
  checks around pandas cost), its ratio printed;
* ``test_parse_careful``: the same file with one blank line, which sends it through the
  row-by-row reader that locates problems (what a file with a problem costs);
* ``test_solve``: Box_LS (``predict_report``, fills and fallbacks included) on the
  converted examples, the solve ``predict`` runs;
* ``test_predict_sequences``: method lookup, solve and the per-sequence report.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from odmd_bench_baselines import box_ls

import odmd_bench
from odmd_bench.predict import predict_sequences
from odmd_bench.predict.sequences import Sequences, format_sequences, read_sequences

N = 100_000
SIZE = (640, 480)


def sequences_file() -> bytes:
    """The benchmark's sequences file (module docstring), as bytes."""
    ex = odmd_bench.generate(N, preset="odmd", perturbation="both", rng=0)
    det = np.random.default_rng(0).random(ex.detected.shape) >= 0.02
    # Box noise can make a tiny box's width negative, which no detector writes (and the
    # reader refuses): such a box counts as missed too.
    det &= (ex.boxes[:, :, 2] > 0) & (ex.boxes[:, :, 3] > 0)
    ex = dataclasses.replace(ex, detected=det, boxes=np.where(det[..., None], ex.boxes, 0.0))
    return format_sequences(ex).encode()


@pytest.fixture(scope="module")
def data() -> bytes:
    return sequences_file()


@pytest.fixture(scope="module")
def sequences(data: bytes) -> Sequences:
    return read_sequences(data, SIZE)


def _rate(benchmark: object) -> None:
    stats = benchmark.stats.stats  # type: ignore[attr-defined]
    benchmark.extra_info["sequences_per_second"] = N / stats.min  # type: ignore[attr-defined]
    print(f"\n{N / stats.min:,.0f} sequences/s (best of {stats.rounds})")


def test_parse(benchmark, data: bytes) -> None:
    seqs = benchmark.pedantic(read_sequences, args=(data, SIZE), rounds=3, iterations=1)
    assert len(seqs) == N and seqs.examples().n_obs == 10
    benchmark.extra_info["megabytes"] = len(data) / 1e6
    _rate(benchmark)


def _header(data: bytes) -> tuple[list[str], dict[str, int]]:
    from odmd_bench.inputs.problems import Problems
    from odmd_bench.predict.sequence_rows import header_columns

    parsed = header_columns(data, Problems())
    assert parsed is not None
    return parsed


_ROWS: dict[str, float] = {}


def test_rows(benchmark, data: bytes) -> None:
    from odmd_bench.predict.sequence_rows import fast_rows

    header, cols = _header(data)
    rows = benchmark.pedantic(fast_rows, args=(data, header, cols), rounds=5, iterations=1)
    assert rows is not None and len(rows.lines) == 10 * N
    _ROWS["ours"] = benchmark.stats.stats.min
    _rate(benchmark)


def test_rows_pandas_reference(benchmark, data: bytes) -> None:
    """The reading ``fast_rows`` does, bare: pandas' C parser.

    A few byte-level checks (no quote, the commas), ``read_csv`` with the reader's
    options, the names factorized and stripped, the number columns gathered.
    """
    pd = pytest.importorskip("pandas")
    import io

    header, cols = _header(data)
    numeric = [c for c in header if c != "sequence"]

    def read() -> tuple[np.ndarray, np.ndarray]:
        returns = data.count(b"\r")
        assert b'"' not in data and not returns
        n_lines = data.count(b"\n") + (not data.endswith(b"\n"))
        assert data.count(b",") == (len(header) - 1) * n_lines
        dtypes = {i: (object if name == "sequence" else np.float64) for i, name in enumerate(header)}
        df = pd.read_csv(
            io.BytesIO(data),
            header=None,
            skiprows=1,
            names=list(range(len(header))),
            dtype=dtypes,
            keep_default_na=False,
            na_values=[""],
            index_col=False,
            encoding="utf-8",
            engine="c",
            low_memory=False,
        )
        codes, uniques = pd.factorize(df[cols["sequence"]].to_numpy(dtype=object), sort=False)
        stripped = np.array([str(u).strip() for u in uniques], dtype=object)
        numbers = np.empty((len(df), len(numeric)))
        for j, c in enumerate(numeric):
            numbers[:, j] = df[cols[c]].to_numpy(dtype=np.float64)
        return stripped[codes], numbers

    names, numbers = benchmark.pedantic(read, rounds=5, iterations=1)
    assert numbers.shape == (10 * N, len(numeric))
    ref = benchmark.stats.stats.min
    benchmark.extra_info["reference"] = "a bare pandas reader: byte checks, read_csv (C engine), factorize"
    if "ours" in _ROWS:
        benchmark.extra_info["ours_over_pandas"] = _ROWS["ours"] / ref
        print(f"\nthe strict reader's fast path takes {_ROWS['ours'] / ref:.2f} times pandas' time")
    _rate(benchmark)


def test_parse_careful(benchmark, data: bytes) -> None:
    blank = data.replace(b"\n", b"\n\n", 1)
    seqs = benchmark.pedantic(read_sequences, args=(blank, SIZE), rounds=1, iterations=1)
    assert len(seqs) == N
    _rate(benchmark)


def test_solve(benchmark, sequences: Sequences) -> None:
    ex = sequences.examples()
    depth, _ = benchmark.pedantic(box_ls.predict_report, args=(ex,), rounds=10, iterations=1)
    assert depth.shape == (N,)
    _rate(benchmark)


def test_predict_sequences(benchmark, sequences: Sequences) -> None:
    result = benchmark.pedantic(predict_sequences, args=(sequences, "box-ls"), rounds=5, iterations=1)
    assert result.depth.shape == (N,)
    _rate(benchmark)
