"""The site's pages, rendered from Jinja2 templates (``site/templates/``); nothing is written here.

The templates hold the markup, with autoescaping: every value a template prints is escaped
unless it is markup already (a macro's output). What a page shows is decided here: the
columns of a board's table, a method's facts, which links are links (:func:`_link`).

Every number taken from ``leaderboard.json`` is printed by the board's own formatter
(:func:`~odmd_bench.leaderboard.render.format_number`, as ``LEADERBOARD.md``; the templates'
``fmt`` filter) and carries, in ``data-json``, the path it was read from
(``BOARD-ID/METHOD/sets/SET/percent_error/mean``, ``reported/I/all``) and in
``data-decimals`` the digits printed, so that a test can read every printed number back
against the JSON. Jinja2 is the ``[site]`` extra: :func:`environment` names it when missing.
"""

from __future__ import annotations

import functools
import hashlib
import importlib.resources
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from html import escape
from typing import TYPE_CHECKING, Any

from odmd_bench._version import __version__
from odmd_bench.data.registry import BENCHMARKS
from odmd_bench.extras import require
from odmd_bench.leaderboard.files import board_digest
from odmd_bench.leaderboard.ranking import RANK_SEED
from odmd_bench.leaderboard.render import format_difference, format_number
from odmd_bench.leaderboard.site.data import FACETS, SiteBoard, SiteData, SiteRow
from odmd_bench.leaderboard.site.downloads import download_files, downloads_list
from odmd_bench.leaderboard.specs import SET_TITLES

if TYPE_CHECKING:
    import jinja2

#: Decimals printed: percent errors (as LEADERBOARD.md), absolute errors in metres, p-values.
PERCENT_DECIMALS = 2
METRES_DECIMALS = 4
P_DECIMALS = 4


@dataclass(frozen=True)
class ExtraColumn:
    """A per-board field of a ``leaderboard.json`` row, shown where rows have it.

    Attributes:
        key: the sort key (``sort=KEY`` in the URL) and cell name.
        title: the column's heading.
        path: where the number is in a row of ``leaderboard.json``, e.g. ``("audit", "all")``.
        decimals: digits printed (by :func:`~odmd_bench.leaderboard.render.format_number`).
    """

    key: str
    title: str
    path: tuple[str, ...]
    decimals: int = PERCENT_DECIMALS


#: Extra per-board fields of an entry: each is a sortable column of the index and a line of
#: the method page, where the entry's ``leaderboard.json`` row has it (rows without it show
#: "-"). A new field of the board (for example an audit's fresh-seed All) is shown by
#: adding it here, e.g. ``ExtraColumn("audit", "Fresh-seed All", ("audit", "all"))``.
EXTRA_COLUMNS: tuple[ExtraColumn, ...] = (
    # The recorded fresh-seed audit (leaderboard audit): the mean of the three generated sets
    # on fresh draws, beside the committed test's; only the odmd-v1 board's rows have it.
    ExtraColumn("fresh", "Fresh-seed mean (audit)", ("audit", "fresh")),
)


def _e(text: object) -> str:
    """Text escaped for HTML, quotes included (the spelling of the entities: :func:`html.escape`'s)."""
    return escape(str(text), quote=True)


def _finalize(value: object) -> object:
    """What a template prints: markup as it is, anything else escaped by :func:`_e`.

    Autoescaping then leaves it alone; doing it here keeps html.escape's entities
    (``&quot;``, ``&#x27;``) where markupsafe would write ``&#34;``, ``&#39;``: the same page
    to a browser, and the same bytes as the site built before the templates.
    """
    from markupsafe import Markup

    return value if hasattr(value, "__html__") else Markup(_e(value))


@functools.cache
def environment() -> jinja2.Environment:
    """The templates of ``site/templates/``, autoescaped; a usage error naming the ``[site]`` extra without Jinja2."""
    jinja2 = require("jinja2", "site", "the leaderboard site")
    env = jinja2.Environment(
        loader=jinja2.PackageLoader(__package__, "templates"),
        autoescape=True,
        undefined=jinja2.StrictUndefined,
        trim_blocks=True,
        lstrip_blocks=True,
        keep_trailing_newline=True,
        finalize=_finalize,
    )
    env.filters.update(fmt=format_number, count=_count, repr=repr, difference=format_difference)
    env.globals.update(
        version=__version__,
        set_title=lambda s: SET_TITLES.get(s, s),
        PERCENT_DECIMALS=PERCENT_DECIMALS,
        METRES_DECIMALS=METRES_DECIMALS,
        P_DECIMALS=P_DECIMALS,
    )
    return env


def render(name: str, **context: Any) -> str:
    """The template ``name`` of ``site/templates/`` rendered with ``context``."""
    return environment().get_template(name).render(**context)


def _count(value: float | None) -> str:
    """A count or rate for people: thousands separated, no decimals (``-`` when absent)."""
    return "-" if value is None else f"{value:,.0f}"


def _dig(node: Any, path: Sequence[str]) -> Any:
    for k in path:
        if not isinstance(node, dict) or k not in node:
            return None
        node = node[k]
    return node


