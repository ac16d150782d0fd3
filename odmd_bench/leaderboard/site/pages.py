"""The site's files, computed: ``{relative path: bytes}``; nothing is written here.

Every number taken from ``leaderboard.json`` is printed by the board's own formatter
(:func:`~odmd_bench.leaderboard.render.format_number`, as ``LEADERBOARD.md``) and carries,
in ``data-json``, the path it was read from (``BOARD-ID/METHOD/sets/SET/percent_error/mean``,
``reported/I/all``) and in ``data-decimals`` the digits printed, so that a test can read
every printed number back against the JSON.
"""

from __future__ import annotations

import csv
import hashlib
import importlib.resources
import io
import json
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from html import escape
from string import Template
from typing import Any

from odmd_bench._version import __version__
from odmd_bench.data.registry import BENCHMARKS
from odmd_bench.leaderboard.files import JSON_FILE, board_digest
from odmd_bench.leaderboard.ranking import RANK_SEED
from odmd_bench.leaderboard.render import format_difference, format_number
from odmd_bench.leaderboard.site.data import FACETS, SiteBoard, SiteData, SiteRow, Versus
from odmd_bench.leaderboard.specs import SET_TITLES

#: Decimals printed: percent errors (as LEADERBOARD.md), absolute errors in metres, p-values.
PERCENT_DECIMALS = 2
METRES_DECIMALS = 4
P_DECIMALS = 4
NO_PLOT = (
    "<p>No figure: this site was built without the [plot] extra (matplotlib); "
    "<code>pip install 'odmd-bench[plot]'</code> and build it again to draw it.</p>"
)


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


def template(name: str) -> Template:
    """A template of the package (``site/templates/NAME``)."""
    return Template(asset(name).decode("utf-8"))


def asset(name: str) -> bytes:
    """A file of the package's ``site/templates/`` folder."""
    return importlib.resources.files(__package__).joinpath("templates").joinpath(name).read_bytes()


def _e(text: object) -> str:
    return escape(str(text), quote=True)


def _num(value: float, src: str, decimals: int = PERCENT_DECIMALS, cls: str = "num", key: str = "") -> str:
    """A table cell printing a number of leaderboard.json (``src``: its path there)."""
    k = f' data-k="{_e(key)}"' if key else ""
    return (
        f'<td class="{cls}"{k} data-v="{value!r}" data-json="{_e(src)}" data-decimals="{decimals}">'
        f"{format_number(value, decimals)}</td>"
    )


def _count(value: float | None) -> str:
    """A count or rate for people: thousands separated, no decimals (``-`` when absent)."""
    return "-" if value is None else f"{value:,.0f}"


def _counted(value: float, src: str, tag: str = "span", attrs: str = "") -> str:
    """A count or rate of leaderboard.json (``src``: its path there), printed by :func:`_count`."""
    return f'<{tag}{attrs} data-json="{_e(src)}" data-decimals="0">{_count(value)}</{tag}>'


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
    """A ``paper`` or ``code`` value: a link, ``none``, or a path in the repository."""
    if target.startswith(("http://", "https://")):
        return f'<a href="{_e(target)}" rel="noopener">{_e(target)}</a>'
    if target == "none":
        return "none"
    if source_url:
        url = source_url.rstrip("/") + "/" + target
        return f'<a href="{_e(url)}" rel="noopener"><code>{_e(target)}</code></a>'
    return f"<code>{_e(target)}</code> in the repository"


# ----------------------------------------------------------------------------- index


@dataclass(frozen=True)
class Column:
    """A column of a board's table on the index."""

    key: str
    title: str
    numeric: bool
    cell: Callable[[SiteRow], str]
    narrow: bool = True  # shown on a phone-width screen


def _text_cell(key: str, value: Callable[[SiteRow], str]) -> Callable[[SiteRow], str]:
    return lambda r: f'<td data-k="{key}" data-v="{_e(value(r))}">{_e(value(r))}</td>'


def _group_cell(r: SiteRow) -> str:
    g = r.data["group"]
    return (
        f'<td class="group num" data-k="group" data-v="{g}" data-json="{r.src}/group" data-decimals="0">'
        f"<span>{g}</span></td>"
    )


def _method_cell(r: SiteRow) -> str:
    name = r.data["name"]
    return (
        f'<td data-k="method" data-v="{_e(name)}"><a href="methods/{_e(r.method)}.html#{r.board}">'
        f"{_e(name)}</a></td>"
    )


