#!/usr/bin/env bash
# The project's checks, in the order a failure is cheapest to read:
# lint, format, types, the test suite, then the leaderboard re-scoring.
set -euo pipefail
cd "$(dirname "$0")/.."
ruff check .
ruff format --check .
mypy
pytest
# Re-score every leaderboard entry from its committed predictions; fails on any difference.
odmd-bench leaderboard check --original "${ODMD_ORIGINAL:-../shared/odmd-original}"