def _extra(r: SiteRow, c: ExtraColumn) -> float | None:
    v = _dig(r.data, c.path)
    return float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else None


def _link(target: str, source_url: str | None) -> str:
    """A ``paper`` or ``code`` value: a link (http and https only), ``none``, or a path in the repository."""
    macros = environment().get_template("macros.html").module
    if target.startswith(("http://", "https://")):
        return str(macros.link(target, target, False))  # type: ignore[attr-defined]
    if target == "none":
        return "none"
    if source_url:
        return str(macros.link(source_url.rstrip("/") + "/" + target, target, True))  # type: ignore[attr-defined]
    return str(macros.link(None, target, True))  # type: ignore[attr-defined]


# ----------------------------------------------------------------------------- index


@dataclass(frozen=True)
class Column:
    """A column of a board's table on the index; ``kind`` names its cell's macro (templates/board.html).

    ``value`` gives a text cell its text; ``extra`` is an :data:`EXTRA_COLUMNS` column's field.
    """

    key: str
    title: str
    numeric: bool
    kind: str
    narrow: bool = True  # shown on a phone-width screen
    value: Callable[[SiteRow], str] | None = None
    extra: ExtraColumn | None = None


def _text(key: str, value: Callable[[SiteRow], str], narrow: bool = True) -> Column:
    return Column(key, key.capitalize(), False, "text", narrow, value)


def columns(board: SiteBoard) -> list[Column]:
    """The columns of ``board``'s table, in order."""
    cols = [Column("group", "Group", True, "group"), Column("method", "Method", False, "method")]
    cols += [Column(s, SET_TITLES.get(s, s), True, "set") for s in board.spec.sets]
    cols += [
        Column("all", "All", True, "all"),
        Column("vs", "vs group best", True, "vs", narrow=False),
        _text("calibrated", lambda r: r.facets["calibrated"]),
        _text("input", lambda r: r.facets["input"], narrow=False),
        _text("training", lambda r: r.facets["training"]),
        _text("selection", lambda r: r.facets["selection"]),
        Column("parameters", "Parameters", True, "parameters", narrow=False),
        Column("speed", "Examples/s", True, "speed", narrow=False),
        _text("date", lambda r: r.data["metadata"]["date"], narrow=False),
    ]
    cols += [Column(c.key, c.title, True, "extra", False, extra=c) for c in EXTRA_COLUMNS]
    return cols


def _sort_keys(site: SiteData) -> dict[str, str]:
    """``{sort key: title}`` of every column of every board, first title kept."""
    keys: dict[str, str] = {}
    for b in site.boards:
        for c in columns(b):
            keys.setdefault(c.key, c.title)
    return keys


# ----------------------------------------------------------------------------- method pages


def reproduce(meta: dict[str, Any], entry: str) -> str:
    """The Reproduce commands of an entry: how to get its plug-in (where it records one), then its command."""
    plugin = meta.get("plugin") or {}
    lines = []
    if "requirement" in plugin:
        lines.append(f"pip install {plugin['requirement']}")
    elif "source" in plugin:
        lines.append(
            f"# the plug-in's source: leaderboard/{entry}/{plugin['source']}/ (module {plugin['module']})"
        )
    return "\n".join([*lines, str(meta["command"])])


def predictions_path(r: SiteRow) -> str:
    """Where the site holds a row's predictions file."""
    return f"predictions/{r.method}/{r.board}/{r.entry.predictions.name}"


def figure_path(r: SiteRow) -> str:
    """Where the site holds a row's error-against-depth figure."""
    return f"figures/{r.method}--{r.board}.png"


# ----------------------------------------------------------------------------- the whole site


def _page(name: str, title: str, base: str, digest: str, **context: Any) -> bytes:
    """The template ``name`` (a page of the site's frame, page.html); ``base`` leads to the site's top."""
    from odmd_bench.project import card_url, citation_text, repository_url

    frame = dict(citation=citation_text(), repository=repository_url(), card=card_url())
    return render(name, title=title, base=base, digest=digest, **frame, **context).encode("utf-8")


def _markup(html: str) -> Any:
    """``html`` as markup that a template prints as it is (rendered, or escaped, already)."""
    environment()  # Jinja2 (and its markupsafe) installed, or a usage error naming the extra
    from markupsafe import Markup

    return Markup(html)


def uncertainty_body(boards: Sequence[Mapping[str, Any]]) -> str:
    """The body of the site's ``uncertainty.html`` from the ``uncertainty`` list of leaderboard.json.

    Every number printed is one of the JSON's (coverage in percent) and every text is
    escaped. Unlike the other pages' numbers, these carry no ``data-json`` path, so the
    test that reads every page's numbers back against the JSON does not reach them.
    """
    return render("uncertainty_body.html", boards=boards)


