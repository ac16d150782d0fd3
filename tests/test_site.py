"""The leaderboard's web site, parsed and in a real browser.

Parsed: its numbers are leaderboard.json's, its links resolve, nothing is loaded from
elsewhere, two builds are identical. In a real browser (Debian's chromium driven by
playwright): a view given by the URL shows the right rows in the right order.

The committed board's site is built once per module without figures and with fewer
resamples for the paired comparisons (the figures and the determinism are checked on a
small board). The browser tests skip outside CI when chromium or playwright is missing
(saying how to install them) and fail in CI.
"""

from __future__ import annotations

import functools
import hashlib
import http.server
import json
import os
import re
import shutil
import subprocess
import sys
import threading
from collections.abc import Iterator
from html.parser import HTMLParser
from pathlib import Path
from typing import Any
from urllib.parse import parse_qs, urlsplit

import pytest
import yaml
from click.testing import CliRunner
from conftest import boards_data, two_entry_board

from odmd_bench import leaderboard as lb
from odmd_bench.cli.main import cli
from odmd_bench.errors import UsageError, ValidationError
from odmd_bench.leaderboard.site import build_site, facets, write_site
from odmd_bench.leaderboard.site.figures import SpeedPoint, pareto

REPO = Path(__file__).resolve().parents[1]
FAST = 200
CHROMIUM = Path("/usr/bin/chromium")
INSTALL = "apt-get install -y chromium (Debian's), and playwright's Python package (pip install -e '.[dev]')"


@pytest.fixture(scope="module", autouse=True)
def _set_files_once(croissant_set_files_made_once: None) -> None:
    """Each set's Croissant JSON file made once in the run (tests/conftest.py)."""


# ----------------------------------------------------------------------------- parsing


class Page(HTMLParser):
    """Links, sources, ids, numbers with data-json, tables and rows of one page."""

    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.links: list[tuple[str, str, str]] = []  # (tag, attribute, value)
        self.ids: set[str] = set()
        self.numbers: list[tuple[str, str, str | None, str]] = []  # (json path, decimals, text?, text)
        self.tables: dict[str, list[str]] = {}
        self._open: list[dict[str, Any]] = []
        self._table: str | None = None

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        a = {k: v or "" for k, v in attrs}
        for attr in ("href", "src"):
            if attr in a:
                self.links.append((tag, attr, a[attr]))
        if "id" in a:
            self.ids.add(a["id"])
        if tag == "table" and "data-board" in a:
            self._table = a["data-board"]
            self.tables[self._table] = []
        if tag == "tr" and self._table is not None and "data-method" in a:
            self.tables[self._table].append(a["data-method"])
        if "data-json" in a:
            self._open.append({"tag": tag, "a": a, "text": ""})
        elif self._open and tag not in ("br",):
            self._open[-1].setdefault("depth", 0)
            self._open[-1]["depth"] = self._open[-1]["depth"] + 1

    def handle_endtag(self, tag: str) -> None:
        if tag == "table":
            self._table = None
        if not self._open:
            return
        top = self._open[-1]
        if top.get("depth"):
            top["depth"] -= 1
            return
        if tag == top["tag"]:
            self._open.pop()
            a = top["a"]
            self.numbers.append((a["data-json"], a.get("data-decimals", ""), a.get("data-text"), top["text"]))

    def handle_data(self, data: str) -> None:
        if self._open:
            self._open[-1]["text"] += data


def parse(path: Path) -> Page:
    page = Page()
    page.feed(path.read_text(encoding="utf-8"))
    return page


def _row(data: dict[str, Any], board_id: str, method: str) -> dict[str, Any]:
    board = next(b for b in data["boards"] if f"{b['benchmark']}-{b['split']}" == board_id)
    return next(r for r in board["rows"] if r["method"] == method)


def _resolve(data: dict[str, Any], path: str) -> Any:
    """A value of leaderboard.json by a site's data-json path."""
    parts = path.split("/")
    node: Any = data["reported"][int(parts[1])] if parts[0] == "reported" else _row(data, parts[0], parts[1])
    for k in parts[2:]:
        node = node[k]
    return node


def _views(data: dict[str, Any]) -> dict[str, list[str]]:
    """Each board's method order in leaderboard.json."""
    return {
        f"{b['benchmark']}-{b['split']}": [r["method"] for r in b["rows"]]
        for b in data["boards"]
        if b["rows"]
    }


def _sorted(data: dict[str, Any], board: str, key: str, order: str) -> list[str]:
    """The order a view sorted by ``key`` must show: by the JSON's means, ties in board order."""
    rows = next(b["rows"] for b in data["boards"] if f"{b['benchmark']}-{b['split']}" == board)
    value = (lambda r: r["all"]) if key == "all" else (lambda r: r["sets"][key]["percent_error"]["mean"])
    sign = -1 if order == "desc" else 1
    return [r["method"] for r in sorted(rows, key=lambda r: (sign * value(r), r["position"]))]


