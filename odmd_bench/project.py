"""Where the project lives and how to cite it.

The addresses are configured in one place, ``[project.urls]`` of ``pyproject.toml``, and read
here from the installed distribution's metadata (``importlib.metadata``), so that the site's
footer, the Croissant descriptions and the exported results all name the same addresses. To
move the project, change them there and reinstall (``pip install -e .``); ``CITATION.cff``
and ``.zenodo.json`` repeat them, and ``tests/test_citation.py`` fails until they agree.

Example:
    >>> from odmd_bench.project import repository_url
    >>> repository_url().startswith("https://")
    True
"""

from __future__ import annotations

from functools import cache
from importlib import metadata

from odmd_bench._version import __version__
from odmd_bench.errors import UsageError

#: The distribution whose metadata holds the addresses.
DISTRIBUTION = "odmd-bench"

#: The ``[project.urls]`` labels the package reads: the site, the code, the benchmark card.
SITE, REPOSITORY, CARD = "Homepage", "Repository", "Card"

#: The paper that introduced the benchmark (cite it for the benchmark itself).
PAPER_BIBTEX = """@inproceedings{GrCoCVPR21,
  title     = {Depth from Camera Motion and Object Detection},
  author    = {Griffin, Brent A. and Corso, Jason J.},
  booktitle = {Proceedings of the IEEE/CVF Conference on Computer Vision and Pattern Recognition (CVPR)},
  year      = {2021},
  doi       = {10.48550/arXiv.2103.01468}
}"""

#: How the paper is named in one line.
PAPER_TEXT = (
    "Brent A. Griffin and Jason J. Corso. Depth from Camera Motion and Object Detection. CVPR 2021. "
    "doi:10.48550/arXiv.2103.01468"
)


@cache
def project_urls() -> dict[str, str]:
    """``{label: address}`` of ``[project.urls]``, as installed.

    Raises:
        UsageError: When the distribution is not installed, or its metadata lacks one of
            the labels the package reads (an install older than the addresses: reinstall).
    """
    try:
        raw = metadata.metadata(DISTRIBUTION).get_all("Project-URL") or []
    except metadata.PackageNotFoundError:
        raise UsageError(
            f"{DISTRIBUTION} is not installed, so its addresses are unknown; pip install -e ."
        ) from None
    urls = {}
    for line in raw:
        label, _, url = line.partition(",")
        urls[label.strip()] = url.strip()
    missing = [k for k in (SITE, REPOSITORY, CARD) if not urls.get(k)]
    if missing:
        raise UsageError(
            f"the installed {DISTRIBUTION} metadata has no [project.urls] {', '.join(missing)}; "
            "reinstall it (pip install -e .)"
        )
    return urls


def site_url() -> str:
    """The leaderboard site's address, ending in ``/``."""
    return project_urls()[SITE].rstrip("/") + "/"


def repository_url() -> str:
    """The source repository's address (no trailing ``/``)."""
    return project_urls()[REPOSITORY].rstrip("/")


def card_url() -> str:
    """The benchmark card's address."""
    return project_urls()[CARD]


def software_bibtex(version: str = __version__) -> str:
    """BibTeX for this package at ``version`` (cite it for results computed with it)."""
    return (
        "@software{odmd_bench,\n"
        "  title   = {odmd-bench: the ODMD benchmark as a package},\n"
        "  author  = {{The odmd-bench authors}},\n"
        f"  version = {{{version}}},\n"
        f"  url     = {{{repository_url()}}}\n"
        "}"
    )


def citation_text(version: str = __version__) -> str:
    """One paragraph saying what to cite: the paper, and the package with its version."""
    return f"{PAPER_TEXT}; and odmd-bench {version}, {repository_url()}."


__all__ = [
    "CARD",
    "DISTRIBUTION",
    "PAPER_BIBTEX",
    "PAPER_TEXT",
    "REPOSITORY",
    "SITE",
    "card_url",
    "citation_text",
    "project_urls",
    "repository_url",
    "site_url",
    "software_bibtex",
]
