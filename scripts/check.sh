#!/usr/bin/env bash
# The project's checks, in the order a failure is cheapest to read:
# lint, format, types, the test suite, the installed wheel, then the leaderboard re-scoring.
set -euo pipefail
cd "$(dirname "$0")/.."
ruff check .
ruff format --check .
# mypy reads packages from folders, not from the editable install's import hook: map
# baselines/ to the name it is installed under.
stubs=$(mktemp -d)
trap 'rm -rf "$stubs"' EXIT
ln -s "$PWD/baselines" "$stubs/odmd_bench_baselines"
MYPYPATH="$stubs" mypy
pytest
# The wheel as users install it: contents, and the commands run from it outside the repository,
# with and without torch (scripts/check_wheel.sh says what it checks).
bash scripts/check_wheel.sh
# Re-score every leaderboard entry from its committed predictions; fails on any difference.
# The odmd-paper entries need the original release; in CI (CI=true) it must be there.
original="${ODMD_ORIGINAL:-../shared/odmd-original}"
if [ -d "$original" ] || [ "${CI:-}" = "true" ]; then
    odmd-bench leaderboard check --original "$original"
else
    echo "SKIPPED leaderboard check: the original ODMD release is not at $original (set ODMD_ORIGINAL); CI runs it"
fi