# ----------------------------------------------------------------------------- the committed board


@pytest.fixture(scope="module")
def committed_data_dir(
    paper_data_dir: Path, v1_data_dir: Path, tmp_path_factory: pytest.TempPathFactory
) -> Path:
    return boards_data(tmp_path_factory.mktemp("site-data"), paper_data_dir, v1_data_dir)


@pytest.fixture(scope="module")
def site(committed_data_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The committed board's site (no figures: they are checked on the small board)."""
    files, _ = build_site(REPO / "leaderboard", committed_data_dir, figures=False, n_resamples=FAST)
    out = tmp_path_factory.mktemp("site") / "site"
    write_site(files, out)
    return out


@pytest.fixture(scope="module")
def board_json(site: Path) -> dict[str, Any]:
    """The board the site was built from (the views are not committed: the site builds it)."""
    return json.loads((site / "downloads" / lb.JSON_FILE).read_text(encoding="utf-8"))


def _pages(site: Path) -> list[Path]:
    return sorted(site.rglob("*.html"))


def test_every_number_on_every_page_is_leaderboard_json_to_its_printed_digits(
    site: Path, board_json: dict[str, Any]
) -> None:
    counted = 0
    for path in _pages(site):
        for src, decimals, as_text, text in parse(path).numbers:
            value = _resolve(board_json, src)
            if as_text:
                assert text == str(value), (path.name, src)
            elif isinstance(value, dict):  # a comparison the JSON holds: its difference, as the row minus A
                assert f"{-value['difference_a_minus_b']:+.2f}" in text.replace("-0.00", "+0.00"), (
                    path.name,
                    src,
                )
            else:
                shown = float(text.replace(",", ""))
                assert shown == round(float(value), int(decimals)), (path.name, src, text, value)
                assert len(text.partition(".")[2]) == int(decimals), (path.name, src, text)
            counted += 1
    # Not vacuous: the index alone prints group, every set and All of every row.
    rows = sum(len(b["rows"]) for b in board_json["boards"])
    expected = {
        f"{b['benchmark']}-{b['split']}/{r['method']}/{path}"
        for b in board_json["boards"]
        for r in b["rows"]
        for path in ("group", "all", *(f"sets/{s}/percent_error/mean" for s in b["sets"]))
    }
    assert expected <= {n[0] for n in parse(site / "index.html").numbers} and rows > 20
    assert counted > 10 * rows


def test_the_index_holds_each_board_in_board_order_and_links_every_entry(
    site: Path, board_json: dict[str, Any]
) -> None:
    page = parse(site / "index.html")
    assert page.tables == _views(board_json)
    assert set(page.tables) == {
        "odmd-paper-test",
        "odmd-v1-test",
        "odms-detection-test",
        "kitti-tracking-test",
    }
    links = {v for tag, attr, v in page.links if tag == "a"}
    for board, methods in page.tables.items():
        for m in methods:
            assert f"methods/{m}.html#{board}" in links
            assert board in parse(site / "methods" / f"{m}.html").ids
    assert {"downloads/leaderboard.json", *(f"downloads/{b}.csv" for b in page.tables)} <= links
    assert "reported.html" in links


def test_every_link_resolves_to_a_file_of_the_site_and_nothing_is_loaded_from_elsewhere(site: Path) -> None:
    checked = 0
    for path in _pages(site):
        for tag, attr, value in parse(path).links:
            parts = urlsplit(value)
            if value.startswith("data:"):
                assert tag == "link" and value == "data:,"  # the empty icon: no favicon request
                continue
            if parts.scheme or value.startswith("//"):
                assert tag == "a" and attr == "href", f"{path.name} loads {value} from elsewhere"
                assert parts.scheme in ("http", "https")
                continue
            target = (path.parent / parts.path).resolve() if parts.path else path
            assert target.is_file() and target.is_relative_to(site.resolve()), f"{path.name}: {value}"
            if parts.fragment and target.suffix == ".html":
                assert parts.fragment in parse(target).ids, f"{path.name}: {value}"
            checked += 1
    assert checked > 200
    css = (site / "assets" / "site.css").read_text()
    js = (site / "assets" / "site.js").read_text()
    assert "url(" not in css and "@import" not in css
    assert not re.search(r"fetch\(|XMLHttpRequest|https?://|import\(", js)


def test_the_downloads_are_the_board(site: Path, board_json: dict[str, Any]) -> None:
    # The board is built from the entries: every row's numbers are the scores its entry records.
    rows = 0
    for board in board_json["boards"]:
        for row in board["rows"]:
            entry = yaml.safe_load((REPO / "leaderboard" / row["entry"] / "entry.yaml").read_text())
            shown = {s: m["percent_error"]["mean"] for s, m in row["sets"].items()} | {"all": row["all"]}
            assert shown == entry["scores"] and row["predictions_csv_sha256"] == entry["predictions_sha256"]
            rows += 1
    assert rows == len(list((REPO / "leaderboard" / lb.ENTRIES).glob("*/*/entry.yaml")))
    import csv

    for board in board_json["boards"]:
        bid = f"{board['benchmark']}-{board['split']}"
        with open(site / "downloads" / f"{bid}.csv", newline="") as fh:
            rows = list(csv.DictReader(fh))
        assert [r["method"] for r in rows] == [r["method"] for r in board["rows"]]
        for line, row in zip(rows, board["rows"], strict=True):
            assert float(line["all"]) == row["all"] and int(line["group"]) == row["group"]
            for s in board["sets"]:
                assert float(line[s]) == row["sets"][s]["percent_error"]["mean"]


def test_each_method_page_offers_its_predictions_with_their_sha256_and_its_command(
    site: Path, board_json: dict[str, Any]
) -> None:
    for board in board_json["boards"]:
        bid = f"{board['benchmark']}-{board['split']}"
        for row in board["rows"]:
            page = site / "methods" / f"{row['method']}.html"
            text = page.read_text()
            pred = site / "predictions" / row["method"] / bid / row["predictions_file"]
            assert (
                pred.read_bytes()
                == (REPO / "leaderboard" / row["entry"] / row["predictions_file"]).read_bytes()
            )
            assert hashlib.sha256(pred.read_bytes()).hexdigest() in text
            assert row["predictions_csv_sha256"] in text
            assert all(h in text for h in row["metadata"]["sets_content_sha256"].values())
            import html

            assert html.escape(row["metadata"]["command"], quote=True) in text
            assert "Box_LS" in text or row["method"] == "box-ls"
            assert "No figure: this site was built without the [plot] extra" in text


def test_the_reported_page_is_labelled_and_holds_every_result(site: Path, board_json: dict[str, Any]) -> None:
    text = (site / "reported.html").read_text()
    assert "These numbers are copied from publications, not computed here" in text
    sources = parse(site / "reported.html").numbers
    assert len([s for s in sources if s[0].startswith("reported/")]) == sum(
        len(r["sets"]) + 1 for r in board_json["reported"]
    )


def test_the_index_is_small(site: Path) -> None:
    assert (site / "index.html").stat().st_size <= 300_000


# ----------------------------------------------------------------------------- a small board


@pytest.fixture(scope="module")
def small_board(v1_data_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A built board of two odmd-v1 entries, one with a speed (so that the speed figure is drawn)."""
    import yaml

    root = two_entry_board(tmp_path_factory.mktemp("small"), v1_data_dir)
    entry = root / lb.ENTRIES / "box-ls" / "odmd-v1-test" / "entry.yaml"
    meta = yaml.safe_load(entry.read_text())
    meta["parameters"] = 0
    meta["speed"] = {
        "examples_per_second": 1.5e6,
        "device": "a test CPU",
        "command": "pytest benchmarks/x.py",
    }
    entry.write_text(yaml.safe_dump(meta, sort_keys=False))
    lb.write(root, lb.build(root, v1_data_dir, n_resamples=FAST), plot=False)
    return root


def test_two_builds_with_figures_are_identical(small_board: Path, v1_data_dir: Path) -> None:
    pytest.importorskip("matplotlib")
    first, said = build_site(small_board, v1_data_dir, n_resamples=FAST)
    second, _ = build_site(small_board, v1_data_dir, n_resamples=FAST)
    assert said == [] and first == second
    figures = sorted(k for k in first if k.startswith("figures/"))
    assert figures == [
        "figures/box-ls--odmd-v1-test.png",
        "figures/expansion--odmd-v1-test.png",
        "figures/speed.svg",
    ]
    assert all(first[f].startswith(b"\x89PNG") for f in figures[:2])
    assert first["figures/speed.svg"].startswith(b"<?xml") and b"<text" in first["figures/speed.svg"]
    assert 'src="figures/speed.svg"' in first["index.html"].decode()
    page = first["methods/expansion.html"].decode()
    assert 'src="../figures/expansion--odmd-v1-test.png"' in page and "No figure" not in page
    assert "1 entries record their speed; 1 do not" in first["index.html"].decode()


def test_the_comparisons_are_compares(small_board: Path, v1_data_dir: Path) -> None:
    """Expansion against Box_LS (the best and the reference): the verdict and interval of compare_errors."""
    from odmd_bench.evaluation.compare import compare_errors
    from odmd_bench.leaderboard.render import format_difference
    from odmd_bench.leaderboard.site import load_site_data

    site = load_site_data(small_board, v1_data_dir, n_resamples=FAST)
    (board,) = [b for b in site.boards if b.rows]
    best, other = board.rows
    (vs,) = other.versus
    c = compare_errors(best.result.percent_errors(), other.result.percent_errors(), n_resamples=FAST).all
    assert (vs.method, vs.verdict) == (best.method, c.verdict)
    assert format_difference(vs.difference, vs.ci_low, vs.ci_high) == format_difference(
        c.difference, c.ci_low, c.ci_high
    )
    assert best.versus == []


def test_a_board_that_differs_from_its_entries_builds_no_site(
    small_board: Path, v1_data_dir: Path, tmp_path: Path
) -> None:
    root = tmp_path / "leaderboard"
    shutil.copytree(small_board, root)
    path = root / lb.ENTRIES / "box-ls" / "odmd-v1-test" / "entry.yaml"
    meta = yaml.safe_load(path.read_text())
    meta["scores"]["camera"] += 0.01
    path.write_text(yaml.safe_dump(meta, sort_keys=False))
    with pytest.raises(ValidationError) as e:
        build_site(root, v1_data_dir, figures=False, n_resamples=FAST)
    assert "leaderboard check fails" in e.value.message
    assert "entries/box-ls/odmd-v1-test/entry.yaml: scores.camera: recorded" in "\n".join(e.value.problems)


def test_cli_site_writes_replaces_and_refuses_a_folder_of_other_files(
    small_board: Path, v1_data_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from odmd_bench.leaderboard import ranking

    monkeypatch.setattr(ranking, "RANK_RESAMPLES", FAST)
    out = tmp_path / "site"
    args = [
        "leaderboard",
        "site",
        "-o",
        str(out),
        "--root",
        str(small_board),
        "--data-dir",
        str(v1_data_dir),
        "--no-plot",
    ]
    first = CliRunner().invoke(cli, args)
    assert first.exit_code == 0, first.output
    assert f"wrote {out}:" in first.output and (out / "methods" / "expansion.html").is_file()
    (out / "notes.html").write_text("the user's")  # kept: the site removes only what it wrote
    again = CliRunner().invoke(cli, args)
    assert again.exit_code == 0 and (out / "notes.html").read_text() == "the user's"
    assert "kept 1 file(s)" in again.output
    other = tmp_path / "other"
    other.mkdir()
    (other / "notes.txt").write_text("mine")
    refused = CliRunner().invoke(cli, [*args[:3], str(other), *args[4:]])
    assert refused.exit_code == 2 and "holds no site written by odmd-bench" in refused.output
    assert (other / "notes.txt").read_text() == "mine"
    with pytest.raises(UsageError, match="is a file"):
        write_site({}, other / "notes.txt")


def test_cli_site_refuses_a_folder_of_other_files_before_it_scores(small_board: Path, tmp_path: Path) -> None:
    other, data = tmp_path / "other", tmp_path / "data"
    other.mkdir()
    data.mkdir()
    (other / "notes.txt").write_text("mine")
    args = ["leaderboard", "site", "-o", str(other), "--root", str(small_board), "--data-dir", str(data)]
    refused = CliRunner().invoke(cli, args)
    assert refused.exit_code == 2 and "holds no site written by odmd-bench" in refused.output
    assert not any(data.iterdir())  # nothing was generated to score the board: refused first
    assert [p.name for p in other.iterdir()] == ["notes.txt"]


def test_an_extra_field_of_the_board_is_a_column_and_a_line_of_the_method_page(
    small_board: Path, v1_data_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """EXTRA_COLUMNS is where a new per-board field (an audit's result) is shown."""
    from odmd_bench.leaderboard.site import ExtraColumn, load_site_data, pages, render_site

    site = load_site_data(small_board, v1_data_dir, n_resamples=FAST)
    plain = render_site(site, figures=False)
    monkeypatch.setattr(
        pages, "EXTRA_COLUMNS", (ExtraColumn("rows", "Rows scored", ("predictions_rows",), 0),)
    )
    files = render_site(site, figures=False)
    index, page = files["index.html"].decode(), files["methods/box-ls.html"].decode()
    assert (
        '<th data-key="rows" data-type="num"' in index
        and 'data-key="rows"' not in plain["index.html"].decode()
    )
    assert 'data-json="odmd-v1-test/box-ls/predictions_rows" data-decimals="0">12000<' in index
    assert "<dt>Rows scored</dt>" in page and "Rows scored" not in plain["methods/box-ls.html"].decode()


def test_facets_are_what_the_entry_declares() -> None:
    base = {"calibrated": False, "training_data": "none (said in words)", "selected_on": "val"}
    for kind in ("none", "generator", "real", "other"):
        assert facets({**base, "training_kind": kind})["training"] == kind
    assert facets({**base, "training_kind": "real", "selected_on": "nothing"})["selected_on"] == "nothing"
    # per-set selection is an option the entry records, not a guess from its text
    per_set = {**base, "training_kind": "x", "options": {"config": "p-z", "selection": "per-set"}}
    assert facets(per_set)["selection"] == "per-set"
    words = {**base, "training_kind": "x", "command": "odmd-bench baseline dbox --selection per-set"}
    assert facets(words)["selection"] == "overall"


def test_the_method_page_shows_the_honesty_fields_and_how_to_get_a_plugin(site: Path) -> None:
    page = (site / "methods" / "dbox-p-z-per-set.html").read_text()
    assert "<dt>Selected on</dt><dd>val</dd>" in page and "<dt>Test labels used</dt><dd>no</dd>" in page
    assert "(kind: generator)" in page
    from odmd_bench.leaderboard.site.pages import reproduce

    meta = {"command": "odmd-bench baseline mine -o p.csv", "plugin": {"requirement": "mine==1.2"}}
    assert (
        reproduce(meta, "entries/mine/odmd-v1-test")
        == "pip install mine==1.2\nodmd-bench baseline mine -o p.csv"
    )
    meta["plugin"] = {"source": "plugin", "module": "mine.depth"}
    assert reproduce(meta, "entries/mine/odmd-v1-test").splitlines()[0] == (
        "# the plug-in's source: leaderboard/entries/mine/odmd-v1-test/plugin/ (module mine.depth)"
    )


def test_pareto_front() -> None:
    pts = [
        SpeedPoint("b", n, v, a)
        for n, v, a in [("slow-good", 10, 3), ("fast-bad", 1000, 20), ("dominated", 5, 9), ("mid", 100, 10)]
    ]
    assert [p.name for p in pareto(pts)] == ["fast-bad", "mid", "slow-good"]


# ----------------------------------------------------------------------------- in a real browser


@pytest.fixture(scope="module")
def browser(site: Path, tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Any, str]]:
    """(a page of headless chromium, the site's address on 127.0.0.1), one browser per module."""
    problems = []
    if not CHROMIUM.is_file():
        problems.append(f"{CHROMIUM} is missing")
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        problems.append("playwright is not installed")
    if problems:
        message = f"the browser tests need chromium and playwright ({'; '.join(problems)}): {INSTALL}"
        if os.environ.get("CI"):
            pytest.fail(message + "; CI must have them", pytrace=False)
        pytest.skip(message)

    class Quiet(http.server.SimpleHTTPRequestHandler):
        def log_message(self, format: str, *args: Any) -> None:  # noqa: A002
            pass

    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), functools.partial(Quiet, directory=str(site)))
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    base = f"http://127.0.0.1:{server.server_address[1]}/"
    profile = tmp_path_factory.mktemp("chromium-profile")
    with sync_playwright() as p:
        context = p.chromium.launch_persistent_context(
            str(profile),
            executable_path=str(CHROMIUM),
            headless=True,
            args=["--no-sandbox", "--disable-gpu", "--disable-background-networking"],
            viewport={"width": 1280, "height": 900},
        )
        page = context.new_page()
        outside: list[str] = []
        page.on("request", lambda r: None if r.url.startswith((base, "data:")) else outside.append(r.url))
        page.on("pageerror", lambda e: outside.append(f"script error: {e}"))
        try:
            yield page, base
        finally:
            context.close()
            server.shutdown()
            server.server_close()
    assert outside == []