def _vs_cell(r: SiteRow) -> str:
    vs = r.data["versus_group_leader"]
    if vs is None:
        return (
            f'<td class="num" data-k="vs" data-v="0">{"best" if r.data["group"] == 1 else "group best"}</td>'
        )
    text = format_difference(vs["difference_a_minus_b"], vs["ci_low"], vs["ci_high"])
    return f'<td class="num" data-k="vs" data-v="{-vs["difference_a_minus_b"] + 0.0!r}">{text}</td>'


def _parameters_cell(r: SiteRow) -> str:
    v = r.data["metadata"].get("parameters")
    if v is None:
        return '<td class="num" data-k="parameters" data-v="">-</td>'
    return _counted(v, f"{r.src}/metadata/parameters", "td", f' class="num" data-k="parameters" data-v="{v}"')


def _speed_cell(r: SiteRow) -> str:
    sp = r.data["metadata"].get("speed")
    if sp is None:
        return '<td class="num" data-k="speed" data-v="">-</td>'
    v = sp["examples_per_second"]
    attrs = f' class="num" data-k="speed" data-v="{v!r}" title="{_e(sp["device"])}"'
    return _counted(v, f"{r.src}/metadata/speed/examples_per_second", "td", attrs)


def _columns(board: SiteBoard) -> list[Column]:
    def set_cell(s: str) -> Callable[[SiteRow], str]:
        return lambda r: _num(
            r.data["sets"][s]["percent_error"]["mean"], f"{r.src}/sets/{s}/percent_error/mean", key=s
        )

    def extra_cell(c: ExtraColumn) -> Callable[[SiteRow], str]:
        def cell(r: SiteRow) -> str:
            v = _extra(r, c)
            if v is None:
                return f'<td class="num" data-k="{_e(c.key)}" data-v="">-</td>'
            return _num(v, f"{r.src}/{'/'.join(c.path)}", c.decimals, key=c.key)

        return cell

    cols = [Column("group", "Group", True, _group_cell), Column("method", "Method", False, _method_cell)]
    cols += [Column(s, SET_TITLES.get(s, s), True, set_cell(s)) for s in board.spec.sets]
    cols += [
        Column("all", "All", True, lambda r: _num(r.data["all"], f"{r.src}/all", cls="num all", key="all")),
        Column("vs", "vs group best", True, _vs_cell, narrow=False),
        Column("calibrated", "Calibrated", False, _text_cell("calibrated", lambda r: r.facets["calibrated"])),
        Column("input", "Input", False, _text_cell("input", lambda r: r.facets["input"]), narrow=False),
        Column("training", "Training", False, _text_cell("training", lambda r: r.facets["training"])),
        Column("selection", "Selection", False, _text_cell("selection", lambda r: r.facets["selection"])),
        Column("parameters", "Parameters", True, _parameters_cell, narrow=False),
        Column("speed", "Examples/s", True, _speed_cell, narrow=False),
        Column("date", "Date", False, _text_cell("date", lambda r: r.data["metadata"]["date"]), narrow=False),
    ]
    cols += [Column(c.key, c.title, True, extra_cell(c), narrow=False) for c in EXTRA_COLUMNS]
    return cols


def _narrow(cell: str, narrow: bool) -> str:
    """The cell, hidden on a phone-width screen unless ``narrow``."""
    if narrow:
        return cell
    if cell.startswith('<td class="'):
        return cell.replace('<td class="', '<td class="hide-narrow ', 1)
    return cell.replace("<td", '<td class="hide-narrow"', 1)


def _th(c: Column) -> str:
    classes = " ".join(x for x in ("num" if c.numeric else "", "" if c.narrow else "hide-narrow") if x)
    attr = f' class="{classes}"' if classes else ""
    kind = "num" if c.numeric else "text"
    return (
        f'<th data-key="{c.key}" data-type="{kind}"{attr}><button type="button">{_e(c.title)}</button></th>'
    )


