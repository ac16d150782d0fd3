#!/usr/bin/env bash
# The project's checks, in the order a failure is cheapest to read: lint, format, types, the API
# reference, then the wheel as users install it: its contents, its commands run outside the
# repository (the leaderboard re-scoring among them), and the whole test suite, run once, on it.
# Each step says how long it took; about 4 minutes in all on 2 idle cores, after the installs (docs/development.md).
set -euo pipefail
cd "$(dirname "$0")/.."
start=$SECONDS
stubs=$(mktemp -d)
api=$(mktemp -d)
trap 'rm -rf "$stubs" "$api"' EXIT
cpu() {  # CPU=seconds of CPU (user + system) used so far by the commands this script ran
    times >"$stubs/times"  # (not in a $(...) subshell, which has no children of its own)
    CPU=$(awk 'NR == 2 { split($1 "m" $2, t, "[ms]+"); printf "%.0f", t[1] * 60 + t[2] + t[3] * 60 + t[4] }' "$stubs/times")
}
step() {  # step NAME COMMAND...: run it, then say how long it took (wall clock, and CPU: on a
    local name=$1 t=$SECONDS c  # busy machine the CPU time is about what it takes alone)
    cpu
    c=$CPU
    shift
    echo "--- $name"
    "$@"
    cpu
    echo "--- $name: ok, $((SECONDS - t)) s, CPU $((CPU - c)) s ($((SECONDS - start)) s in all)"
}
step "ruff check" ruff check .
step "ruff format --check" ruff format --check .
# mypy reads packages from folders, not from the editable install's import hook: map
# baselines/ to the name it is installed under.
mkdir "$stubs/mypy"
ln -s "$PWD/baselines" "$stubs/mypy/odmd_bench_baselines"
step "mypy" env MYPYPATH="$stubs/mypy" mypy
# The API reference from the docstrings (pdoc), into a temporary folder: any warning fails.
step "API reference (pdoc)" python scripts/api_docs.py "$api"
# The wheel as users install it: contents, the commands run from it outside the repository with
# and without torch, the leaderboard re-scoring, and the test suite (scripts/check_wheel.sh).
step "the installed wheel and the test suite" bash scripts/check_wheel.sh
cpu
echo "check: OK ($((SECONDS - start)) s, CPU $CPU s)"
