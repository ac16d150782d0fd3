"""The shared numeric bounds: every number that enters or leaves a command is bounded, the culprit named."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

import odmd_bench
from odmd_bench import DataError, UsageError, methods
from odmd_bench.cli.main import cli
from odmd_bench.errors import DepthRangeError
from odmd_bench.evaluation import kinds
from odmd_bench.inputs import bounds
from odmd_bench.predict import sequences

HEADER = "sequence,observation,x1,y1,x2,y2,cam_x,cam_y,cam_z,depth\n"


def _good(name: str = "s", move: float = 0.1) -> list[str]:
    return [
        f"{name},{k},100,100,{200 + 10 * k},{200 + 10 * k},0,0,{move * k},{5 - 0.1 * k}" for k in range(5)
    ]


def _run(tmp_path: Path, text: str, *args: str) -> tuple[int, str, Path]:
    src = tmp_path / "seq.csv"
    src.write_text(text)
    out = tmp_path / "out.csv"
    r = CliRunner().invoke(
        cli, ["predict", str(src), "--method", "box-ls", "--image-size", "640", "480", "-o", str(out), *args]
    )
    return r.exit_code, r.stderr, out


def test_evaluate_and_the_rest_share_one_depth_bound() -> None:
    assert kinds.MAX_ABS_DEPTH is bounds.MAX_ABS_DEPTH


@pytest.mark.parametrize(
    ("column", "value", "words"),
    [
        ("cam_z", "1e200", "cam_z is out of range (|cam_z| > 1e+12 m) (1 row): line 4"),
        ("x2", "1e9", "x2 is out of range (|x2| > 1e+06 pixels) (1 row): line 4"),
        ("depth", "1e-300", "depth is out of range (1e-06 to 1e+12 m) (1 row): line 4"),
        ("depth", "1e13", "depth is out of range (1e-06 to 1e+12 m) (1 row): line 4"),
    ],
)
def test_cells_beyond_the_bounds_are_refused_by_line(
    tmp_path: Path, column: str, value: str, words: str
) -> None:
    rows = _good()
    cells = rows[2].split(",")
    cells[HEADER.strip().split(",").index(column)] = value
    rows[2] = ",".join(cells)
    code, err, out = _run(tmp_path, HEADER + "\n".join(rows) + "\n")
    assert code == 2 and words in err and "Traceback" not in err
    assert not out.exists()


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (["--image-size", "640", "1e-300"], "image size: 1e-300 is outside 1 to 1e+06 pixels"),
        (["--image-size", "1e7", "480"], "image size: 1e+07 is outside 1 to 1e+06 pixels"),
        (["--intrinsics", "1e300", "500", "320", "240"], "intrinsics fx fy: 1e+300 is outside 1 to 1e+06"),
        (
            ["--intrinsics", "500", "500", "-1e9", "240"],
            "intrinsics cx cy: -1e+09 is outside -1e+06 to 1e+06",
        ),
    ],
)
def test_options_beyond_the_bounds_are_refused(tmp_path: Path, args: list[str], words: str) -> None:
    src = tmp_path / "seq.csv"
    src.write_text(HEADER + "\n".join(_good()) + "\n")
    base = ["predict", str(src), "--method", "robust", "-o", str(tmp_path / "o.csv")]
    if args[0] != "--image-size":
        base += ["--image-size", "640", "480"]
    r = CliRunner().invoke(cli, [*base, *args])
    assert r.exit_code == 2 and words in r.stderr and "Traceback" not in r.stderr


def test_depths_beyond_the_bound_from_bounded_cells_name_the_sequence(tmp_path: Path) -> None:
    # Boxes that barely grow while the camera moves 1e11 m: Box_LS's depth is ~1e22 m.
    far = [f"far,{k},100,100,{200 + 1e-9 * k},{200 + 1e-9 * k},0,0,{1e11 * k}," for k in range(5)]
    code, err, out = _run(tmp_path, HEADER + "\n".join(_good() + far) + "\n")
    assert code == 2 and "Traceback" not in err
    assert (
        "error: method 'box-ls' gives depths that are not finite or beyond 1e+12 m for 1 of 2 sequences"
        in err
    )
    assert "  - sequences 'far'\n" in err
    assert not out.exists()


def test_an_own_methods_non_finite_depths_are_an_input_error_not_a_bug() -> None:
    ex = odmd_bench.generate(3, rng=0)
    for bad in (np.inf, 1e200, -1e13):

        def report(examples: odmd_bench.Examples, bad: float = bad) -> tuple[np.ndarray, dict[str, int]]:
            d = np.ones(len(examples))
            d[-1] = bad
            return d, {}

        m = methods.Method("own", "odmd_bench_baselines.own", "odmd-bench 0.1.0", lambda e: None, report)
        with pytest.raises(DepthRangeError, match="for 1 of 3 examples") as info:
            m.run(ex)
        assert info.value.where == (2,) and f"example 2: {bad!r}" in info.value.problems[0]


def test_pixels_refuse_out_of_range_arrays_and_options() -> None:
    ex = odmd_bench.generate(2, rng=0)
    corners = np.full((2, ex.n_obs, 4), [100.0, 100.0, 200.0, 200.0])
    camera = np.zeros((2, ex.n_obs, 3))
    camera[1, 3, 2] = 1e200
    with pytest.raises(DataError) as info:
        odmd_bench.Examples.from_pixels(corners, camera, (640, 480), depth=[1e-300, 3.0])
    text = str(info.value)
    assert "camera position beyond 1e+12 m: observation 1 3" in text
    assert "known depth outside 1e-06 to 1e+12 m: example 0" in text
    with pytest.raises(UsageError, match="out of range"):
        sequences.read_sequences((HEADER + "\n".join(_good())).encode(), (0.5, 480))


def test_weights_scaled_beyond_the_bound_are_named(tmp_path: Path) -> None:
    torch = pytest.importorskip("torch")
    from odmd_bench_baselines import dbox

    shipped = dbox.weights_path("p")
    state = torch.load(shipped, weights_only=True)
    scaled = tmp_path / "scaled.pt"
    torch.save({k: v * 1e30 for k, v in state.items()}, scaled)
    ex = odmd_bench.generate(4, rng=0)
    text = tmp_path / "seq.csv"
    sequences.write_sequences(text, ex, (640, 480))
    r = CliRunner().invoke(
        cli,
        ["predict", str(text), "--method", "dbox", "--image-size", "640", "480", "--weights", str(scaled)],
    )
    assert r.exit_code == 2 and "Traceback" not in r.stderr and "internal error" not in r.stderr
    assert str(scaled) in r.stderr and "beyond 1e+06 (the bound on a weight" in r.stderr