def _board_section(board: SiteBoard) -> str:
    bid, spec = board.id, board.spec
    desc = BENCHMARKS[spec.benchmark].description
    head = (
        f'<section id="{bid}" data-board-section="{bid}">\n'
        f"<h2>{_e(spec.key)} <small>({_e(spec.title)})</small></h2>\n"
    )
    if not board.rows:
        return head + (
            f"<p>Data: {_e(desc)}.</p>\n<p>No entries yet. Add one with <code>odmd-bench leaderboard add "
            f"PREDS.csv --benchmark {spec.benchmark} --split {spec.split} ...</code>.</p>\n</section>"
        )
    hashes = ", ".join(f"{_e(s)} <code>{h[:12]}</code>" for s, h in board.data["sets_content_sha256"].items())
    cols = _columns(board)
    ths = "".join(_th(c) for c in cols)
    lines = []
    previous = 0
    for pos, r in enumerate(board.rows, 1):
        g = r.data["group"]
        cls = ("gstart " if g != previous and pos > 1 else "") + ("godd" if g % 2 else "geven")
        previous = g
        attrs = "".join(f' data-{k}="{v}"' for k, v in r.facets.items())
        cells = "".join(_narrow(c.cell(r), c.narrow) for c in cols)
        lines.append(
            f'<tr data-method="{_e(r.method)}" data-pos="{pos}" data-group="{g}"{attrs} class="{cls}">{cells}</tr>'
        )
    return head + (
        f'<p class="meta">Data: {_e(desc)}. Version: {_e(board.data["data_version"])}; content SHA-256 {hashes}. '
        f'Download: <a href="downloads/{bid}.csv">{bid}.csv</a>.</p>\n'
        f'<div class="scroll"><table data-board="{bid}">\n<thead><tr>{ths}</tr></thead>\n<tbody>\n'
        + "\n".join(lines)
        + "\n</tbody>\n</table></div>\n</section>"
    )


def _controls(site: SiteData) -> dict[str, str]:
    boards = "".join(f'<option value="{b.id}">{_e(b.spec.key)}</option>' for b in site.boards if b.rows)
    keys: dict[str, str] = {}
    for b in site.boards:
        for c in _columns(b):
            keys.setdefault(c.key, c.title)
    facet = "".join(
        f'<label>{name.replace("_", " ").capitalize()} <select name="{name}"><option value="">any</option>'
        + "".join(f'<option value="{v}">{v}</option>' for v in values)
        + "</select></label>\n"
        for name, values in FACETS.items()
    )
    return {
        "board_options": boards,
        "sort_options": "".join(f'<option value="{_e(k)}">{_e(t)}</option>' for k, t in keys.items()),
        "facet_controls": facet,
    }


# ----------------------------------------------------------------------------- method pages


def _stats_table(r: SiteRow) -> str:
    heads = ["n", "mean %", "median %", "max %", "std %", "mean abs. error (m)"]
    head = "<tr><th>Set</th>" + "".join(f'<th class="num">{h}</th>' for h in heads) + "</tr>"
    lines = []
    for s in r.spec.sets:
        m, p = r.data["sets"][s], f"{r.src}/sets/{s}"
        lines.append(
            f"<tr><td>{_e(SET_TITLES.get(s, s))}</td>"
            f'<td class="num" data-json="{p}/n" data-decimals="0">{m["n"]}</td>'
            + "".join(
                _num(m["percent_error"][k], f"{p}/percent_error/{k}")
                for k in ("mean", "median", "max", "std")
            )
            + _num(m["absolute_error"]["mean"], f"{p}/absolute_error/mean", METRES_DECIMALS)
            + "</tr>"
        )
    lines.append(
        f"<tr><td><strong>All</strong></td><td></td>{_num(r.data['all'], f'{r.src}/all', cls='num all')}"
        '<td colspan="4"></td></tr>'
    )
    return (
        f'<div class="scroll"><table class="stats">\n<thead>{head}</thead>\n<tbody>\n'
        + "\n".join(lines)
        + "\n</tbody></table></div>"
    )


def _versus_row(r: SiteRow, v: Versus) -> str:
    name = r.data["name"]
    verdict = {"A better": f"{v.name} better", "B better": f"{name} better"}.get(v.verdict, v.verdict)
    src = f' data-json="{v.src}"' if v.src else ""
    return (
        f'<tr data-against="{_e(v.method)}"{src}><td><a href="{_e(v.method)}.html#{r.board}">{_e(v.name)}</a> '
        f'({v.role})</td><td class="num">{format_difference(v.difference, v.ci_low, v.ci_high)}</td>'
        f'<td class="num">{format_number(v.p_value, P_DECIMALS)}</td><td>{_e(verdict)}</td></tr>'
    )


