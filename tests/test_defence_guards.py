"""Direct tests of three defences that a one-line change could switch off unnoticed (issue 45, item 6).

- The site's HTML escaping: a payload of ``<``, ``>``, ``&`` and both quotes in every field
  of an entry (and of a reported result) that reaches a page is shown as text, in the built
  files and in Chromium's DOM: no element or attribute of it is made.
- ``depth_problems``: NaN and infinities from any source, a shipped method's included, never pass.
- The links of an entry: ``paper`` (and ``code``) take http and https only; ``javascript:``,
  ``data:``, ``file:`` and the rest are refused, and the site links nothing else.

docs/development.md (Mutation testing) records the mutation run over these defences.
"""

from __future__ import annotations

import functools
import html
import http.server
import os
import threading
from html.parser import HTMLParser
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from conftest import two_entry_board

from odmd_bench import DepthRangeError
from odmd_bench import leaderboard as lb
from odmd_bench.inputs.bounds import MAX_ABS_DEPTH, depth_problems
from odmd_bench.leaderboard.rules import REQUIRED_FIELDS, content_problems, show
from odmd_bench.leaderboard.site import build_site, write_site
from odmd_bench.leaderboard.site.pages import _link

CHROMIUM = Path("/usr/bin/chromium")
FAST = 200

#: What a hostile entry writes in every text field: an element, an attribute breaking out of
#: double and of single quotes, an entity, and a handler that would run.
PAYLOAD = """<pwn-x data-pwn="1">&amp;'" data-pwn='2' <img src=x onerror=pwned()>"""
#: The same for a link: no spaces (a URL has none), quotes to break out of ``href``.
LINK_PAYLOAD = """https://example.org/"data-pwn="1"><pwn-x>&amp;'"""
#: Tags and attributes no page may have (each would come from the payload).
FORBIDDEN_TAGS = {"pwn-x"}
FORBIDDEN_ATTRS = {"data-pwn", "onerror"}


# --------------------------------------------------------------------------- the site's escaping