def _shown(page: Any, board: str) -> list[str]:
    return list(
        page.eval_on_selector_all(
            f'table[data-board="{board}"] tbody tr',
            "rows => rows.filter(r => !r.hidden).map(r => r.dataset.method)",
        )
    )


def test_browser_a_view_given_by_the_url_shows_its_rows_in_order(
    browser: tuple[Any, str], board_json: dict[str, Any]
) -> None:
    page, base = browser
    for board in board_json["boards"]:
        bid = f"{board['benchmark']}-{board['split']}"
        for key in (*board["sets"], "all"):
            for order in ("asc", "desc") if key == "all" else ("asc",):
                # the script runs at the end of the body: the view is applied by DOMContentLoaded
                page.goto(
                    f"{base}index.html?board={bid}&sort={key}&order={order}", wait_until="domcontentloaded"
                )
                assert _shown(page, bid) == _sorted(board_json, bid, key, order), (bid, key, order)
                hidden = page.eval_on_selector_all(
                    "section[data-board-section]", "s => s.filter(x => x.hidden).map(x => x.id)"
                )
                assert sorted(hidden) == sorted(b for b in _views(board_json) if b != bid)


def test_browser_a_filtered_view_shows_only_its_rows(
    browser: tuple[Any, str], board_json: dict[str, Any]
) -> None:
    page, base = browser
    page.goto(f"{base}index.html?training=generator&selected_on=val&selection=overall&sort=method&order=asc")
    for board in board_json["boards"]:
        bid = f"{board['benchmark']}-{board['split']}"
        keep = [
            r
            for r in board["rows"]
            if facets(r["metadata"]) | {}
            and facets(r["metadata"])["training"] == "generator"
            and facets(r["metadata"])["selected_on"] == "val"
            and facets(r["metadata"])["selection"] == "overall"
        ]
        expected = [r["method"] for r in sorted(keep, key=lambda r: (r["name"].lower(), r["position"]))]
        assert _shown(page, bid) == expected and expected
    shown = page.text_content("#shown")
    total = sum(len(b["rows"]) for b in board_json["boards"])
    assert shown is not None and shown.endswith(f"of {total} rows shown")