def _versus_table(r: SiteRow, n_resamples: int) -> str:
    if not r.versus:
        return "<p>Nothing to compare it with: it is the board's best method, and the reference (Box_LS) itself or not on this board.</p>"
    return (
        '<div class="scroll"><table class="versus">\n<thead><tr><th>Against</th>'
        '<th class="num">All: this minus it [95% interval]</th><th class="num">p</th><th>Verdict</th></tr>'
        "</thead>\n<tbody>\n" + "\n".join(_versus_row(r, v) for v in r.versus) + "\n</tbody></table></div>\n"
        '<p class="meta">As <code>odmd-bench compare</code> gives it (A: the other method, B: this one): a paired '
        "bootstrap interval and sign-flip test on the per-example percent errors, stratified by set, "
        f"{n_resamples} resamples, seed {RANK_SEED}.</p>"
    )


def _facts(r: SiteRow, name: str) -> str:
    meta = r.data["metadata"]
    items = [("Name here", _e(meta["name"]))] if meta["name"] != name else []
    calibrated = r.facets["calibrated"]
    items += [
        ("Training data", f"{_e(meta['training_data'])} (kind: {_e(r.facets['training'])})"),
        ("Selected on", _e(r.facets["selected_on"])),
        ("Test labels used", "yes" if meta.get("uses_test_labels") else "no"),
        ("Selection", r.facets["selection"]),
        ("Calibrated", calibrated + (" (uses the camera intrinsics)" if calibrated == "yes" else "")),
        ("Input", r.facets["input"]),
        ("Date", _e(meta["date"])),
    ]
    if "parameters" in meta:
        items.append(("Parameters", _counted(meta["parameters"], f"{r.src}/metadata/parameters")))
    sp = meta.get("speed")
    if sp is not None:
        rate = _counted(sp["examples_per_second"], f"{r.src}/metadata/speed/examples_per_second")
        items.append(
            (
                "Speed",
                f"{rate} examples per second on {_e(sp['device'])}, measured by <code>{_e(sp['command'])}</code>",
            )
        )
    for c in EXTRA_COLUMNS:
        v = _extra(r, c)
        if v is not None:
            src = f"{r.src}/{'/'.join(c.path)}"
            items.append(
                (
                    _e(c.title),
                    f'<span data-json="{src}" data-decimals="{c.decimals}">{format_number(v, c.decimals)}</span>',
                )
            )
    if meta.get("notes"):
        items.append(("Notes", _e(meta["notes"])))
    if r.data["warnings"]:
        items.append(("Warnings", "<br>".join(_e(w) for w in r.data["warnings"])))
    return '<dl class="facts">' + "".join(f"<dt>{k}</dt><dd>{v}</dd>" for k, v in items) + "</dl>"


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


def _method_board(
    r: SiteRow, board: SiteBoard, name: str, figures: bool, files: dict[str, bytes], n: int
) -> str:
    meta = r.data["metadata"]
    pred = predictions_path(r)
    hashes = "".join(
        f'<li>{_e(SET_TITLES.get(s, s))}: <code class="hash">{_e(h)}</code></li>'
        for s, h in meta["sets_content_sha256"].items()
    )
    fig = NO_PLOT
    if figures:
        fig = (
            f'<img class="figure" src="../{figure_path(r)}" width="512" height="272" alt="Median percent error '
            f'against true depth, per set, of {_e(meta["name"])} on {_e(r.spec.key)}">'
        )
    cmd = f"command-{r.board}"
    return f"""<section id="{r.board}">
<h2>{_e(r.spec.key)} <small>({_e(r.spec.title)})</small></h2>
<p class="meta">Position {_counted(r.data["position"], f"{r.src}/position")} of {len(board.rows)}, rank group
<span data-json="{r.src}/group" data-decimals="0">{r.data["group"]}</span>
(<a href="../index.html?board={r.board}">the board</a>). Data: {_e(r.spec.benchmark)}
({_e(board.data["data_version"])}).</p>
{_facts(r, name)}
<h3>Errors per set</h3>
{_stats_table(r)}
<h3>Data and predictions</h3>
<p>Scored on the sets of content SHA-256:</p>
<ul>{hashes}</ul>
<p>Predictions: <a href="../{pred}" download>{_e(r.entry.predictions.name)}</a>
({_counted(r.data["predictions_rows"], f"{r.src}/predictions_rows")} rows;
SHA-256 of the file <code class="hash">{hashlib.sha256(files[pred]).hexdigest()}</code>; of the CSV inside, as
leaderboard.json records it, <code class="hash">{_e(r.data["predictions_csv_sha256"])}</code>).
In the repository: <code>leaderboard/{_e(r.data["entry"])}/</code>.</p>
<h3>Reproduce</h3>
<pre><code id="{cmd}">{_e(reproduce(meta, r.data["entry"]))}</code></pre>
<button type="button" class="copy" data-for="{cmd}" hidden>Copy the command</button>
<h3>Paired comparisons</h3>
{_versus_table(r, n)}
<h3>Error against depth</h3>
{fig}
</section>"""