@pytest.fixture(scope="module")
def hostile_site(v1_data_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A built board whose second entry, and a reported result, carry the payload in every text field."""
    fields = {
        "name": PAYLOAD[:80],
        "description": PAYLOAD,
        "paper": LINK_PAYLOAD,
        "code": LINK_PAYLOAD,
        "training_data": PAYLOAD,
        "command": PAYLOAD,
        "notes": PAYLOAD,
    }
    tmp = tmp_path_factory.mktemp("hostile")
    root = two_entry_board(tmp, v1_data_dir, **fields)
    entry = root / lb.ENTRIES / "expansion" / "odmd-v1-test" / "entry.yaml"
    meta = yaml.safe_load(entry.read_text())
    meta["parameters"] = 0
    meta["speed"] = {"examples_per_second": 2.5e6, "device": PAYLOAD[:200], "command": PAYLOAD}
    entry.write_text(yaml.safe_dump(meta, sort_keys=False))
    sets_text = {s: "5.0" for s in ("normal", "camera", "object", "robot")}  # (the odmd-v1 sets)
    reported = [
        {
            "method": PAYLOAD,
            "benchmark": "odmd-v1",
            "split": "test",
            "sets": sets_text,
            "all": "5.0",
            "training_data": PAYLOAD,
            "source": PAYLOAD,
            "notes": PAYLOAD,
        }
    ]
    (root / "reported.yaml").write_text(yaml.safe_dump(reported, sort_keys=False))
    lb.write(root, lb.build(root, v1_data_dir, n_resamples=FAST), plot=False)
    files, _ = build_site(root, v1_data_dir, figures=False, n_resamples=FAST)
    out = tmp / "site"
    write_site(files, out)
    return out


class _Elements(HTMLParser):
    """Every tag and attribute name of a page, and its text."""

    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.tags: set[str] = set()
        self.attrs: set[str] = set()
        self.text: list[str] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        self.tags.add(tag)
        self.attrs.update(name for name, _ in attrs)

    def handle_data(self, data: str) -> None:
        self.text.append(data)


def _pages(site: Path) -> list[Path]:
    return sorted(site.rglob("*.html"))


def test_the_payload_is_text_in_every_built_page(hostile_site: Path) -> None:
    shown = 0
    for page in _pages(hostile_site):
        source = page.read_text(encoding="utf-8")
        parsed = _Elements()
        parsed.feed(source)
        assert not parsed.tags & FORBIDDEN_TAGS and not parsed.attrs & FORBIDDEN_ATTRS, page
        assert "<pwn-x" not in source and "<img src=x" not in source, page
        shown += "".join(parsed.text).count(PAYLOAD[:60])
    assert shown >= 8  # it is on the pages, as text: name, description, ... and the reported result


def test_every_field_that_reaches_a_page_is_shown_escaped(hostile_site: Path) -> None:
    method_page = (hostile_site / "methods" / "expansion.html").read_text(encoding="utf-8")
    index = (hostile_site / "index.html").read_text(encoding="utf-8")
    reported = (hostile_site / "reported.html").read_text(encoding="utf-8")
    escaped = html.escape(PAYLOAD, quote=True)
    assert escaped in method_page and html.escape(PAYLOAD[:80], quote=True) in index
    assert html.escape(LINK_PAYLOAD, quote=True) in method_page  # the links' text and targets
    assert escaped in reported


def test_the_uncertainty_page_shows_every_text_escaped() -> None:
    """The uncertainty page (its template rendered by :func:`uncertainty_body`) with the payload in every text it shows."""
    from odmd_bench.leaderboard.site.pages import uncertainty_body

    cell = {"coverage": {"observed": 0.9, "level": 0.9}, "interval_score": {"mean": 1.0}}
    row = {
        "group": 1,
        "name": PAYLOAD,
        "sets": {PAYLOAD: cell},
        "all": {"coverage": 0.9, "interval_score_mean": 1.0, "crps_mean": 0.5},
        "point_depths_of": PAYLOAD,
    }
    board = {"benchmark": PAYLOAD, "split": PAYLOAD, "rows": [row], "without_uncertainty": [PAYLOAD]}
    source = uncertainty_body([board])
    parsed = _Elements()
    parsed.feed(source)
    assert not parsed.tags & FORBIDDEN_TAGS and not parsed.attrs & FORBIDDEN_ATTRS
    assert "<pwn-x" not in source and "<img src=x" not in source
    assert "".join(parsed.text).count(PAYLOAD) >= 5  # name, set, benchmark, split, point depths, without


@pytest.fixture(scope="module")
def hostile_browser(hostile_site: Path, tmp_path_factory: pytest.TempPathFactory) -> Any:
    if not CHROMIUM.is_file():
        if os.environ.get("CI"):
            pytest.fail(f"{CHROMIUM} is missing; CI must have it", pytrace=False)
        pytest.skip(f"{CHROMIUM} is missing: apt-get install -y chromium")
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        if os.environ.get("CI"):
            pytest.fail("playwright is not installed; CI must have it", pytrace=False)
        pytest.skip("playwright is not installed (pip install -e '.[dev]')")

    class Quiet(http.server.SimpleHTTPRequestHandler):
        def log_message(self, format: str, *args: Any) -> None:  # noqa: A002
            pass

    handler = functools.partial(Quiet, directory=str(hostile_site))
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    base = f"http://127.0.0.1:{server.server_address[1]}/"
    with sync_playwright() as p:
        context = p.chromium.launch_persistent_context(
            str(tmp_path_factory.mktemp("profile")),
            executable_path=str(CHROMIUM),
            headless=True,
            args=["--no-sandbox", "--disable-gpu", "--disable-background-networking"],
        )
        page = context.new_page()
        errors: list[str] = []
        page.on("pageerror", lambda e: errors.append(str(e)))
        page.on("dialog", lambda d: errors.append(f"dialog {d.message}"))
        try:
            yield page, base, errors
        finally:
            context.close()
            server.shutdown()
            server.server_close()


def test_no_element_or_attribute_of_the_payload_reaches_the_dom(
    hostile_browser: Any, hostile_site: Path
) -> None:
    page, base, errors = hostile_browser
    for path in _pages(hostile_site):
        rel = path.relative_to(hostile_site).as_posix()
        for query in ("", "?sort=method&order=desc") if rel == "index.html" else ("",):
            page.goto(base + rel + query, wait_until="load")
            made = page.evaluate(
                "() => document.querySelectorAll('pwn-x, [data-pwn], img[onerror], [onerror]').length"
            )
            assert made == 0, rel
            if rel in ("index.html", "methods/expansion.html", "reported.html"):
                assert PAYLOAD[:60] in page.inner_text("body"), rel  # shown, as text
            hrefs = page.eval_on_selector_all("a[href]", "links => links.map(a => a.protocol)")
            assert set(hrefs) <= {"http:", "https:"}, (rel, set(hrefs))
    assert errors == []


# --------------------------------------------------------------------------- depth_problems


def test_depth_problems_flags_nan_infinities_and_beyond_the_bound_of_either_sign() -> None:
    d = np.array(
        [np.nan, np.inf, -np.inf, MAX_ABS_DEPTH, -MAX_ABS_DEPTH, np.nextafter(MAX_ABS_DEPTH, np.inf)]
    )
    d = np.append(d, [-np.nextafter(MAX_ABS_DEPTH, np.inf), 0.0, 3.5, -2.0, 1e-300])
    assert depth_problems(d).tolist() == [
        True,
        True,
        True,
        False,
        False,
        True,
        True,
        False,
        False,
        False,
        False,
    ]
    # any dtype and shape, a list too, and a NaN that is not the first
    assert depth_problems([1.0, float("nan")]).tolist() == [False, True]
    assert depth_problems(np.array([np.nan, 1.0], dtype=np.float32)).tolist() == [True, False]
    assert depth_problems(np.full((2, 2), np.nan)).all()
    # read as float64 whatever it is given: an int64 whose absolute value overflows, None
    assert depth_problems(np.array([np.iinfo(np.int64).min, 3])).tolist() == [True, False]
    assert depth_problems(np.array([None, 2.0], dtype=object)).tolist() == [True, False]


class _Nan:
    """A method module whose every depth is NaN (or inf), as a bug would make them."""

    def __init__(self, value: float) -> None:
        self.value = value

    def predict(self, examples: Any) -> np.ndarray:
        return self.predict_report(examples)[0]

    def predict_report(self, examples: Any) -> tuple[np.ndarray, dict[str, int]]:
        depths = np.full(len(examples), 2.0)
        depths[len(examples) // 2] = self.value
        return depths, {}


@pytest.mark.parametrize("value", [np.nan, np.inf, -np.inf, 1e300, -1e300])
@pytest.mark.parametrize("source", ["odmd-bench 0.0", "someone-else 1.0"])
def test_a_method_s_nan_never_passes_whoever_ships_it(source: str, value: float) -> None:
    from odmd_bench import MethodError, generate
    from odmd_bench.methods import Method

    fake = _Nan(value)
    method = Method("fake", "fake", source, fake.predict, fake.predict_report)
    assert method.is_own == source.startswith("odmd-bench")
    ex = generate(6, rng=0)
    if method.is_own or np.isfinite(value):
        # odmd-bench's own methods have only depth_problems between them and a score
        with pytest.raises(DepthRangeError, match="not finite or beyond") as info:
            method.run(ex)
        assert list(info.value.where) == [3]
    else:
        with pytest.raises(MethodError, match="returned 1 non-finite depths"):
            method.run(ex)


def test_a_shipped_method_s_nan_stops_predict_too(monkeypatch: pytest.MonkeyPatch) -> None:
    import odmd_bench_baselines.box_ls as box_ls

    from odmd_bench.predict import predict_sequences
    from odmd_bench.predict.sequences import read_sequences

    rows = ["sequence,observation,x1,y1,x2,y2,cam_x,cam_y,cam_z"]
    for seq in ("a", "b"):
        for k in range(4):
            w = 40 + 10 * k
            rows.append(f"{seq},{k},{100 - w},{100 - w},{100 + w},{100 + w},0,0,{0.1 * k}")
    seqs = read_sequences(("\n".join(rows) + "\n").encode(), (640.0, 480.0))
    real = box_ls.predict_report

    def nan_first(examples: Any, **kw: Any) -> Any:
        depths, counts = real(examples, **kw)
        depths = np.array(depths, dtype=np.float64)
        depths[0] = np.nan
        return depths, counts

    monkeypatch.setattr(box_ls, "predict_report", nan_first)
    with pytest.raises(DepthRangeError, match="not finite"):
        predict_sequences(seqs, "box-ls")


# --------------------------------------------------------------------------- link schemes

GOOD_LINKS = ["https://arxiv.org/abs/2103.01468", "http://example.org/x?y=1#z"]
BAD_LINKS = [
    "javascript:alert(1)",
    "JavaScript:alert(1)",
    "data:text/html,<script>alert(1)</script>",
    "file:///etc/passwd",
    "ftp://example.org/x",
    "vbscript:msgbox(1)",
    "//example.org/x",
    "HTTPS://example.org/x",  # the scheme as written: lowercase only
    "https:example.org",
    "https://",
    " https://example.org/x",
    "https://example.org/x y",
    "https://example.org/\tx",
    "mailto:a@example.org",
    "http\u00a0://example.org",
]


def _meta(**over: object) -> dict[str, object]:
    base: dict[str, object] = {
        "method": "m",
        "name": "M",
        "description": "d",
        "paper": "none",
        "code": "https://example.org/code",
        "training_data": "none",
        "command": "c",
        "date": "2026-01-02",
        "benchmark": "odmd-v1",
        "split": "test",
        "sets_content_sha256": {},
        "calibrated": False,
        "predictions": "predictions.csv",
    }
    return {**base, **over}


def _paper_problems(link: str) -> list[str]:
    return [p for p in content_problems(_meta(paper=link)) if "paper" in p]


@pytest.mark.parametrize("link", GOOD_LINKS + ["none"])
def test_a_paper_link_over_http_or_https_or_none_is_taken(link: str) -> None:
    assert _paper_problems(link) == []


@pytest.mark.parametrize("link", BAD_LINKS)
def test_a_paper_link_of_any_other_scheme_is_refused(link: str) -> None:
    problems = _paper_problems(link)
    if "\t" in link:
        assert problems == ["field 'paper' must not hold line breaks or control characters"]
    else:  # the message shows the link refused
        assert problems == [f"paper {show(link)} is not an http(s) link, or 'none'"]
        assert show(link) != show(None)


@pytest.mark.parametrize("link", [k for k in BAD_LINKS if not k.startswith(("http://", "https://"))])
def test_the_site_links_nothing_but_http_and_https(link: str) -> None:
    shown = _link(link, None)
    assert "<a " not in shown and "href" not in shown  # text, never a link
    assert "<script" not in shown and html.escape(link, quote=True) in shown
    for good in GOOD_LINKS:
        assert _link(good, None) == f'<a href="{html.escape(good)}" rel="noopener">{html.escape(good)}</a>'
    assert _link("none", None) == "none"
    for base in (
        "https://github.com/o/r/blob/FIX",
        "https://github.com/o/r/blob/FIX/",
        "https://github.com/o/r/blob/FIX//",
    ):
        assert _link("docs/x.md", base) == (  # one slash between, only slashes stripped
            '<a href="https://github.com/o/r/blob/FIX/docs/x.md" rel="noopener"><code>docs/x.md</code></a>'
        )


@pytest.mark.parametrize("field", ["date", "predictions", "sets_content_sha256", "paper"])
def test_a_missing_field_is_named_once_and_its_own_rule_is_not_run_on_nothing(field: str) -> None:
    meta = _meta()
    del meta[field]
    problems = content_problems(meta)  # no KeyError: each rule runs only on a field that is there
    named = [p for p in problems if f"{field!r}" in p or p.startswith(f"{field} ")]
    assert named == [f"missing field {field!r}: {REQUIRED_FIELDS[field]}"]


@pytest.mark.parametrize(
    ("name", "said"),
    [
        ("../x.csv", "must be a file name in the entry folder"),
        ("sub/x.csv", "must be a file name in the entry folder"),
        (".hidden.csv", "must be a file name in the entry folder"),
        ("x.txt", "must be a .csv or .csv.gz file"),
    ],
)
def test_the_predictions_file_name_is_checked(name: str, said: str) -> None:
    assert [p for p in content_problems(_meta(predictions=name)) if p.startswith("predictions")] == [
        f"predictions {show(name)} {said}"
    ]
    assert [p for p in content_problems(_meta(predictions="p.csv.gz")) if p.startswith("predictions")] == []
