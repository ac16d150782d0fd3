"""The uncertainty board: entries with error bars ranked by interval score, others listed as such.

A small board (two point entries, two uncertainty entries made by hand) checks the rules;
the committed board's site page is checked in a real browser (chromium, as tests/test_site.py).
"""

from __future__ import annotations

import functools
import http.server
import json
import os
import shutil
import threading
from pathlib import Path

import numpy as np
import pytest
from conftest import add_entry, boards_data

from odmd_bench import leaderboard as lb
from odmd_bench import load_split
from odmd_bench.errors import ValidationError
from odmd_bench.evaluation.predictions import write_predictions
from odmd_bench.leaderboard.site.pages import uncertainty_body
from odmd_bench.leaderboard.uncertainty import UNCERTAINTY

FAST = 200
CHROMIUM = Path("/usr/bin/chromium")


def _uncertain(root: Path, main: Path, method: str, preds: Path) -> None:
    """An uncertainty entry ``method``: the main entry's metadata with other predictions."""
    folder = root / UNCERTAINTY / method / "odmd-v1-test"
    folder.mkdir(parents=True)
    shutil.copy(main / "entry.yaml", folder / "entry.yaml")
    text = (folder / "entry.yaml").read_text()
    name = [line for line in text.splitlines() if line.startswith("predictions:")][0].split(":", 1)[1].strip()
    shutil.copy(preds, folder / name)


@pytest.fixture(scope="module")
def board(v1_data_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, lb.Built]:
    tmp = tmp_path_factory.mktemp("unc-board")
    root = tmp / "leaderboard"
    (root / lb.ENTRIES).mkdir(parents=True)
    sets = load_split("test", "odmd-v1", v1_data_dir)
    rng = np.random.default_rng(0)
    depths = {s: ex.depth * np.exp(0.1 * rng.standard_normal(len(ex))) for s, ex in sets.items()}
    for method, d in (("honest", depths), ("other", {s: 1.2 * ex.depth for s, ex in sets.items()})):
        preds = tmp / f"{method}.csv"
        write_predictions(preds, "test", d, benchmark="odmd-v1")
        add_entry(root, v1_data_dir, preds, method)
    # "honest": intervals at the true quantiles of its (log-normal) error; "wide": three times wider.
    for method, k in (("honest", 1.0), ("wide", 3.0)):
        half = np.exp(k * 1.6448536269514722 * 0.1)
        unc = {
            s: {"depth_lo": d / half, "depth_hi": d * half, "depth_std": k * 0.1 * d}
            for s, d in depths.items()
        }
        preds = tmp / f"{method}-unc.csv"
        write_predictions(preds, "test", depths, benchmark="odmd-v1", uncertainty=unc, level=0.9)
        main = root / lb.ENTRIES / "honest" / "odmd-v1-test"
        _uncertain(root, main, method, preds)
        entry = root / UNCERTAINTY / method / "odmd-v1-test" / "entry.yaml"
        entry.write_text(entry.read_text().replace("method: honest", f"method: {method}"))
    return root, lb.build(root, v1_data_dir, n_resamples=FAST)


def test_ranked_by_interval_score_and_the_others_listed(board: tuple[Path, lb.Built]) -> None:
    _, built = board
    (ub,) = built.uncertainty
    assert [r.entry.method for r in ub.rows] == ["honest", "wide"]  # the wide intervals lose
    honest, wide = (r.result for r in ub.rows)
    assert honest.all_uncertainty["interval_score_mean"] < wide.all_uncertainty["interval_score_mean"]
    assert honest.all_uncertainty["crps_mean"] < wide.all_uncertainty["crps_mean"]
    assert [r.ranked.group for r in ub.rows] == [1, 2]
    for m in honest.sets.values():
        assert 0.85 <= m["coverage"]["observed"] <= 0.95
    assert all(m["coverage"]["observed"] > 0.99 for m in wide.sets.values())  # over-covers: wider than needed
    assert ub.rows[0].point_of == "HONEST" and ub.without == ("OTHER",)
    md = built.markdown
    assert "## Uncertainty" in md and "Without error bars (not ranked here): OTHER." in md
    js = json.loads(built.json_text)["uncertainty"][0]
    assert [r["method"] for r in js["rows"]] == ["honest", "wide"]
    assert set(js["rows"][0]["sets"]["robot"]) == {"coverage", "sharpness", "interval_score", "crps"}
    assert js["without_uncertainty"] == ["OTHER"]


