"""The uncertainty columns: strict reading, the scores, and rules that reward honest sharp intervals.

docs/uncertainty.md explains each rule with the worked examples checked here by hand.
scipy (a dev-only dependency) cross-checks the CRPS and the normal's quantiles.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from scipy import integrate, stats

import odmd_bench
from odmd_bench import ValidationError
from odmd_bench.cli.main import cli
from odmd_bench.data.io import write_sets
from odmd_bench.data.registry import get_benchmark, set_file
from odmd_bench.evaluation.parse import parse_predictions
from odmd_bench.evaluation.predictions import format_predictions, write_predictions
from odmd_bench.evaluation.report import format_per_example, format_result
from odmd_bench.evaluation.scoring import evaluate
from odmd_bench.evaluation.uncertainty import (
    covered,
    crps_normal,
    interval_score,
    interval_width,
    normal_quantile,
    reliability,
)
from odmd_bench.predict.intervals import conformal_quantile, fit_calibration, relative_residuals

BENCH = "odmd-paper"
SIZES = {"normal": 7, "camera": 5, "object": 6, "robot": 4}
PERTURB = {"normal": "normal", "camera": "camera", "object": "object", "robot": "both"}


@pytest.fixture(scope="module")
def sets_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    data = tmp_path_factory.mktemp("unc-data")
    sets = {
        s: odmd_bench.generate(n, perturbation=PERTURB[s], rng=i) for i, (s, n) in enumerate(SIZES.items())
    }
    write_sets(
        set_file(get_benchmark(BENCH), "test", data), sets, file_attrs={"benchmark": BENCH, "split": "test"}
    )
    return data


def _truth(data: Path) -> dict[str, np.ndarray]:
    return {s: ex.depth for s, ex in odmd_bench.load_split("test", BENCH, data).items()}


def _file(tmp_path: Path, data: Path, scale: float = 1.1, width: float = 0.2, std: bool = True) -> Path:
    """Depths ``scale`` times the truth, intervals of ``depth * (1 -+ width)`` at level 0.9."""
    truth = _truth(data)
    depths = {s: scale * z for s, z in truth.items()}
    unc = {
        s: {"depth_lo": d * (1 - width), "depth_hi": d * (1 + width)}
        | ({"depth_std": d * width} if std else {})
        for s, d in depths.items()
    }
    path = tmp_path / "preds.csv"
    write_predictions(path, "test", depths, BENCH, uncertainty=unc, level=0.9)
    return path


# --- the scores, each against a case computed by hand --------------------------------


def test_interval_score_by_hand() -> None:
    # Z = 10, level 0.9 (a = 0.1, 2/a = 20): [9, 11] covers: width 2 m = 20 %;
    # [11, 12] misses by 1 m below: 1 + 20 * 1 = 21 m = 210 %; [8, 9] misses by 1 m above: 210 %.
    got = interval_score([10.0, 10.0, 10.0], [9.0, 11.0, 8.0], [11.0, 12.0, 9.0], 0.9)
    assert got.tolist() == pytest.approx([20.0, 210.0, 210.0], rel=1e-12)
    assert interval_width([10.0], [9.0], [11.0]).tolist() == [20.0]
    assert covered([10.0, 10.0], [10.0, 10.5], [10.0, 11.0]).tolist() == [True, False]  # bounds included


def test_crps_by_hand_and_against_scipy() -> None:
    # Z = mu: CRPS = sigma (2 phi(0) - 1/sqrt(pi)) = sigma (sqrt(2/pi) - sqrt(1/pi)).
    by_hand = 1.0 * (math.sqrt(2 / math.pi) - 1 / math.sqrt(math.pi))
    assert crps_normal([10.0], [10.0], [1.0])[0] == pytest.approx(by_hand / 10 * 100, rel=1e-12)
    assert crps_normal([10.0], [9.0], [0.0])[0] == pytest.approx(10.0)  # sigma 0: the absolute error
    # The definition, integral of (F(y) - 1{y >= Z})^2 dy, integrated numerically (scipy).
    rng = np.random.default_rng(0)
    for mu, s, z in zip(rng.uniform(1, 5, 6), rng.uniform(0.05, 2, 6), rng.uniform(1, 5, 6), strict=True):
        f = stats.norm(mu, s).cdf
        below, _ = integrate.quad(lambda y, f=f: f(y) ** 2, mu - 40 * s, z, limit=200)
        above, _ = integrate.quad(lambda y, f=f: (1 - f(y)) ** 2, z, mu + 40 * s, limit=200)
        assert crps_normal([z], [mu], [s])[0] == pytest.approx((below + above) / z * 100, rel=1e-7)


def test_normal_quantile_matches_scipy() -> None:
    for p in (0.05, 0.5, 0.9, 0.95, 0.995):
        assert normal_quantile(p) == pytest.approx(stats.norm.ppf(p), abs=1e-10)


def test_reliability_by_hand() -> None:
    # |Z - mu| / sigma = 0, 1, 2: the 50 % interval (+-0.674) covers one, the 99 % (+-2.576) all three.
    z = [10.0, 11.0, 12.0]
    assert reliability(z, [10.0, 10.0, 10.0], [1.0, 1.0, 1.0], (0.5, 0.9, 0.99)) == pytest.approx(
        [1 / 3, 2 / 3, 1.0]
    )


# --- the rules reward honest, sharp intervals ----------------------------------------


def _draw(n: int = 200_000) -> tuple[np.ndarray, np.ndarray]:
    """Estimates and true depths whose relative error is N(0, 0.1^2): the honest spread is 0.1 d."""
    rng = np.random.default_rng(7)
    d = rng.uniform(1.0, 5.0, n)
    return d, d * (1 + 0.1 * rng.standard_normal(n))


def test_too_narrow_intervals_are_caught_by_coverage() -> None:
    d, z = _draw()
    half = normal_quantile(0.95) * 0.1 * d
    honest = covered(z, d - half, d + half).mean()
    narrow = covered(z, d - half / 2, d + half / 2).mean()
    assert honest == pytest.approx(0.9, abs=0.005)
    assert narrow < 0.65  # claims 90 %, covers about 59 %


@pytest.mark.parametrize("factor", [0.5, 0.8, 1.25, 2.0])
def test_wrong_width_loses_on_interval_score_and_crps(factor: float) -> None:
    d, z = _draw()
    half = normal_quantile(0.95) * 0.1 * d
    honest_is = interval_score(z, d - half, d + half, 0.9).mean()
    other_is = interval_score(z, d - factor * half, d + factor * half, 0.9).mean()
    assert other_is > honest_is
    assert crps_normal(z, d, factor * 0.1 * d).mean() > crps_normal(z, d, 0.1 * d).mean()


def test_a_sharper_honest_method_wins() -> None:
    """Two honest methods: the one with the smaller error gets the narrower interval and the better scores."""
    d, z = _draw()
    rng = np.random.default_rng(8)
    d2 = z / (1 + 0.2 * rng.standard_normal(z.size))  # errors twice as large
    q = normal_quantile(0.95)
    sharp = interval_score(z, d * (1 - 0.1 * q), d * (1 + 0.1 * q), 0.9).mean()
    blunt = interval_score(z, d2 * (1 - 0.2 * q), d2 * (1 + 0.2 * q), 0.9).mean()
    assert sharp < blunt


# --- the strict reader -----------------------------------------------------------------


def _parse(text: str) -> list[str]:
    with pytest.raises(ValidationError) as e:
        parse_predictions(text.encode())
    return e.value.problems


def test_every_problem_is_named_located_at_once() -> None:
    text = (
        "split,set,index,depth,depth_lo,depth_hi,level,depth_std\n"
        "test,robot,0,1.5,1.0,2.0,0.9,0.1\n"
        "test,robot,1,1.5,,2.0,0.9,0.1\n"  # missing bound
        "test,robot,2,1.5,nan,2.0,0.9,0.1\n"  # non-finite
        "test,robot,3,1.5,-1,2.0,0.9,0.1\n"  # negative
        "test,robot,4,1.5,2.5,2.0,0.9,0.1\n"  # inverted
        "test,robot,5,1.5,1.0,2.0,1.5,0.1\n"  # level outside (0, 1)
        "test,robot,6,1.5,1.0,2.0,0.8,0.1\n"  # another level
        "test,robot,7,1.5,1.0,2.0,0.9,-0.2\n"  # negative std
        "test,robot,8,1.5,1.0,2.0,0.9,abc\n"  # not a number
        "test,robot,9,1.5,1.0,1e999,0.9,0.1\n"  # overflows
    )
    problems = "\n".join(_parse(text))
    for expected in (
        "depth_lo is missing (an empty cell) (1 row): line 3",
        "depth_lo is NaN or infinite (1 row): line 4",
        "depth_lo is negative (1 row): line 5 (-1.0)",
        "depth_lo is above depth_hi (an inverted interval) (1 row): line 6 (2.5 > 2.0)",
        "level is outside (0, 1)",
        "line 7 (1.5)",
        "level varies between rows: 0.9 (8 rows, first on line 2), 0.8 (1 row, first on line 8)",
        "depth_std is negative (1 row): line 9 (-0.2)",
        "depth_std is not a number (1 row): line 10",
        "depth_hi is NaN or infinite (1 row): line 11 (inf)",
    ):
        assert expected in problems


def test_incomplete_interval_columns_are_refused() -> None:
    problems = _parse("split,set,index,depth,depth_lo,depth_hi\ntest,robot,0,1.5,1,2\n")
    assert any("the header has depth_lo, depth_hi but not level" in p for p in problems)
    problems = _parse("split,set,index,depth,Depth_Std\ntest,robot,0,1.5,0.1\n")
    assert any("looks like the optional column 'depth_std' misspelt" in p for p in problems)


def test_clean_and_row_by_row_reading_agree() -> None:
    rng = np.random.default_rng(5)
    forms = ("{!r}", "{:.3e}", "{:.0f}", "{:.20f}", "{:.1f}", "{:.17g}")
    rows = "".join(
        f"test,robot,{i},{1 + i / 7!r},"
        + ",".join(forms[i % len(forms)].format(float(v)) for v in sorted(rng.lognormal(0, 4, 2)))
        + f",0.9,{forms[i % len(forms)].format(0.1 * i)}\n"
        for i in range(600)
    )
    head = "split,set,index,depth,depth_lo,depth_hi,level,depth_std\n"
    clean = parse_predictions((head + rows).encode())
    quoted = parse_predictions((head + rows.replace("test,", '"test",')).encode())  # row by row
    assert clean.level == quoted.level == 0.9
    for c in ("depth_lo", "depth_hi", "level", "depth_std"):
        np.testing.assert_array_equal(clean.uncertainty[c], quoted.uncertainty[c])  # bit for bit
    cells = [line.split(",") for line in rows.splitlines()]
    assert clean.uncertainty["depth_lo"].tolist() == [float(c[4]) for c in cells]  # Python's float
    assert clean.uncertainty["depth_std"].tolist() == [float(c[7]) for c in cells]
    assert clean.ignored_columns == ()


def test_interval_alone_or_spread_alone(sets_dir: Path, tmp_path: Path) -> None:
    truth = _truth(sets_dir)
    only_std = {s: {"depth_std": 0.1 * z} for s, z in truth.items()}
    path = tmp_path / "std.csv"
    write_predictions(path, "test", truth, BENCH, uncertainty=only_std)
    r = evaluate(path, data_dir=sets_dir)
    assert set(r.sets["robot"]) >= {"crps"} and "coverage" not in r.sets["robot"]
    assert r.all_uncertainty == {
        "crps_mean": pytest.approx(0.1 * (math.sqrt(2 / math.pi) - 1 / math.sqrt(math.pi)) * 100)
    }


# --- every output format ---------------------------------------------------------------


def test_scores_per_set_and_all_in_every_format(sets_dir: Path, tmp_path: Path) -> None:
    # Depths 10 % too deep, intervals d (1 -+ 0.2): Z = d / 1.1 lies inside (d * 0.8 <= d / 1.1),
    # so coverage 1, width 0.4 d / Z = 0.44 = 44 %, interval score 44 % too (no miss).
    r = evaluate(_file(tmp_path, sets_dir), data_dir=sets_dir)
    m = r.sets["camera"]
    assert m["coverage"] == {
        "level": 0.9,
        "observed": 1.0,
        "error": pytest.approx(0.1),
        "below": 0.0,
        "above": 0.0,
    }
    assert m["sharpness"]["mean"] == pytest.approx(44.0)
    assert m["interval_score"]["mean"] == pytest.approx(44.0)
    # CRPS of N(1.1 Z, (0.22 Z)^2) at Z: u = -0.1 / 0.22, in % of Z.
    u = -0.1 / 0.22
    crps = 0.22 * (u * (2 * stats.norm.cdf(u) - 1) + 2 * stats.norm.pdf(u) - 1 / math.sqrt(math.pi)) * 100
    assert m["crps"]["mean"] == pytest.approx(crps, rel=1e-9)
    assert r.all_uncertainty["crps_mean"] == pytest.approx(crps, rel=1e-9)
    assert r.all_uncertainty["coverage"] == 1.0
    js = json.loads(format_result(r, "json"))
    for s in SIZES:
        assert {"coverage", "interval_score", "crps", "sharpness"} <= set(js["sets"][s])
    assert js["all"]["interval_score_mean"] == pytest.approx(44.0)
    assert js["provenance"]["ignored_columns"] == []
    table = format_result(r, "table")
    assert "interval score %" in table and "camera      100.00   +10.00" in table
    md = format_result(r, "markdown")
    assert "| camera | 100.00 | +10.00 |" in md
    csv_text = format_result(r, "csv")
    head = csv_text.splitlines()[0].split(",")
    assert head[-6:] == [
        "level",
        "coverage",
        "coverage_error",
        "sharpness_mean",
        "interval_score_mean",
        "crps_mean",
    ]
    per = format_per_example(r).splitlines()
    assert per[0].endswith("depth_lo,depth_hi,depth_std,covered,interval_score,crps")
    assert per[1].split(",")[-3] == "1"


def test_the_point_scores_do_not_change_with_the_columns(sets_dir: Path, tmp_path: Path) -> None:
    with_cols = evaluate(_file(tmp_path, sets_dir), data_dir=sets_dir)
    plain = tmp_path / "plain.csv"
    write_predictions(plain, "test", {s: 1.1 * z for s, z in _truth(sets_dir).items()}, BENCH)
    without = evaluate(plain, data_dir=sets_dir)
    assert not without.uncertainty and not without.all_uncertainty
    for s in SIZES:
        assert with_cols.sets[s]["percent_error"] == without.sets[s]["percent_error"]
    table_without = format_result(without, "table").split("\n", 1)[1]  # (the first line names the file)
    assert format_result(with_cols, "table").split("\n", 1)[1].startswith(table_without.rstrip("\n"))
    assert "coverage" not in format_result(without, "json")


def test_cli_exit_status_2_and_compare_on_interval_score(sets_dir: Path, tmp_path: Path) -> None:
    bad = tmp_path / "bad.csv"
    text = format_predictions(
        "test", _truth(sets_dir), BENCH, {s: {"depth_std": -z} for s, z in _truth(sets_dir).items()}
    )
    bad.write_text(text)
    r = CliRunner().invoke(cli, ["evaluate", str(bad), "--data-dir", str(sets_dir)])
    assert r.exit_code == 2 and "depth_std is negative (22 rows)" in r.output
    assert "Traceback" not in r.output
    a = _file(tmp_path / "a", sets_dir, width=0.2) if (tmp_path / "a").mkdir() is None else None
    b = _file(tmp_path / "b", sets_dir, width=0.5) if (tmp_path / "b").mkdir() is None else None
    args = [
        "compare",
        str(a),
        str(b),
        "--data-dir",
        str(sets_dir),
        "--metric",
        "interval_score",
        "--format",
        "json",
    ]
    r = CliRunner().invoke(cli, args)
    assert r.exit_code == 0, r.output
    out = json.loads(r.stdout)
    assert out["metric"] == "interval_score_mean"
    assert out["all"]["mean_a"] == pytest.approx(44.0) and out["all"]["mean_b"] == pytest.approx(110.0)
    plain = tmp_path / "plain.csv"
    write_predictions(plain, "test", _truth(sets_dir), BENCH)
    r = CliRunner().invoke(
        cli, ["compare", str(a), str(plain), "--data-dir", str(sets_dir), "--metric", "interval_score"]
    )
    assert r.exit_code == 2 and "B has no interval" in r.output


# --- the calibration (split conformal) ---------------------------------------------------


def test_conformal_quantile_by_hand() -> None:
    # n = 9, level 0.8: the ceil(10 * 0.8) = 8th smallest.
    assert conformal_quantile(np.arange(1, 10) / 10, 0.8) == 0.8
    with pytest.raises(odmd_bench.UsageError, match="too few"):
        conformal_quantile([0.1, 0.2, 0.3], 0.9)  # ceil(4 * 0.9) = 4 > 3
    assert relative_residuals([10.0], [8.0], [0.5]).tolist() == [0.5]


def test_calibrated_intervals_cover_new_draws() -> None:
    """Fitted on one draw, the intervals cover about the level on another, spread or not."""
    rng = np.random.default_rng(3)

    def draw(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        s = rng.uniform(0.02, 0.3, n)  # each example's own relative uncertainty
        d = rng.uniform(1, 5, n)
        return d * np.exp(s * rng.standard_normal(n)), d, s

    z, d, s = draw(4000)
    for spread in ({"a": s}, None):
        cal = fit_calibration({"a": z}, {"a": d}, spread, 0.9, source="draw 1")
        z2, d2, s2 = draw(20_000)
        bars = cal.intervals(d2, s2 if spread else None, key="a")
        assert covered(z2, bars["depth_lo"], bars["depth_hi"]).mean() == pytest.approx(0.9, abs=0.015)
        widths = interval_width(z2, bars["depth_lo"], bars["depth_hi"]).mean()
        if spread:
            with_spread = widths
        else:
            assert with_spread < widths  # the method's own spread makes them sharper


def test_plot_reliability_diagram(sets_dir: Path, tmp_path: Path) -> None:
    pytest.importorskip("matplotlib")
    path = _file(tmp_path, sets_dir)
    png, numbers = tmp_path / "rel.png", tmp_path / "rel.csv"
    args = ["plot", str(path), "--set", "normal", "--reliability", "-o", str(png), "--csv", str(numbers)]
    r = CliRunner().invoke(cli, [*args, "--data-dir", str(sets_dir)])
    assert r.exit_code == 0, r.output
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    rows = [line.split(",") for line in numbers.read_text().splitlines()[1:]]
    z = _truth(sets_dir)["normal"]
    expected = reliability(z, 1.1 * z, 0.2 * 1.1 * z)
    assert [float(c) for _, kind, _, c in rows if kind == "normal"] == expected
    assert rows[-1][1:] == ["interval", "0.9", "1.0"]
    plain = tmp_path / "plain.csv"
    write_predictions(plain, "test", _truth(sets_dir), BENCH)
    r = CliRunner().invoke(
        cli,
        ["plot", str(plain), "--set", "normal", "--reliability", "-o", str(png), "--data-dir", str(sets_dir)],
    )
    assert r.exit_code == 2 and "a reliability diagram needs error bars" in r.output
