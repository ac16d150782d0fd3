#!/usr/bin/env bash
# The sequences reader of an earlier commit against this checkout's, alternating, on one
# machine: benchmarks/bench_predict.py's test_parse (read_sequences on the benchmark's
# 1,000,000-row file), the earlier package put first on PYTHONPATH.
#
#   bash scripts/parse_before_after.sh 53fee02 [ROUNDS]
#
# Prints the best and the median time of each side in each round (one core: OpenBLAS
# kept to one thread). Run it from the repository root, in the checkout's environment.
set -euo pipefail
rev=${1:?usage: parse_before_after.sh REV [ROUNDS]}
rounds=${2:-3}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
git archive "$rev" | tar -x -C "$work"
for round in $(seq "$rounds"); do
  for side in before after; do
    if [ "$side" = before ]; then path=$work; else path=$PWD; fi
    OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 PYTHONPATH=$path python -m pytest benchmarks/bench_predict.py \
      -k "test_parse and not careful" --benchmark-only -p no:randomly -q \
      --benchmark-json="$work/$side-$round.json" > "$work/$side-$round.log" 2>&1
    python - "$work/$side-$round.json" "$side" "$round" <<'PY'
import json, sys
stats = json.load(open(sys.argv[1]))["benchmarks"][0]["stats"]
print(f"{sys.argv[2]:6s} round {sys.argv[3]}: best {stats['min']:.3f} s, median {stats['median']:.3f} s")
PY
  done
done
