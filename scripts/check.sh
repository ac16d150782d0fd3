#!/usr/bin/env bash
# The project's checks, in the order a failure is cheapest to read: lint, format, types, the API
# reference, then the wheel as users install it: its contents, its commands run outside the
# repository (the leaderboard re-scoring among them), and the whole test suite, run once, on it.
# Each step says how long it took; about 4 minutes in all on 2 idle cores (docs/development.md).
set -euo pipefail
cd "$(dirname "$0")/.."
start=$SECONDS
step() {  # step NAME COMMAND...: run it, then say how long it took
    local name=$1 t=$SECONDS
    shift
    echo "--- $name"
    "$@"
    echo "--- $name: ok, $((SECONDS - t)) s ($((SECONDS - start)) s in all)"
}
step "ruff check" ruff check .
step "ruff format --check" ruff format --check .
# mypy reads packages from folders, not from the editable install's import hook: map
# baselines/ to the name it is installed under.
stubs=$(mktemp -d)
api=$(mktemp -d)
trap 'rm -rf "$stubs" "$api"' EXIT
ln -s "$PWD/baselines" "$stubs/odmd_bench_baselines"
step "mypy" env MYPYPATH="$stubs" mypy
# The API reference from the docstrings (pdoc), into a temporary folder: any warning fails.
step "API reference (pdoc)" python scripts/api_docs.py "$api"
# The wheel as users install it: contents, the commands run from it outside the repository with
# and without torch, the leaderboard re-scoring, and the test suite (scripts/check_wheel.sh).
step "the installed wheel and the test suite" bash scripts/check_wheel.sh
echo "check: OK ($((SECONDS - start)) s)"
