#!/usr/bin/env bash
# DBox on one GPU: the CUDA tests, the speed benchmark (GPU against the CPU), and one
# training run of config p sized to a wall-clock budget, scored on odmd-v1 test.
#
# usage: scripts/gpu_measure.sh OUT_DIR [TRAIN_SECONDS [TRAIN_OPTION...]]
#   e.g. scripts/gpu_measure.sh out 150 --cuda-graph
#   GPU_BENCH_SELECT: a pytest -k expression choosing the benchmark's cases (default: all)
#
# Run from the repository root on a machine with a CUDA GPU and odmd-bench installed
# (torch included). Every step runs even when an earlier one fails; each writes its log
# into OUT_DIR. The run's steps are TRAIN_SECONDS (default 240) times the steps per
# second that the benchmark measured for `--data device` fp32 (with --cuda-graph: for
# the graphed case), times 0.9 (the validation
# checks take the rest); the learning rate follows the usual cosine over those steps.
# OUT_DIR gets seven files: gpu.txt, tests.log, bench.json, bench.log, train.log,
# evaluate.txt and run.tgz (the run's weights, records and log.jsonl).
set -uo pipefail
out=${1:?usage: scripts/gpu_measure.sh OUT_DIR [TRAIN_SECONDS]}
budget=${2:-240}
shift $(( $# > 1 ? 2 : 1 ))
case=cuda-device-fp32
[[ " $* " == *" --cuda-graph "* ]] && case=cuda-device-graph
mkdir -p "$out"
export PYTHONUNBUFFERED=1
work=$(mktemp -d)
data="$work/data"

nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv 2>&1 | tee "$out/gpu.txt"
python3 -c 'import torch; print("torch", torch.__version__, "cuda", torch.version.cuda)' 2>&1 | tee -a "$out/gpu.txt"
grep -m1 "model name" /proc/cpuinfo | tee -a "$out/gpu.txt"
nproc | tee -a "$out/gpu.txt"

echo "== CUDA tests"
python3 -m pytest tests/test_dbox_device_data.py tests/test_dbox_distributed.py -k cuda \
    -p no:randomly -p no:cacheprovider -q -rs 2>&1 | tee "$out/tests.log"

echo "== speed"
python3 -m pytest benchmarks/bench_dbox_gpu.py --benchmark-only -p no:randomly -p no:cacheprovider -s -q \
    -k "${GPU_BENCH_SELECT:-}" --benchmark-json "$out/bench.json" 2>&1 | tee "$out/bench.log"

rate=$(python3 - "$out/bench.json" "$case" <<'EOF'
import json, sys
try:
    runs = json.load(open(sys.argv[1]))["benchmarks"]
    print(next(b["extra_info"]["steps_per_s"] for b in runs if b["name"].endswith(f"[{sys.argv[2]}]")))
except Exception:
    print(100)
EOF
)
steps=$(python3 -c "print(max(1000, int($rate * $budget * 0.9) // 1000 * 1000))")
echo "== training: $steps steps (measured $rate steps/s, budget $budget s)"
odmd-bench generate --data-dir "$data" 2>&1 | tail -3
odmd-bench train-dbox --config p --device cuda --steps "$steps" --seed 0 --out "$work/run" --data-dir "$data" "$@" \
    2>&1 | tr '\r' '\n' | tee "$out/train.log" | awk 'NR % 20 == 0' | tail -20
odmd-bench baseline dbox --weights "$work/run/dbox_p.pt" --device cuda --data-dir "$data" -o "$work/preds_p.csv" \
    2>&1 | tee "$out/evaluate.txt"
odmd-bench evaluate "$work/preds_p.csv" --data-dir "$data" 2>&1 | tee -a "$out/evaluate.txt"
rm -f "$work/run/last.pt"
tar -czf "$out/run.tgz" -C "$work" run
rm -rf "$work"
