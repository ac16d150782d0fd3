"""The ``odmd-bench`` command line: parse, call the library, print. No logic here.

Each area's commands live in ``odmd_bench/commands/<area>.py`` and are added below.
Errors: the package's own exceptions (bad input, bad usage) print a one-pass report
and exit 2; click's usage errors exit 2; anything else is a bug and exits 1.
"""

from __future__ import annotations

import sys
import traceback
from typing import Any

import click

from odmd_bench import __version__
from odmd_bench.errors import OdmdError


class _Group(click.Group):
    def invoke(self, ctx: click.Context) -> Any:
        try:
            return super().invoke(ctx)
        except OdmdError as e:
            click.echo(f"error: {e.render()}", err=True)
            ctx.exit(2)
        except (click.exceptions.Exit, click.exceptions.Abort, click.ClickException):
            raise
        except KeyboardInterrupt:
            click.echo("interrupted; no partial file was left behind", err=True)
            ctx.exit(130)
        except Exception:
            click.echo(
                "internal error (a bug in odmd-bench; please report it with this trace):\n"
                + traceback.format_exc(),
                err=True,
            )
            ctx.exit(1)


@click.group(cls=_Group)
@click.version_option(__version__, prog_name="odmd-bench")
def cli() -> None:
    """odmd-bench: data, evaluation and baselines for ODMD (Griffin and Corso, CVPR 2021)."""
    import logging

    handler = logging.StreamHandler()
    handler.setFormatter(logging.Formatter("%(message)s"))
    logger = logging.getLogger("odmd_bench")
    if not logger.handlers:
        logger.addHandler(handler)
    logger.setLevel(logging.INFO)


def _register() -> None:
    from odmd_bench.cli import baseline, data, dbox, evaluate, leaderboard

    for module in (data, baseline, evaluate, leaderboard, dbox):
        for command in module.COMMANDS:
            cli.add_command(command)


_register()


def main() -> None:
    sys.exit(cli.main(standalone_mode=True))
