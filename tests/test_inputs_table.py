"""The fast path of the strict CSV reading: decimals converted without a call per cell, clean files."""

from __future__ import annotations

import decimal
import random
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import odmd_bench
from odmd_bench.inputs import decimals, table
from odmd_bench.inputs.problems import Problems
from odmd_bench.predict import sequence_rows, sequences


def _parse(cells: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """parse_decimals on ``cells`` laid out like a CSV line after a header."""
    body = b"h" * 32 + b"".join(c.encode() + b"," for c in cells)
    lens = np.array([len(c.encode()) for c in cells], dtype=np.int64)
    end = 32 + np.cumsum(lens + 1) - 1
    start = end - lens
    dot = np.array([c.rfind(".") for c in cells], dtype=np.int64)
    dot = np.where(dot >= 0, start + dot, end)
    return decimals.parse_decimals(np.frombuffer(body, dtype=np.uint8), start, end, dot)


def _assert_as_float(cells: list[str], at_least: float) -> None:
    """Every cell converted is bit for bit ``float``'s; at least a fraction ``at_least`` converted."""
    values, done = _parse(cells)
    want = np.array([float(c) for c in cells])
    wrong = np.flatnonzero(done & (values.view(np.uint64) != want.view(np.uint64)))
    assert not wrong.size, [(cells[i], values[i], want[i]) for i in wrong[:5]]
    assert done.mean() >= at_least, done.mean()


def _random_cells(n: int, seed: int) -> list[str]:
    """Decimal strings of every shape the fast form has, and some it has not."""
    r = random.Random(seed)
    out = []
    for _ in range(n):
        digits = "".join(r.choice("0123456789") for _ in range(r.randint(0, 18)))
        fraction = "".join(r.choice("0123456789") for _ in range(r.randint(0, 26)))
        sign = r.choice(["", "", "-", "+"])
        cell = sign + digits + ("." + fraction if r.random() < 0.8 or not digits else fraction)
        out.append(cell if any(ch.isdigit() for ch in cell) else cell + "0")
    return out


@pytest.fixture(params=[True, False], ids=["extended", "float64"])
def precision(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch) -> bool:
    """Both conversions: extended precision (where the platform has it) and plain float64."""
    if request.param and not decimals._EXTENDED:
        pytest.skip("no 64-bit-significand longdouble here")
    monkeypatch.setattr(decimals, "use_extended", request.param)
    return bool(request.param)


def test_repr_written_numbers_convert_exactly(precision: bool) -> None:
    rng = np.random.default_rng(0)
    x = rng.standard_normal(200_000) * 10.0 ** rng.integers(-4, 16, 200_000)
    x = np.concatenate((x, rng.random(50_000), rng.integers(-(10**6), 10**6, 50_000).astype(float)))
    _assert_as_float([repr(float(v)) for v in x], 0.9 if precision else 0.25)


def test_decimal_strings_of_every_length_convert_as_float_does(precision: bool) -> None:
    _assert_as_float(_random_cells(300_000, 1), 0.2 if precision else 0.1)


def test_decimals_halfway_between_two_floats_are_left_to_float(precision: bool) -> None:
    """Exact midpoints, and decimals a unit in the 19th digit either side of one."""
    rng = np.random.default_rng(2)
    cells = ["9007199254740993", "9007199254740993.0", "-9007199254740995", "0.5", "2.5"]
    for v in rng.random(3000) * 10.0 ** rng.integers(-3, 6, 3000):
        a = float(v)
        mid = (decimal.Decimal(a) + decimal.Decimal(float(np.nextafter(a, np.inf)))) / 2
        for rounding in (decimal.ROUND_DOWN, decimal.ROUND_UP, decimal.ROUND_HALF_EVEN):
            context = decimal.Context(prec=19, rounding=rounding)
            cells.append(format(context.plus(mid), "f"))
    _assert_as_float(cells, 0.0)
    values, done = _parse(["9007199254740993"])
    assert not done[0] or values[0] == 9007199254740992.0


def test_cells_not_in_the_fast_form_are_marked() -> None:
    cells = ["1e5", "+1.5", "1.2.3", "1-2", "- 1", ".", "-", "1,5", "0x10", "inf", "nan", "1_000", "١٢"]
    _, done = _parse(cells)
    assert not done.any()
    _, done = _parse(["-0.0", "0", "-.5", "5.", "00012.5000"])
    assert done.all()
    values, _ = _parse(["-0.0"])
    assert np.signbit(values[0])


def _both(text: str) -> tuple[sequence_rows.Rows, sequence_rows.Rows | None]:
    data = text.encode()
    header, cols = sequence_rows.header_columns(data, Problems()) or ([], {})
    careful = sequence_rows.careful_rows(text, header, cols, Problems())
    return careful, sequence_rows.fast_rows(data, header, cols)


def _assert_same(a: sequence_rows.Rows, b: sequence_rows.Rows) -> None:
    np.testing.assert_array_equal(a.lines, b.lines)
    assert a.sequence.tolist() == b.sequence.tolist()
    for name in ("numbers", "depth", "orientation"):
        x, y = getattr(a, name), getattr(b, name)
        assert (x is None) == (y is None), name
        if x is not None:
            assert x.shape == y.shape and x.tobytes() == np.ascontiguousarray(y).tobytes(), name


def test_a_clean_file_reads_the_same_as_row_by_row() -> None:
    r = random.Random(3)
    head = "note,sequence,observation,x1,y1,x2,y2,cam_x,cam_y,cam_z,depth,cam_qx,cam_qy,cam_qz,cam_qw\n"
    names = ["a", " spaced ", "naïve", "a-very-long-sequence-name-of-forty-bytes!", "s.1", "7"]
    lines = []
    for i in range(3000):
        cells = [r.choice(["", "x", "note, no", "1.2.3"]).replace(",", ";"), r.choice(names), str(i)]
        box = [repr(r.uniform(-10, 700)) for _ in range(4)] if r.random() > 0.1 else [""] * 4
        cam = [
            r.choice([repr(r.gauss(0, 1)), "1e-05", "+2.5", "3", "-0.0", "1E3", "12345678901234567890.5"])
            for _ in range(3)
        ]
        quat = [repr(r.random()) for _ in range(4)]
        lines.append(",".join([*cells, *box, *cam, r.choice(["", repr(r.uniform(0.1, 9))]), *quat]))
    text = head + "\n".join(lines) + "\n"
    careful, fast = _both(text)
    assert fast is not None
    _assert_same(careful, fast)
    for variant in (text.replace("\n", "\r\n"), text[:-1]):  # CRLF; no line end at the end
        careful, fast = _both(variant)
        assert fast is not None
        _assert_same(careful, fast)


@pytest.mark.parametrize("end", ["\n", "\r\n"])
def test_the_first_row_is_read_whole_whatever_the_line_ends(end: str) -> None:
    text = end.join(
        [
            "sequence,observation,x1,y1,x2,y2,cam_x,cam_y,cam_z",
            "seq1,1,100,100,140,150,0,0,0.5",
            "seq1,2,101,100,141,150,0,0,0.4",
            "",
        ]
    )
    careful, fast = _both(text)
    assert fast is not None and fast.sequence.tolist() == ["seq1", "seq1"]
    _assert_same(careful, fast)


@pytest.mark.parametrize(
    "change",
    [
        ("a,1,", "a,1,\n\na,1,"),  # a blank line
        ("a,1,", 'a,1,"'),  # a quote
        ("0.5\n", "0.5\r"),  # a lone carriage return
        ("a,1,100", "a,1,100,7"),  # a field too many
        ("a,1,100", "a,1,1.0.0"),  # no number
        ("a,1,100", "a,1, 100"),  # a space (the row-by-row reader strips it)
        ("a,1,100", "a,1,nan"),  # not finite
        ("a,1,", ",1,"),  # no sequence name
    ],
)
def test_a_file_that_is_not_clean_goes_row_by_row(change: tuple) -> None:
    good = "sequence,observation,x1,y1,x2,y2,cam_x,cam_y,cam_z\na,1,100,100,140,150,0,0,0.5\na,2,101,100,141,150,0,0,0.4\n"
    assert _both(good)[1] is not None
    careful, fast = _both(good.replace(*change))
    assert fast is None


def test_the_sequences_reader_is_the_same_on_the_fast_and_the_careful_path() -> None:
    ex = odmd_bench.generate(500, perturbation="both", rng=4)
    text = sequences.format_sequences(ex)
    fast = sequences.read_sequences(text.encode(), (640, 480))
    careful = sequences.read_sequences(text.replace("\n", "\n\n", 1).encode(), (640, 480))
    for name in ("boxes", "camera", "depth", "observation_depth", "detected"):
        a, b = getattr(fast.examples(), name), getattr(careful.examples(), name)
        assert a.tobytes() == b.tobytes(), name


def test_factorize_keeps_the_order_of_first_appearance() -> None:
    codes, uniques = table.factorize(np.array(["b", "b", "a", "c", "a", "b"], dtype=object))
    assert codes.tolist() == [0, 0, 1, 2, 1, 0] and uniques.tolist() == ["b", "a", "c"]
    codes, uniques = table.factorize(np.zeros(0, dtype=object))
    assert codes.size == 0 and uniques.size == 0


def test_predict_reads_and_solves_without_pandas(tmp_path: Path) -> None:
    path = tmp_path / "s.csv"
    sequences.write_sequences(path, odmd_bench.generate(50, rng=0))
    code = (
        "import sys\n"
        "from odmd_bench.cli.main import main\n"
        f"sys.argv = ['odmd-bench', 'predict', {str(path)!r}, '--method', 'box-ls', '--image-size', '640', '480', '-o', {str(tmp_path / 'd.csv')!r}]\n"
        "try:\n    main()\nexcept SystemExit as e:\n    assert not e.code, e.code\n"
        "assert 'pandas' not in sys.modules, 'pandas imported'\n"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path)
    assert r.returncode == 0, r.stderr


def test_a_big_endian_machine_reads_the_same_by_float(monkeypatch: pytest.MonkeyPatch) -> None:
    """The words are little-endian: elsewhere every cell goes to ``float`` and names row by row."""
    text = sequences.format_sequences(odmd_bench.generate(30, rng=5), names=[f"s{i}" for i in range(30)])
    want = _both(text)[1]
    monkeypatch.setattr(decimals, "LITTLE_ENDIAN", False)
    monkeypatch.setattr(table, "LITTLE_ENDIAN", False)
    _, done = _parse(["1.5"])
    assert not done.any()
    got = _both(text)[1]
    assert want is not None and got is not None
    _assert_same(want, got)