# ----------------------------------------------------------------------------- reported


def _reported(site: SiteData) -> str:
    rows = {(r.method, b.spec.benchmark, b.spec.split): r for b in site.boards for r in b.rows}
    reported = list(enumerate(site.data.get("reported", [])))
    out = []
    for bench, split in sorted({(x["benchmark"], x["split"]) for _, x in reported}):
        sets = BENCHMARKS[bench].sets
        head = "".join(f'<th class="num">{_e(SET_TITLES.get(s, s))}</th>' for s in sets)
        lines = []
        for i, x in reported:
            if (x["benchmark"], x["split"]) != (bench, split):
                continue
            here = "-"
            if x.get("entry"):
                row = rows.get((x["entry"], bench, split))
                here = f"no entry {_e(x['entry'])} yet"
                if row is not None:
                    here = (
                        f'<a href="methods/{_e(row.method)}.html#{row.board}">{_e(row.data["name"])}</a>: '
                        f'<span data-json="{row.src}/all" data-decimals="{PERCENT_DECIMALS}">'
                        f"{format_number(row.data['all'])}</span>"
                    )
            cells = "".join(
                f'<td class="num" data-json="reported/{i}/sets/{s}" data-text="1">{_e(x["sets"][s])}</td>'
                for s in sets
            )
            lines.append(
                f"<tr><td>{_e(x['method'])}</td><td>{_e(x['input'])}</td>{cells}"
                f'<td class="num all" data-json="reported/{i}/all" data-text="1">{_e(x["all"])}</td>'
                f"<td>{_e(x['training_data'])}</td><td>{_e(x['source'])}</td><td>{here}</td>"
                f"<td>{_e(x.get('notes') or '')}</td></tr>"
            )
        out.append(
            f'<h2>{_e(bench)} {_e(split)} (reported)</h2>\n<div class="scroll"><table class="reported">\n'
            f'<thead><tr><th>Method</th><th>Input</th>{head}<th class="num">All</th><th>Trained on</th>'
            "<th>Source</th><th>Re-scored here</th><th>Notes</th></tr></thead>\n<tbody>\n"
            + "\n".join(lines)
            + "\n</tbody></table></div>"
        )
    if not out:
        return "<p>No reported results.</p>"
    return "\n".join(out) + (
        '\n<p class="meta"><strong>Input</strong>: <em>segmentation</em> methods take the original ODMS '
        "segmentation masks, not the boxes the entries are scored on; their numbers are not comparable with "
        "the entries'.</p>"
    )


# ----------------------------------------------------------------------------- downloads and figures


