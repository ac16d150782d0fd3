"""describe() and `odmd-bench info --stats`: the ranges of depth and camera motion a set covers."""

from __future__ import annotations

import json
from pathlib import Path

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

import odmd_bench
from odmd_bench import Examples
from odmd_bench.cli.main import cli
from odmd_bench.data.describe import describe, format_description
from odmd_bench.data.io import write_sets

DOCS = Path(__file__).resolve().parents[1] / "docs"


@pytest.fixture(scope="module")
def pz_training() -> dict:
    """describe() of the p-z training stream as the docs compute it (100,000 examples, seed 0)."""
    return describe(odmd_bench.generate(100000, "odms", "both", rng=0))


def _hand_made() -> Examples:
    """Four examples of three observations whose every summary number is known by hand."""
    camera = np.zeros((4, 3, 3))
    camera[0, 0] = (0.0, 0.0, -0.5)  # forward 0.5 m along z: L 0.5, Z_n 1.0, ratio 2
    camera[1, 0] = (0.0, 0.0, 0.25)  # backward 0.25 m: L 0.25, Z_n 1.0, ratio 4
    camera[2, 0] = (0.375, 0.0, -0.5)  # x,y motion: L 0.625, Z_n unknown (NaN)
    camera[2, 1] = (0.125, 0.0, -0.25)  # dyadic numbers: shifts are exact
    # example 3 does not move: no L, no ratio, not counted for forward or x,y motion
    detected = np.ones((4, 3), dtype=bool)
    detected[1, 1] = False
    boxes = np.full((4, 3, 4), 0.1)
    depth = np.array([1.0, 1.0, np.nan, 2.0])
    return Examples(boxes=boxes, detected=detected, camera=camera, depth=depth)


def test_every_number_of_a_hand_made_set() -> None:
    d = describe(_hand_made())
    assert d["n"] == 4 and d["n_obs"] == 3
    assert d["depth"]["n"] == 3 and d["depth"]["min"] == 1.0 and d["depth"]["max"] == 2.0
    assert d["depth"]["median"] == 1.0 and d["depth"]["mean"] == pytest.approx(4 / 3)
    assert d["camera_travel"]["n"] == 3
    assert (d["camera_travel"]["min"], d["camera_travel"]["max"]) == (0.25, 0.625)
    assert d["depth_over_travel"]["n"] == 2
    assert (d["depth_over_travel"]["min"], d["depth_over_travel"]["max"]) == (2.0, 4.0)
    assert d["forward"] == pytest.approx(2 / 3)  # examples 0 and 2 of the three that move
    assert d["xy_motion"] == pytest.approx(1 / 3)
    assert d["missing_observations"] == pytest.approx(1 / 12)
    assert d["examples_with_missing"] == pytest.approx(1 / 4)
    json.dumps(d)  # JSON-ready


def test_an_empty_set_and_a_set_without_motion_or_depth() -> None:
    empty = Examples(
        boxes=np.zeros((0, 10, 4)), detected=np.zeros((0, 10), bool), camera=np.zeros((0, 10, 3))
    )
    d = describe(empty)
    assert d["n"] == 0 and d["depth"]["n"] == 0 and d["depth"]["median"] is None
    assert d["forward"] is None and d["xy_motion"] is None
    still = Examples(boxes=np.ones((2, 10, 4)), detected=np.ones((2, 10), bool), camera=np.zeros((2, 10, 3)))
    d = describe(still)
    assert d["camera_travel"]["n"] == 0 and d["depth_over_travel"]["n"] == 0 and d["forward"] is None
    text = "\n".join(format_description("still", d))
    assert "set still: 2 examples x 10 observations" in text and " - " in text


def test_generated_z_only_data_agree_with_the_generator_configuration() -> None:
    cfg = odmd_bench.PRESETS["odms"]
    ex = odmd_bench.generate(4000, "odms", "normal", rng=3)
    d = describe(ex)
    assert d["xy_motion"] == 0.0 and d["missing_observations"] == 0.0
    # the total move is drawn from [move_min, move_max] along z; half the examples are reversed
    assert cfg.move_min[2] <= d["camera_travel"]["min"] and d["camera_travel"]["max"] <= cfg.move_max[2]
    assert 0.45 < d["forward"] < 0.55
    ratio = ex.depth / np.abs(ex.camera[:, 0, 2])
    assert d["depth_over_travel"]["median"] == pytest.approx(float(np.median(ratio)))


