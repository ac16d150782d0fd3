#!/usr/bin/env bash
# Run the two-process test's torchrun command N times and count the failed launches.
#
# usage: scripts/torchrun_loop.sh N      (from the repository root, in a venv with torch)
#
# The command of tests/test_dbox_distributed.py's
# test_two_processes_train_the_weights_of_one_and_only_process_0_writes: config p, 30 steps,
# two processes of one thread, the write watch on. docs/dbox.md ("Leaving") quotes its
# counts, measured with a CPU hog beside it (`yes > /dev/null &`). A failed launch's log
# is kept as torchrun-fail.I.log in the current folder.
set -uo pipefail
n=${1:?usage: scripts/torchrun_loop.sh N}
fails=0
for i in $(seq 1 "$n"); do
  d=$(mktemp -d); mkdir "$d/w"
  env -u RANK -u WORLD_SIZE -u LOCAL_RANK OMP_NUM_THREADS=1 PYTHONFAULTHANDLER=1 PYTHONWARNINGS=error \
    DBOX_TEST_WRITES="$d/w" python -m torch.distributed.run --standalone --nproc_per_node 2 \
    --monitor-interval 0.1 tests/dbox_worker.py train-dbox --config p --steps 30 --val-every 15 --seed 3 \
    --device cpu --threads 1 --out "$d/two" > "$d/log" 2>&1 || { fails=$((fails + 1)); cp "$d/log" "torchrun-fail.$i.log"; }
  rm -rf "$d"
done
echo "failed launches: $fails of $n"