def test_browser_clicking_a_header_sorts_and_updates_the_url(
    browser: tuple[Any, str], board_json: dict[str, Any]
) -> None:
    page, base = browser
    page.goto(f"{base}index.html?board=odmd-v1-test&calibrated=no")
    button = 'table[data-board="odmd-v1-test"] th[data-key="camera"] button'
    page.click(button)
    assert parse_qs(urlsplit(page.url).query) == {
        "board": ["odmd-v1-test"],
        "sort": ["camera"],
        "order": ["asc"],
        "calibrated": ["no"],
    }
    no = [
        m
        for m in _sorted(board_json, "odmd-v1-test", "camera", "asc")
        if not _row(board_json, "odmd-v1-test", m)["metadata"]["calibrated"]
    ]
    assert _shown(page, "odmd-v1-test") == no
    page.click(button)
    assert "order=desc" in page.url
    assert _shown(page, "odmd-v1-test") == [
        m for m in _sorted(board_json, "odmd-v1-test", "camera", "desc") if m in no
    ]
    # The view survives a reload: it lives in the URL.
    page.reload()
    assert _shown(page, "odmd-v1-test") == [
        m for m in _sorted(board_json, "odmd-v1-test", "camera", "desc") if m in no
    ]


def test_browser_writes_a_screenshot_of_the_index(
    browser: tuple[Any, str], tmp_path_factory: pytest.TempPathFactory
) -> None:
    """The README's view, for review: ODMD_SITE_SCREENSHOT=docs/leaderboard-site.png keeps it there."""
    page, base = browser
    page.goto(f"{base}index.html?board=odmd-paper-test&sort=robot&order=asc")
    shot = Path(os.environ.get("ODMD_SITE_SCREENSHOT") or tmp_path_factory.mktemp("screenshot") / "index.png")
    page.screenshot(path=str(shot))
    assert shot.read_bytes().startswith(b"\x89PNG") and 10_000 < shot.stat().st_size < 300_000


