"""The ``odmd-bench`` command line: parse, call the library, print. No logic here."""

from __future__ import annotations

import click

from odmd_bench import __version__


@click.group()
@click.version_option(__version__, prog_name="odmd-bench")
def cli() -> None:
    """odmd-bench: data, evaluation and baselines for ODMD."""


def main() -> None:
    cli()
