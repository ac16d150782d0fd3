"""docs/pages-workflow.yml: valid, triggered by pushes to main, and every command and option it calls exists.

The steps that set up the machine (``uses:``, ``pip install``, ``git clone``) are not
run; every ``odmd-bench`` command line of the others is resolved against the CLI, down to
each option, so that a renamed command or option fails here, not on the first push.
"""

from __future__ import annotations

import shlex
from pathlib import Path
from typing import Any

import click
import pytest
import yaml

from odmd_bench.cli.main import cli

WORKFLOW = Path(__file__).resolve().parents[1] / "docs" / "pages-workflow.yml"


def _workflow() -> dict[str, Any]:
    data = yaml.safe_load(WORKFLOW.read_text(encoding="utf-8"))
    assert isinstance(data, dict)
    return data


def _commands() -> list[list[str]]:
    """Every odmd-bench command line of the build job's run steps, as words."""
    out = []
    for step in _workflow()["jobs"]["build"]["steps"]:
        for line in step.get("run", "").splitlines():
            words = shlex.split(line, comments=True)
            if words[:1] == ["odmd-bench"]:
                out.append(words[1:])
    return out


def _missing(words: list[str]) -> list[str]:
    """What a command line (after ``odmd-bench``) calls that does not exist: its command or options."""
    command: click.Command = cli
    # each context made as the command line makes it: a parent's settings (-h) are inherited,
    # and click caches a command's help option from the first context it is given
    ctx = cli.make_context("odmd-bench", [], resilient_parsing=True)
    while isinstance(command, click.Group) and words and not words[0].startswith("-"):
        sub = command.get_command(ctx, words[0])
        if sub is None:
            return [f"command {words[0]!r}"]
        command, words = sub, words[1:]
        if isinstance(command, click.Group):
            ctx = command.make_context(command.name or "", [], parent=ctx, resilient_parsing=True)
    options = {o for p in command.params for o in (*p.opts, *p.secondary_opts)}
    missing = [
        f"option {w}" for w in (w.split("=")[0] for w in words if w.startswith("-")) if w not in options
    ]
    if not missing:
        left = command.make_context(command.name or "", list(words), parent=ctx, resilient_parsing=True).args
        missing += [f"argument {a!r}" for a in left]
    return missing


def test_the_workflow_builds_on_pushes_to_main_and_deploys_what_it_built() -> None:
    workflow = _workflow()
    triggers = workflow.get("on", workflow.get(True))  # YAML 1.1 reads the key `on` as True
    assert triggers["push"] == {"branches": ["main"]}
    assert workflow["permissions"] == {"contents": "read", "pages": "write", "id-token": "write"}
    build, deploy = workflow["jobs"]["build"], workflow["jobs"]["deploy"]
    steps = {s["name"]: s for s in build["steps"]}
    assert list(steps) == [
        "Check out",
        "Set up Python",
        "Install",
        "Get the original release",
        "Check the board",
        "Build the site",
        "Upload the site",
    ]
    site = shlex.split(steps["Build the site"]["run"])
    assert steps["Upload the site"]["uses"].startswith("actions/upload-pages-artifact@")
    assert steps["Upload the site"]["with"]["path"] == site[site.index("-o") + 1]
    assert "$ODMD_ORIGINAL" in steps["Get the original release"]["run"] and "ODMD_ORIGINAL" in build["env"]
    assert deploy["needs"] == "build" and deploy["environment"]["name"] == "github-pages"
    assert [s["uses"].split("@")[0] for s in deploy["steps"]] == ["actions/deploy-pages"]


def test_every_command_and_option_it_calls_exists() -> None:
    commands = _commands()
    assert [w[:2] for w in commands] == [["leaderboard", "check"], ["leaderboard", "site"]]
    assert "--source-url" in commands[1]
    for words in commands:
        assert _missing(words) == [], words


@pytest.mark.parametrize(
    ("bad", "missing"),
    [
        (["leaderboard", "sight", "-o", "x"], ["command 'sight'"]),
        (["leaderboard", "site", "--out-dir", "x"], ["option --out-dir"]),
        (["leaderboard", "check", "extra"], ["argument 'extra'"]),
    ],
)
def test_the_check_finds_a_command_or_option_that_does_not_exist(bad: list[str], missing: list[str]) -> None:
    assert _missing(bad) == missing