# ----------------------------------------------------------------------------- layout, in a real browser

#: The widths the site is checked at: a laptop and a phone (390 px: an iPhone 12 to 15).
WIDTHS = (1280, 390)

_BOX = "e => { const r = e.getBoundingClientRect(); return [r.left, r.top, r.right, r.bottom]; }"


@pytest.mark.parametrize("width", WIDTHS)
def test_browser_no_page_is_wider_than_the_window(browser: tuple[Any, str], site: Path, width: int) -> None:
    """Every page, at both widths: nothing (a hash, a command, a table) widens the page itself.

    Wide tables scroll inside their own box (``.scroll``); the page does not.
    """
    page, base = browser
    page.set_viewport_size({"width": width, "height": 900})
    try:
        wide = {}
        for path in _pages(site):
            page.goto(base + path.relative_to(site).as_posix())
            inner, scroll = page.evaluate("[window.innerWidth, document.documentElement.scrollWidth]")
            if scroll > inner:
                wide[path.relative_to(site).as_posix()] = scroll
        assert wide == {}, f"pages wider than the window ({width} px): {wide}"
    finally:
        page.set_viewport_size({"width": 1280, "height": 900})


@pytest.mark.parametrize("width", WIDTHS)
def test_browser_method_and_all_stay_in_view_on_every_board(
    browser: tuple[Any, str], site: Path, width: int
) -> None:
    """Each board's Method and All cells are on screen and on top, the table scrolled to either end."""
    page, base = browser
    page.set_viewport_size({"width": width, "height": 900})
    try:
        page.goto(base + "index.html")
        boards = page.eval_on_selector_all("table[data-board]", "ts => ts.map(t => t.dataset.board)")
        assert boards
        for board in boards:
            table = f'table[data-board="{board}"]'
            for end in ("left", "right"):
                page.eval_on_selector(
                    table,
                    "(t, end) => { const s = t.parentElement; s.scrollLeft = end === 'left' ? 0 : s.scrollWidth;"
                    " window.scrollTo(0, t.getBoundingClientRect().top + window.scrollY - 100); }",
                    end,
                )
                for cell in (
                    'th[data-key="method"]',
                    'th[data-key="all"]',
                    "tbody tr:first-child td.all",
                    'tbody tr:first-child td[data-k="method"]',
                ):
                    box = page.eval_on_selector(f"{table} {cell}", _BOX)
                    left, top, right, bottom = box
                    assert left >= 0 and right <= width, (board, end, cell, box)
                    # on top: what the browser finds at the cell's middle is the cell (or inside it)
                    on_top = page.eval_on_selector(
                        f"{table} {cell}",
                        "e => { const r = e.getBoundingClientRect();"
                        " const x = document.elementFromPoint((r.left + r.right) / 2, (r.top + r.bottom) / 2);"
                        " return x === e || e.contains(x); }",
                    )
                    assert on_top, (board, end, cell)
    finally:
        page.set_viewport_size({"width": 1280, "height": 900})


