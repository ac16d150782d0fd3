"""A stable citation: CITATION.cff valid, one set of addresses everywhere, every site page cites."""

from __future__ import annotations

import json
import os
import re
import sys
from pathlib import Path

import pytest
import yaml
from click.testing import CliRunner

from odmd_bench import leaderboard as lb
from odmd_bench._version import __version__
from odmd_bench.cli.main import cli
from odmd_bench.leaderboard.site import build_site
from odmd_bench.project import PAPER_BIBTEX, card_url, citation_text, project_urls, repository_url, site_url

REPO = Path(__file__).resolve().parents[1]
CFF = REPO / "CITATION.cff"
ZENODO = REPO / ".zenodo.json"
FAST = 200


@pytest.fixture(scope="module", autouse=True)
def _set_files_once(croissant_set_files_made_once: None) -> None:
    """Each set's Croissant JSON file made once in the run (tests/conftest.py)."""


def test_citation_cff_passes_cffconvert_validate(tmp_path: Path) -> None:
    if os.environ.get("CI"):  # in the dev extra: CI must have it
        from cffconvert.cli.create_citation import create_citation
    else:
        create_citation = pytest.importorskip("cffconvert.cli.create_citation").create_citation
    create_citation(str(CFF), None).validate()  # raises on a file that breaks the CFF 1.2.0 schema
    broken = tmp_path / "CITATION.cff"
    broken.write_text(CFF.read_text().replace('doi: "10.48550/', 'doi: "not-a-doi/'))
    from jsonschema.exceptions import ValidationError  # cffconvert validates with jsonschema

    with pytest.raises(ValidationError, match="does not match"):
        create_citation(str(broken), None).validate()


def test_the_addresses_are_pyprojects_everywhere() -> None:
    if sys.version_info >= (3, 11):  # tomllib: the installed metadata is not stale
        import tomllib

        urls = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]["urls"]
        assert project_urls() == urls
    cff = yaml.safe_load(CFF.read_text())
    assert cff["repository-code"] == repository_url() and cff["url"] == site_url()
    assert cff["version"] == __version__
    zenodo = json.loads(ZENODO.read_text())
    assert zenodo["version"] == __version__ and zenodo["title"] == cff["title"]
    assert zenodo["license"] == cff["license"] == "MIT"
    related = {r["identifier"] for r in zenodo["related_identifiers"]}
    paper_doi = cff["preferred-citation"]["doi"]
    assert {repository_url(), paper_doi} <= related
    assert f"doi       = {{{paper_doi}}}" in PAPER_BIBTEX and paper_doi in citation_text()
    assert card_url() == f"{repository_url()}/blob/main/docs/card.md"


PLACEHOLDER = re.compile(r"OWNER[./]|github\.io/REPOSITORY|example\.github\.io")


def test_no_placeholder_address_is_left() -> None:
    files = [
        REPO / "README.md",
        CFF,
        ZENODO,
        *REPO.glob("docs/*.md"),
        *REPO.glob("docs/*.yml"),
        *REPO.glob("odmd_bench/**/*.py"),
        *REPO.glob("odmd_bench/**/templates/*"),
    ]
    found = [
        f"{p.relative_to(REPO)}: {m.group()}" for p in files for m in PLACEHOLDER.finditer(p.read_text())
    ]
    assert found == []


@pytest.fixture(scope="module")
def site(v1_data_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> dict[str, bytes]:
    """The site of a board with one odmd-v1 entry, with its Croissant download."""
    from conftest import add_entry
    from odmd_bench_baselines import box_ls

    from odmd_bench import load_split
    from odmd_bench.evaluation.predictions import write_predictions

    tmp = tmp_path_factory.mktemp("cite")
    root = tmp / "leaderboard"
    (root / lb.ENTRIES).mkdir(parents=True)
    sets = load_split("test", "odmd-v1", v1_data_dir)
    preds = tmp / "box-ls.csv"
    write_predictions(preds, "test", {s: box_ls.predict(ex) for s, ex in sets.items()}, benchmark="odmd-v1")
    add_entry(root, v1_data_dir, preds, "box-ls")
    lb.write(root, lb.build(root, v1_data_dir, n_resamples=FAST), plot=False)
    files, _ = build_site(root, v1_data_dir, figures=False, n_resamples=FAST, croissant=True)
    return files


def test_every_page_shows_the_version_and_how_to_cite(site: dict[str, bytes]) -> None:
    pages = {k: v.decode() for k, v in site.items() if k.endswith(".html")}
    assert len(pages) >= 3
    for name, html in pages.items():
        footer = html[html.index("<footer>") : html.index("</footer>")]
        assert f"odmd-bench {__version__}. Cite:" in footer, name
        assert "Depth from Camera Motion and Object Detection" in footer, name
        for url in (repository_url(), f"{repository_url()}/blob/main/CITATION.cff", card_url()):
            assert f'href="{url}"' in footer, (name, url)


def test_the_site_offers_each_ranked_benchmark_in_croissant(
    site: dict[str, bytes], v1_data_dir: Path
) -> None:
    assert [k for k in site if k.endswith(".croissant.json")] == ["downloads/odmd-v1.croissant.json"]
    printed = CliRunner().invoke(
        cli, ["describe", "--format", "croissant", "odmd-v1", "--data-dir", str(v1_data_dir)]
    )
    assert printed.exit_code == 0
    assert site["downloads/odmd-v1.croissant.json"].decode() == printed.stdout
    assert b'<a href="downloads/odmd-v1.croissant.json">' in site["index.html"]


def test_addresses_unknown_to_the_install_are_a_usage_error(monkeypatch: pytest.MonkeyPatch) -> None:
    from importlib import metadata

    from odmd_bench import project
    from odmd_bench.errors import UsageError

    def missing(name: str) -> None:
        raise metadata.PackageNotFoundError(name)

    class Stale:
        def get_all(self, key: str) -> list[str]:
            return ["Homepage, https://example.org/"]

    project.project_urls.cache_clear()
    try:
        monkeypatch.setattr(project.metadata, "metadata", missing)
        with pytest.raises(UsageError, match="not installed"):
            project.project_urls()
        monkeypatch.setattr(project.metadata, "metadata", lambda name: Stale())
        with pytest.raises(UsageError, match="no \\[project.urls\\] Repository, Card"):
            project.repository_url()
    finally:
        monkeypatch.undo()
        project.project_urls.cache_clear()
    assert project.repository_url().startswith("https://")