def board_csv(board: SiteBoard) -> bytes:
    """One board as CSV, a line per entry; the numbers as leaderboard.json writes them."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    sets = list(board.spec.sets)
    w.writerow(
        [
            "position",
            "group",
            "method",
            "name",
            *sets,
            "all",
            *FACETS,
            "parameters",
            "examples_per_second",
            "date",
        ]
    )
    for r in board.rows:
        meta = r.data["metadata"]
        speed = meta.get("speed")
        w.writerow(
            [
                r.data["position"],
                r.data["group"],
                r.method,
                r.data["name"],
                *(json.dumps(r.data["sets"][s]["percent_error"]["mean"]) for s in sets),
                json.dumps(r.data["all"]),
                *(r.facets[f] for f in FACETS),
                meta.get("parameters", ""),
                "" if speed is None else json.dumps(speed["examples_per_second"]),
                meta["date"],
            ]
        )
    return buf.getvalue().encode("utf-8")


def _speed_section(site: SiteData, figures: bool, files: dict[str, bytes]) -> str:
    from odmd_bench.leaderboard.site.figures import SpeedPoint

    points = [
        SpeedPoint(
            b.id, r.data["name"], float(r.data["metadata"]["speed"]["examples_per_second"]), r.data["all"]
        )
        for b in site.boards
        for r in b.rows
        if "speed" in r.data["metadata"]
    ]
    if not points:
        return "<p>No entry records its speed yet.</p>"
    missing = sum(len(b.rows) for b in site.boards) - len(points)
    said = f"<p>{len(points)} entries record their speed" + (
        f"; {missing} do not and are not shown.</p>" if missing else ".</p>"
    )
    if not figures:
        return said + NO_PLOT
    from odmd_bench.leaderboard.site.figures import speed_svg

    files["figures/speed.svg"] = speed_svg(points, [b.id for b in site.boards])
    return said + (
        '<p><img class="figure" src="figures/speed.svg" alt="All against examples per second per board, the '
        'Pareto front marked"></p>\n<p class="meta">The Pareto front (red) joins the entries that no other entry '
        "beats on both speed and All. Each speed was measured where its entry says (the device shows when you "
        "hover over a speed; the method page names the command).</p>"
    )


# ----------------------------------------------------------------------------- the whole site


def _cite() -> dict[str, str]:
    """The footer's citation and addresses (odmd_bench.project: configured in pyproject.toml)."""
    from odmd_bench.project import card_url, citation_text, repository_url

    repo = repository_url()
    return {
        "citation": _e(citation_text()),
        "repository": _e(repo),
        "card": _e(card_url()),
        "maintenance": _e(f"{repo}/blob/main/docs/maintenance.md"),
    }


def _page(title: str, body: str, base: str, digest: str) -> bytes:
    return (
        template("page.html")
        .substitute(title=_e(title), body=body, base=base, version=_e(__version__), digest=digest, **_cite())
        .encode("utf-8")
    )


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
    files: dict[str, bytes] = {
        "assets/site.css": asset("site.css"),
        "assets/site.js": asset("site.js"),
        f"downloads/{JSON_FILE}": site.json_text.encode("utf-8"),
    }
    downloads = [
        f'<li><a href="downloads/{JSON_FILE}">{JSON_FILE}</a>: every board, every statistic, with provenance</li>'
    ]
    for b in site.boards:
        if b.rows:
            files[f"downloads/{b.id}.csv"] = board_csv(b)
            downloads.append(
                f'<li><a href="downloads/{b.id}.csv">{b.id}.csv</a>: the {_e(b.spec.key)} table</li>'
            )
    for name, (data, what) in (extra_downloads or {}).items():
        files[f"downloads/{name}"] = data
        downloads.append(f'<li><a href="downloads/{_e(name)}">{_e(name)}</a>: {_e(what)}</li>')
    downloads.append('<li><a href="reported.html">Results reported in papers</a> (not re-scored)</li>')
    if site.data.get("uncertainty"):
        from odmd_bench.leaderboard.uncertainty import site_page

        files["uncertainty.html"] = _page(
            "Uncertainty: ODMD leaderboard", site_page(site.data["uncertainty"]), "", digest
        )
        downloads.append(
            '<li><a href="uncertainty.html">Uncertainty</a>: error bars ranked by interval score</li>'
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
    index = template("index.html").substitute(
        boards="\n".join(_board_section(b) for b in site.boards),
        downloads="\n".join(downloads),
        speed=_speed_section(site, figures, files),
        **_controls(site),
    )
    files["index.html"] = _page("ODMD leaderboard", index, "", digest)
    for method, mine in sorted(methods.items()):
        first = mine[0][0].data
        meta = first["metadata"]
        body = template("method.html").substitute(
            name=_e(first["name"]),
            description=_e(meta["description"]),
            method=_e(method),
            paper=_link(meta["paper"], source_url),
            code=_link(meta["code"], source_url),
            board_links=", ".join(f'<a href="#{r.board}">{_e(r.spec.key)}</a>' for r, _ in mine),
            version=_e(__version__),
            boards="\n".join(
                _method_board(r, b, first["name"], figures, files, site.n_resamples) for r, b in mine
            ),
        )
        files[f"methods/{method}.html"] = _page(f"{first['name']}: ODMD leaderboard", body, "../", digest)
    reported = template("reported.html").substitute(tables=_reported(site))
    files["reported.html"] = _page("Reported in papers: ODMD leaderboard", reported, "", digest)
    return dict(sorted(files.items()))