def test_browser_an_address_the_page_cannot_show_is_said_on_the_page(
    browser: tuple[Any, str], board_json: dict[str, Any]
) -> None:
    page, base = browser
    page.goto(f"{base}index.html?board=odmd-v1-tset&sort=robto&order=up&training=alien&colour=red")
    box = page.locator("#view-problems")
    assert box.is_visible()
    text = box.text_content() or ""
    assert text.startswith("The address asks for a view this page cannot show:")
    assert "board=odmd-v1-tset is not a board of this site (odmd-paper-test, " in text
    assert "sort=robto is not a column (group, method, " in text
    assert "order=up is neither asc nor desc" in text
    assert "training=alien is not one of none, " in text
    assert "colour is not a setting of the view" in text
    # what is shown instead is said too: every board, the board order
    assert (
        page.eval_on_selector_all("section[data-board-section]", "s => s.filter(x => x.hidden).length") == 0
    )
    # a view chosen on the page is one it can show: the message goes
    page.select_option("#controls select[name=board]", "odmd-v1-test")
    assert not box.is_visible()
    for good in ("", "?board=odmd-v1-test&sort=all&order=desc&training=generator"):
        page.goto(f"{base}index.html{good}")
        assert not page.locator("#view-problems").is_visible()


def _speed_points(site: Path) -> tuple[list[SpeedPoint], list[str]]:
    """The built board's entries that record a speed, and its boards."""
    data = json.loads((site / "downloads" / "leaderboard.json").read_text(encoding="utf-8"))
    points, boards = [], []
    for b in data["boards"]:
        bid = f"{b['benchmark']}-{b['split']}"
        boards.append(bid)
        for r in b["rows"]:
            speed = r["metadata"].get("speed")
            if speed:
                points.append(SpeedPoint(bid, r["name"], float(speed["examples_per_second"]), r["all"]))
    return points, boards