def test_info_stats_prints_and_returns_the_summary(tmp_path: Path) -> None:
    f = tmp_path / "x.h5"
    sets = {s: odmd_bench.generate(50, rng=i) for i, s in enumerate(("normal", "camera", "object", "robot"))}
    write_sets(f, sets)
    r = CliRunner().invoke(cli, ["info", str(f), "--stats"])
    assert r.exit_code == 0, r.output
    for line in format_description("camera", describe(sets["camera"])):
        assert line in r.stdout
    r = CliRunner().invoke(cli, ["info", str(f), "--stats", "--json"])
    assert r.exit_code == 0, r.output
    body = json.loads(r.stdout)
    assert body["sets"]["robot"]["stats"] == json.loads(json.dumps(describe(sets["robot"])))
    r = CliRunner().invoke(cli, ["info", str(f), "--json"])
    assert "stats" not in json.loads(r.stdout)["sets"]["robot"]


def test_info_stats_refuses_an_altered_set(tmp_path: Path) -> None:
    """--stats reads the arrays, so it checks them: a changed depth is named, exit 2, no traceback."""
    f = tmp_path / "x.h5"
    write_sets(
        f, {s: odmd_bench.generate(20, rng=i) for i, s in enumerate(("normal", "camera", "object", "robot"))}
    )
    with h5py.File(f, "r+") as h:
        h["object/depth"][3] = 9.0
    r = CliRunner().invoke(cli, ["info", str(f)])
    assert r.exit_code == 0  # the summary reads attributes only
    r = CliRunner().invoke(cli, ["info", str(f), "--stats"])
    assert r.exit_code == 2 and "object" in r.stderr and "Traceback" not in r.output, r.output


def test_docs_dbox_table_of_z_n_over_l_is_what_the_commands_give(
    paper_data_dir: Path, pz_training: dict
) -> None:
    """docs/dbox.md's table of Z_n / L (training streams against the val sets) holds."""
    import re

    docs = (DOCS / "dbox.md").read_text(encoding="utf-8")
    rows = {}
    for line in docs.splitlines():
        m = re.match(r"\| (.+?) \| ([\d.]+) \| ([\d.]+) \| ([\d.]+) \| (\d+) % \|$", line)
        if m:
            rows[m.group(1)] = tuple(float(v) for v in m.groups()[1:])
    val = odmd_bench.load_split("val", "odms-detection", paper_data_dir)
    paper_val = odmd_bench.load_split("val", "odmd-paper", paper_data_dir)
    sources = {
        "`p-z` training (preset `odms`, perturbation `both`)": pz_training,
        "ODMS-detection val normal": describe(val["normal"]),
        "ODMS-detection val robot": describe(val["robot"]),
        "ODMS-detection val driving": describe(val["driving"]),
        "`p` training (the same command with preset `odmd`), for comparison": describe(
            odmd_bench.generate(100000, "odmd", "both", rng=0)
        ),
        "`odmd-paper` val robot": describe(paper_val["robot"]),
    }
    assert set(rows) == set(sources), sorted(rows)
    for label, d in sources.items():
        r = d["depth_over_travel"]
        got = (round(r["p5"], 2), round(r["median"], 2), round(r["p95"], 2), round(100 * d["forward"]))
        assert got == rows[label], (label, got, rows[label])


def test_docs_own_data_coverage_numbers(pz_training: dict) -> None:
    """docs/own-data.md's Z_n / L of the two example sequences and of the p-z training stream."""
    text = (DOCS / "own-data.md").read_text(encoding="utf-8")
    seqs = odmd_bench.read_sequences(DOCS / "sequences-example.csv", image_size=(4032, 3024))
    medians = [odmd_bench.describe(ex)["depth_over_travel"]["median"] for _, ex in seqs.groups]
    train = pz_training["depth_over_travel"]["p5"]
    line = f"# {medians[0]:.3f} trash can, {medians[1]:.3f} bird house"
    assert line in text, line
    assert (
        f"# {train:.3f}" in text
        and f"{medians[1]:.3f} is at the\n5th percentile of what `p-z` trains on ({train:.3f})" in text
    )
