"""The fast path of the strict CSV reading (pandas on a clean file): numbers as ``float`` gives them, clean files."""

from __future__ import annotations

import decimal
import random
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import odmd_bench
from odmd_bench.inputs import table
from odmd_bench.inputs.problems import Problems
from odmd_bench.predict import sequence_rows, sequences


def _random_cells(n: int, seed: int) -> list[str]:
    """Decimal strings of every shape the readers take: any length, sign, point and exponent."""
    r = random.Random(seed)
    out = []
    for _ in range(n):
        digits = "".join(r.choice("0123456789") for _ in range(r.randint(0, 18)))
        fraction = "".join(r.choice("0123456789") for _ in range(r.randint(0, 26)))
        sign = r.choice(["", "", "-", "+"])
        cell = sign + digits + ("." + fraction if r.random() < 0.8 or not digits else fraction)
        cell = cell if any(ch.isdigit() for ch in cell) else cell + "0"
        if r.random() < 0.2:
            cell += r.choice("eE") + r.choice(["", "+", "-"]) + str(r.randint(0, 330))
        out.append(cell)
    return out


def _halfway_cells(n: int, seed: int) -> list[str]:
    """Exact midpoints between two float64, and decimals a unit in the 19th digit either side."""
    rng = np.random.default_rng(seed)
    cells = ["9007199254740993", "9007199254740993.0", "-9007199254740995", "0.5", "2.5"]
    for v in rng.random(n) * 10.0 ** rng.integers(-3, 6, n):
        a = float(v)
        mid = (decimal.Decimal(a) + decimal.Decimal(float(np.nextafter(a, np.inf)))) / 2
        cells.append(format(mid, "f"))
        for rounding in (decimal.ROUND_DOWN, decimal.ROUND_UP, decimal.ROUND_HALF_EVEN):
            context = decimal.Context(prec=19, rounding=rounding)
            cells.append(format(context.plus(mid), "f"))
    return cells


_EDGES = [
    "-0.0", "0", "-.5", "5.", "00012.5000", "1e5", "1E-5", "+1.5", "4.9e-324", "2.4703282292062327e-324",
    "2.4703282292062328e-324", "2.2250738585072011e-308", "2.2250738585072014e-308", "1.7976931348623157e308",
    "1.7976931348623158e308", "0." + "0" * 400 + "1", "1" * 400, "0.1" + "0" * 300 + "1", "123456789012345678901234567890",
    "0.30000000000000004", "9007199254740993.000000000000000000001", "1e-400",
]  # fmt: skip


def test_clean_files_convert_every_number_as_float_does() -> None:
    """The pandas path gives each cell bit for bit what Python's ``float`` gives it."""
    rng = np.random.default_rng(0)
    x = rng.standard_normal(100_000) * 10.0 ** rng.integers(-300, 300, 100_000)
    cells = [repr(float(v)) for v in x] + _random_cells(200_000, 1) + _halfway_cells(3000, 2) + _EDGES
    cells = [c for c in cells if abs(float(c)) != np.inf]
    data = ("s,v\n" + "".join(f"a,{c}\n" for c in cells)).encode()
    found = table.clean_columns(data, 2, [[1]], 0)
    assert found is not None and found.n == len(cells)
    got = found.numbers[0][:, 0]
    want = np.array([float(c) for c in cells])
    wrong = np.flatnonzero(got.view(np.uint64) != want.view(np.uint64))
    assert not wrong.size, [(cells[i], got[i], want[i]) for i in wrong[:5]]
    assert np.signbit(got[cells.index("-0.0")])


def test_cells_the_row_reader_takes_otherwise_are_not_clean() -> None:
    """Spaces around a number, infinities, ``nan`` and what is no number leave the fast path."""
    for cell in [
        " 1",
        "1 ",
        "\t1",
        "\x0b1",
        "inf",
        "-Infinity",
        "1e400",
        "nan",
        "NaN",
        "1_0",
        "0x10",
        "1e",
        ".",
        "١٢",
    ]:
        data = f"s,v\na,2\nb,{cell}\nc,3\n".encode()
        assert table.clean_columns(data, 2, [[1]], 0) is None, cell
    spaced = table.clean_columns(b"s,v\n a ,1\nb b,2\n", 2, [[1]], 0)
    assert (
        spaced is not None and spaced.values == ("a", "b b") and spaced.numbers[0].tolist() == [[1.0], [2.0]]
    )