def test_browser_the_speed_figures_labels_neither_overlap_nor_leave_it(
    browser: tuple[Any, str], site: Path, tmp_path: Path
) -> None:
    """The committed board's figure and a crowded one, drawn by Chromium: every text's box, measured.

    No two texts (point labels, ticks, titles, legend) share a pixel, and every one is
    inside the figure. The crowded board has eight front points in one decade of speed
    and a few percent of All, with long names.
    """
    pytest.importorskip("matplotlib")
    from odmd_bench.leaderboard.site.figures import speed_svg

    points, boards = _speed_points(site)
    assert points
    # eight on the front (faster, worse), four behind it
    crowded = [
        SpeedPoint("crowded", f"A rather long method name {i} (variant)", 1000 * 1.4**i, 4.0 + 1.1 * i)
        for i in range(8)
    ]
    crowded += [SpeedPoint("crowded", f"dominated {i}", 900 * 1.3**i, 14.0) for i in range(4)]
    page, base = browser
    for name, svg in (
        ("committed", speed_svg(points, boards)),
        ("crowded", speed_svg(crowded, ["crowded"])),
    ):
        text = svg.decode("utf-8")
        page.set_content(
            "<!DOCTYPE html><html><body style='margin:0'>" + text[text.index("<svg") :] + "</body></html>"
        )
        found = page.evaluate(
            """() => {
                const svg = document.querySelector("svg");
                const v = svg.getBoundingClientRect();
                const texts = Array.from(svg.querySelectorAll("text")).filter(t => !t.parentElement.closest("text"));
                return { view: [v.left, v.top, v.right, v.bottom], texts: texts.map(t => {
                    const r = t.getBoundingClientRect();
                    return [t.textContent.trim(), r.left, r.top, r.right, r.bottom]; }) };
            }"""
        )
        left, top, right, bottom = found["view"]
        texts = [t for t in found["texts"] if t[0]]
        labels = {t[0] for t in texts}
        drawn = points if name == "committed" else crowded
        front = {
            p.name.split(" (")[0]
            for b in [*boards, "crowded"]
            for p in pareto([q for q in drawn if q.board == b])
        }
        assert front <= labels, (name, front - labels)
        outside = [t for t in texts if t[1] < left or t[2] < top or t[3] > right or t[4] > bottom]
        assert outside == [], (name, outside)
        overlapping = [
            (a[0], b[0])
            for i, a in enumerate(texts)
            for b in texts[i + 1 :]
            if min(a[3], b[3]) - max(a[1], b[1]) > 0 and min(a[4], b[4]) - max(a[2], b[2]) > 0
        ]
        assert overlapping == [], (name, overlapping)
        shot = tmp_path / f"speed-{name}.png"
        page.screenshot(path=str(shot), full_page=True)  # for review: look at it
        assert shot.stat().st_size > 10_000
    page.goto(base + "index.html")  # the page for the tests after this one