def _speed(site: SiteData, figures: bool, files: dict[str, bytes]) -> dict[str, Any]:
    """The speed section: the entries recording a speed, those not, and the figure drawn."""
    from odmd_bench.leaderboard.site.figures import SpeedPoint

    points = [
        SpeedPoint(
            b.id, r.data["name"], float(r.data["metadata"]["speed"]["examples_per_second"]), r.data["all"]
        )
        for b in site.boards
        for r in b.rows
        if "speed" in r.data["metadata"]
    ]
    if points and figures:
        from odmd_bench.leaderboard.site.figures import speed_svg

        files["figures/speed.svg"] = speed_svg(points, [b.id for b in site.boards])
    return {"shown": len(points), "missing": sum(len(b.rows) for b in site.boards) - len(points)}


def render_site(
    site: SiteData,
    *,
    figures: bool,
    source_url: str | None = None,
    extra_downloads: Mapping[str, tuple[bytes, str]] | None = None,
) -> dict[str, bytes]:
    """Every file of the site, ``{relative path: bytes}``, sorted by path.

    Args:
        site: the board and its re-scored entries (:func:`~odmd_bench.leaderboard.site.data.load_site_data`).
        figures: draw the figures (needs matplotlib).
        source_url: where repository paths (an entry's ``code``) link to, e.g.
            ``https://github.com/odmd-bench/odmd-bench/blob/COMMIT``; without it they are shown as text.
        extra_downloads: further files for ``downloads/``, ``{file name: (bytes, what it is)}``
            (the Croissant descriptions of ``leaderboard site``), each listed with the others.
    """
    digest = board_digest(site.json_text)
    files = {"assets/site.css": _asset("site.css"), "assets/site.js": _asset("site.js")}
    files.update(download_files(site, extra_downloads))
    if site.data.get("uncertainty"):
        files["uncertainty.html"] = _page(
            "uncertainty.html", "Uncertainty: ODMD leaderboard", "", digest, boards=site.data["uncertainty"]
        )
    methods: dict[str, list[tuple[SiteRow, SiteBoard]]] = {}
    for b in site.boards:
        for r in b.rows:
            files[predictions_path(r)] = r.entry.predictions.read_bytes()
            methods.setdefault(r.method, []).append((r, b))
            if figures:
                from odmd_bench.leaderboard.site.figures import error_depth_png

                files[figure_path(r)] = error_depth_png(
                    r.result, r.spec.sets, f"{r.data['name']} on {r.spec.key}"
                )
    files["index.html"] = _page(
        "index.html",
        "ODMD leaderboard",
        "",
        digest,
        site=site,
        columns=columns,
        extra=_extra,
        descriptions={name: bench.description for name, bench in BENCHMARKS.items()},
        sort_keys=_sort_keys(site),
        facets=FACETS,
        downloads=downloads_list(site, extra_downloads),
        speed=_speed(site, figures, files),
        figures=figures,
    )
    for method, mine in sorted(methods.items()):
        files[f"methods/{method}.html"] = _method_page(method, mine, site, files, figures, source_url, digest)
    files["reported.html"] = _page(
        "reported.html", "Reported in papers: ODMD leaderboard", "", digest, **_reported(site)
    )
    return dict(sorted(files.items()))


def _method_page(
    method: str,
    mine: list[tuple[SiteRow, SiteBoard]],
    site: SiteData,
    files: dict[str, bytes],
    figures: bool,
    source_url: str | None,
    digest: str,
) -> bytes:
    """The page of ``method``: a section per board it is on (``mine``); ``files`` holds its predictions."""
    first = mine[0][0]
    meta = first.data["metadata"]
    return _page(
        "method.html",
        f"{first.data['name']}: ODMD leaderboard",
        "../",
        digest,
        first=first,
        method=method,
        paper=_markup(_link(meta["paper"], source_url)),
        code=_markup(_link(meta["code"], source_url)),
        mine=mine,
        figures=figures,
        sha256={r.board: hashlib.sha256(files[predictions_path(r)]).hexdigest() for r, _ in mine},
        predictions_path=predictions_path,
        figure_path=figure_path,
        reproduce=reproduce,
        extras=lambda r: [(c, v) for c in EXTRA_COLUMNS if (v := _extra(r, c)) is not None],
        n_resamples=site.n_resamples,
        rank_seed=RANK_SEED,
    )


def _reported(site: SiteData) -> dict[str, Any]:
    """The reported page's ``tables`` and the board's ``rows``, for its template.

    A table per benchmark and split, ``(benchmark, split, sets, [(index in the JSON, result)])``;
    the rows by ``(method, benchmark, split)``, where an entry re-scores a reported result.
    """
    rows = {(r.method, b.spec.benchmark, b.spec.split): r for b in site.boards for r in b.rows}
    reported = list(enumerate(site.data.get("reported", [])))
    tables = [
        (
            bench,
            split,
            BENCHMARKS[bench].sets,
            [(i, x) for i, x in reported if (x["benchmark"], x["split"]) == (bench, split)],
        )
        for bench, split in sorted({(x["benchmark"], x["split"]) for _, x in reported})
    ]
    return {"tables": tables, "rows": rows}


def _asset(name: str) -> bytes:
    """A file of the package's ``site/templates/`` folder, as it is."""
    return importlib.resources.files(__package__).joinpath("templates").joinpath(name).read_bytes()