def test_clean_files_and_the_row_reader_agree_on_random_files() -> None:
    """Files of random cells (numbers, text, spaces, odd bytes): either not clean, or read alike."""
    r = random.Random(7)
    alphabet = [
        "1",
        "0.5",
        "-2e3",
        "+.5",
        "",
        " ",
        "\t",
        "nan",
        "inf",
        "a",
        "é",
        "\x1a",
        "\x1f",
        ",",
        "\r\n",
        "\n",
        "e",
    ]
    head = "sequence,observation,x1,y1,x2,y2,cam_x,cam_y,cam_z,note\n"
    agree = 0
    for _ in range(400):
        lines = []
        for i in range(r.randint(1, 6)):
            cells = [r.choice(["s", " s", "t"]), str(i)] + [
                r.choice(["3", "4.25", "-1e-3", "7."])
                if r.random() < 0.97
                else "".join(r.choices(alphabet, k=2))
                for _ in range(7)
            ]
            lines.append(
                ",".join(cells) + "," + ("".join(r.choices(alphabet, k=2)) if r.random() < 0.3 else "n")
            )
        text = head + "\n".join(lines) + r.choice(["", "\n"])
        careful, problems, fast = _both_problems(text)
        if fast is not None:
            assert not problems, (text, problems.lines())
            _assert_same(careful, fast)
            agree += 1
    assert agree > 20


def _both_problems(text: str) -> tuple[sequence_rows.Rows, Problems, sequence_rows.Rows | None]:
    data = text.encode()
    header, cols = sequence_rows.header_columns(data, Problems()) or ([], {})
    problems = Problems()
    careful = sequence_rows.careful_rows(text, header, cols, problems)
    return careful, problems, sequence_rows.fast_rows(data, header, cols)


def test_large_files_take_the_fast_path_small_files_the_row_reader(monkeypatch: pytest.MonkeyPatch) -> None:
    """Past :data:`~odmd_bench.inputs.table.PANDAS_BYTES` a clean file is read by pandas, alike."""
    text = sequences.format_sequences(odmd_bench.generate(500, perturbation="both", rng=4))
    calls = []
    monkeypatch.setattr(sequences, "fast_rows", lambda *a: calls.append(1) or sequence_rows.fast_rows(*a))
    careful = sequences.read_sequences(text.encode(), (640, 480))
    assert not calls and len(text) < table.PANDAS_BYTES
    monkeypatch.setattr(sequences, "PANDAS_BYTES", 0)
    fast = sequences.read_sequences(text.encode(), (640, 480))
    assert calls
    for name in ("boxes", "camera", "depth", "observation_depth", "detected"):
        a, b = getattr(fast.examples(), name), getattr(careful.examples(), name)
        assert a.tobytes() == b.tobytes(), name


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


def test_the_predictions_reader_reads_uncertainty_columns_alike_by_pandas(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A large predictions file's uncertainty columns (pandas) read as a small one's (``float``)."""
    from odmd_bench.evaluation import parse, rows

    r = random.Random(5)
    lines = ["split,set,index,depth,depth_lo,depth_hi,level,depth_std"]
    for i in range(2000):
        d = r.uniform(0.5, 40)
        lo = r.choice([repr(d * 0.9), f"{d * 0.9:.3e}", "+0.25", "0.", ".25E-1", "0." + "1" * 30])
        lines.append(f"test,normal,{i},{d!r},{lo},{d * 1.1!r},0.9,{d * 0.05!r}")
    data = ("\n".join(lines) + "\n").encode()
    small = parse.parse_predictions(data)
    monkeypatch.setattr(rows, "PANDAS_BYTES", 0)
    large = parse.parse_predictions(data)
    assert small.uncertainty and not small.problems
    for c, values in small.uncertainty.items():
        assert values.tobytes() == large.uncertainty[c].tobytes(), c
    assert table.number_column(["1", "", "2"]) is None and table.number_column(["1e", "2"]) is None