# ----------------------------------------------------------------------------- the templates and the [site] extra


def test_every_value_a_template_prints_is_escaped(small_board: Path, v1_data_dir: Path) -> None:
    """Autoescaping: the entry's text reaches the pages as text, never as markup."""
    from odmd_bench.leaderboard.site import load_site_data, render_site

    site = load_site_data(small_board, v1_data_dir, n_resamples=FAST)
    row = next(r for b in site.boards for r in b.rows if r.method == "expansion")
    hostile = "<script>alert(\"x\")</script> & 'y'"
    row.data["name"] = row.data["metadata"]["notes"] = hostile
    row.data["metadata"]["speed"] = {"examples_per_second": 2.0, "device": hostile, "command": hostile}
    files = render_site(site, figures=False)
    shown = "&lt;script&gt;alert(&quot;x&quot;)&lt;/script&gt; &amp; &#x27;y&#x27;"
    for page in ("index.html", "methods/expansion.html"):
        text = files[page].decode()
        assert "<script>alert" not in text and shown in text, page
    assert f'title="{shown}"' in files["index.html"].decode()  # an attribute's value too
    assert f"<dt>Notes</dt><dd>{shown}</dd>" in files["methods/expansion.html"].decode()


def test_the_site_without_jinja2_names_the_extra_and_fails_before_scoring(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from odmd_bench.leaderboard.site import pages

    monkeypatch.setitem(sys.modules, "jinja2", None)  # makes `import jinja2` fail
    pages.environment.cache_clear()
    try:
        out = tmp_path / "site"
        # no leaderboard folder, no data: the command fails before it looks for either
        done = CliRunner().invoke(
            cli, ["leaderboard", "site", "-o", str(out), "--root", str(tmp_path / "no")]
        )
        assert done.exit_code == 2, done.output
        assert "odmd-bench leaderboard site needs jinja2, which is not installed" in done.output
        assert "pip install 'odmd-bench[site]'" in done.output and not out.exists()
        with pytest.raises(UsageError, match=re.escape("pip install 'odmd-bench[site]'")):
            pages.environment()
    finally:
        pages.environment.cache_clear()


def test_build_and_check_need_no_jinja2() -> None:
    """The board's commands import nothing of the [site] extra (only `leaderboard site` needs it)."""
    code = (
        "import sys; sys.modules['jinja2'] = sys.modules['markupsafe'] = None\n"
        "import odmd_bench.cli.leaderboard, odmd_bench.leaderboard.site, odmd_bench.leaderboard.audit_check\n"
        "from odmd_bench.leaderboard import build, check_report, write\n"
        "print('ok')"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=False)
    assert done.returncode == 0 and done.stdout == "ok\n", done.stderr


def test_the_pages_workflow_installs_the_site_extra() -> None:
    """docs/pages-workflow.yml runs `leaderboard site`: it installs [site] (and [plot] for the figures)."""
    workflow = yaml.safe_load((REPO / "docs" / "pages-workflow.yml").read_text(encoding="utf-8"))
    runs = "\n".join(s.get("run", "") for s in workflow["jobs"]["build"]["steps"])
    assert "odmd-bench leaderboard site" in runs
    installs = re.findall(r'pip install "\.\[([a-z,]+)\]"', runs)
    assert any({"site", "plot"} <= set(extras.split(",")) for extras in installs), installs


def test_jinja2_is_the_site_extra_in_all_and_not_a_base_requirement() -> None:
    tomllib = pytest.importorskip("tomllib")
    project = tomllib.loads((REPO / "pyproject.toml").read_text(encoding="utf-8"))["project"]

    def names(requirements: list[str]) -> set[str]:
        return {re.split(r"[^A-Za-z0-9._-]", r, maxsplit=1)[0].lower() for r in requirements}

    extras = project["optional-dependencies"]
    assert "jinja2" not in names(project["dependencies"])
    assert names(extras["site"]) == {"jinja2", "markupsafe"}
    own = re.fullmatch(r"odmd-bench\[([^\]]+)\]", "".join(extras["all"]))
    assert own and "site" in own.group(1).split(",")