def test_an_uncertainty_entry_without_an_interval_is_refused(
    board: tuple[Path, lb.Built], v1_data_dir: Path, tmp_path: Path
) -> None:
    root, _ = board
    copy = tmp_path / "leaderboard"
    shutil.copytree(root, copy)
    sets = load_split("test", "odmd-v1", v1_data_dir)
    plain = tmp_path / "plain.csv"
    write_predictions(plain, "test", {s: ex.depth for s, ex in sets.items()}, benchmark="odmd-v1")
    folder = copy / UNCERTAINTY / "wide" / "odmd-v1-test"
    (folder / "predictions.csv.gz").unlink(missing_ok=True)
    for p in folder.glob("predictions*"):
        p.unlink()
    shutil.copy(plain, folder / "predictions.csv")
    entry = folder / "entry.yaml"
    entry.write_text(
        "\n".join(
            "predictions: predictions.csv" if line.startswith("predictions:") else line
            for line in entry.read_text().splitlines()
        )
        + "\n"
    )
    with pytest.raises(ValidationError) as e:
        lb.build(copy, v1_data_dir, n_resamples=FAST)
    assert any(
        "uncertainty/wide/odmd-v1-test: the predictions have no interval" in p for p in e.value.problems
    )


def test_the_committed_uncertainty_page_in_a_browser(
    tmp_path: Path, v1_data_dir: Path, paper_data_dir: Path
) -> None:
    # the views are not committed: built from the committed entries, as the site is (from the
    # run's imported and generated sets, linked: the shared folders are not written to)
    root = Path(__file__).resolve().parents[1] / "leaderboard"
    sets = boards_data(tmp_path / "data", paper_data_dir, v1_data_dir)
    data = json.loads(lb.build(root, sets, n_resamples=FAST).json_text)
    boards = data.get("uncertainty")
    if not boards:
        pytest.fail("the committed entries make no uncertainty board", pytrace=False)
    (tmp_path / "uncertainty.html").write_text(
        f"<!doctype html><html><body>{uncertainty_body(boards)}</body></html>"
    )
    problems = [] if CHROMIUM.is_file() else [f"{CHROMIUM} is missing"]
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        problems.append("playwright is not installed")
    if problems:
        message = f"the browser test needs chromium and playwright: {'; '.join(problems)}"
        if os.environ.get("CI"):
            pytest.fail(message, pytrace=False)
        pytest.skip(message)

    class Quiet(http.server.SimpleHTTPRequestHandler):
        def log_message(self, format: str, *args: object) -> None:  # noqa: A002
            pass

    server = http.server.ThreadingHTTPServer(
        ("127.0.0.1", 0), functools.partial(Quiet, directory=str(tmp_path))
    )
    threading.Thread(target=server.serve_forever, daemon=True).start()
    try:
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=str(CHROMIUM), headless=True, args=["--no-sandbox"])
            page = browser.new_page()
            page.goto(f"http://127.0.0.1:{server.server_address[1]}/uncertainty.html")
            rows = page.locator("tbody tr")
            assert rows.count() == len(boards[0]["rows"])
            first = rows.nth(0).locator("td")
            assert first.nth(1).inner_text() == boards[0]["rows"][0]["name"]
            shown_all = float(first.nth(3 + len(boards[0]["rows"][0]["sets"]) + 1).inner_text())
            assert shown_all == round(boards[0]["rows"][0]["all"]["interval_score_mean"], 2)
            assert "Without error bars" in page.content()
            browser.close()
    finally:
        server.shutdown()
        server.server_close()
