#!/usr/bin/env bash
# The wheel users install, tested as they get it (called by scripts/check.sh, so CI runs it):
#   1. build it from the tracked and not-ignored files (no stale build/ folder can leak in);
#   2. check what it holds: odmd_bench and odmd_bench_baselines only (nothing of tests/,
#      leaderboard/ or benchmarks/), every .py file of odmd_bench/ and baselines/, every
#      shipped DBox weights file, and torch, matplotlib and Jinja2 required by extras only;
#   3. install it into a fresh venv, and from a folder outside the repository, with a data
#      folder of its own, run generate, baseline box-ls and dbox, evaluate and import;
#   4. install it into a second venv where torch, matplotlib and Jinja2 cannot be imported: generate,
#      box-ls, evaluate, compare, import and the leaderboard check (CI's gate: every entry
#      re-scored from its committed predictions) run, and `baseline dbox`, `train-dbox`,
#      `plot` and `leaderboard site` exit 2 naming the extra to install;
#   5. run the whole test suite, once, on the first venv's installed wheel (not the checkout): the
#      one pass of the suite that scripts/check.sh makes (its progress shown as it runs).
# The venvs reuse the dependencies already installed in the running Python's environment
# (a .pth file pointing at its site-packages) and install the wheel with --no-deps, by the
# running environment's pip (none is installed into them): nothing is downloaded. The
# original release ($ODMD_ORIGINAL, default ../shared/odmd-original) is needed for import and
# the leaderboard check: in CI (CI=true) it must be there, elsewhere those steps are skipped
# with a line.
set -euo pipefail
cd "$(dirname "$0")/.."
repo=$PWD
py=$(command -v python)
work=$(mktemp -d)
audits=""  # the background re-run of the audits (section 3), stopped if the script ends first
trap '[ -z "$audits" ] || kill "$audits" 2>/dev/null; rm -rf "$work"' EXIT
start=$SECONDS
original="${ODMD_ORIGINAL:-../shared/odmd-original}"
if [ -d "$original" ]; then
    original=$(cd "$original" && pwd)
elif [ "${CI:-}" = "true" ]; then
    echo "check_wheel: the original ODMD release is not at $original; CI must have it" >&2
    exit 1
else
    original=""
fi

fail() {
    echo "check_wheel: FAILED: $*" >&2
    exit 1
}
lap=$SECONDS
took() {  # took WHAT: how long since the last call
    echo "  ($1: $((SECONDS - lap)) s)"
    lap=$SECONDS
}

# --- 1. build ----------------------------------------------------------------------------
mkdir "$work/src"
git rev-parse --git-dir >/dev/null 2>&1 || fail "not a git checkout: the wheel is built from the files git lists"
git ls-files -z --cached --others --exclude-standard \
    | while IFS= read -r -d '' f; do [ -f "$f" ] && printf '%s\0' "$f"; done \
    | tar --null -T - -cf - | tar -xf - -C "$work/src"
# The running environment's setuptools builds it when recent enough (no download).
isolation=()
if "$py" -c 'import setuptools, sys; sys.exit(int(setuptools.__version__.split(".")[0]) < 77)' 2>/dev/null; then
    isolation=(--no-build-isolation)
fi
"$py" -m pip wheel -q --no-deps "${isolation[@]}" "$work/src" -w "$work/dist" >"$work/build.log" 2>&1 \
    || { cat "$work/build.log" >&2; fail "the wheel does not build"; }
wheel=$(ls "$work"/dist/*.whl)
took "the wheel built"

# --- 2. what it holds ----------------------------------------------------------------------
"$py" - "$wheel" "$work/src" <<'EOF' || fail "the wheel's contents (above)"
import re
import sys
import textwrap
import zipfile
from pathlib import Path

wheel, src = sys.argv[1], Path(sys.argv[2])
with zipfile.ZipFile(wheel) as z:
    names = set(z.namelist())
    meta = next(n for n in names if n.endswith(".dist-info/METADATA"))
    metadata = z.read(meta).decode()
    entry_points = z.read(meta.replace("METADATA", "entry_points.txt")).decode()
tops: dict[str, list[str]] = {}
for n in sorted(names):
    top, _, rest = n.partition("/")
    tops.setdefault(top, []).append(rest)
print(f"{Path(wheel).name}: {len(names)} files")
for top, files in tops.items():
    print(textwrap.fill(" ".join(files), 100, initial_indent=f"  {top}/ ({len(files)}): ", subsequent_indent="      "))
problems = []
stray = sorted(t for t in tops if t not in ("odmd_bench", "odmd_bench_baselines") and not t.endswith(".dist-info"))
if stray:
    problems.append(f"top-level entries other than the two packages: {', '.join(stray)}")
for folder in ("tests", "leaderboard", "benchmarks", "baselines", "splits"):
    if any(n.startswith(folder + "/") for n in names):
        problems.append(f"the repository's {folder}/ is in the wheel")
# Where each source folder lands in the wheel (pyproject's package-dir).
where = {"odmd_bench": "odmd_bench", "baselines": "odmd_bench_baselines", "splits": "odmd_bench/splits"}
missing = [
    str(p.relative_to(src))
    for folder in where
    for p in sorted((src / folder).rglob("*.py"))
    if f"{where[folder]}/{p.relative_to(src / folder).as_posix()}" not in names
]
if missing:
    problems.append(f"{len(missing)} .py files are not in the wheel: {', '.join(missing)}")
# Every shipped DBox checkpoint and record, in subfolders too (weights/selected-on-*/).
weights = src / "baselines" / "dbox" / "weights"
lost = [
    str(p.relative_to(src))
    for p in sorted(weights.rglob("*"))
    if p.is_file() and f"odmd_bench_baselines/dbox/weights/{p.relative_to(weights).as_posix()}" not in names
]
if lost:
    problems.append(f"{len(lost)} shipped weights files are not in the wheel: {', '.join(lost)}")
requires = re.findall(r"^Requires-Dist: (.*)$", metadata, flags=re.M)
for req in requires:
    name = re.match(r"[A-Za-z0-9._-]+", req).group(0).lower()
    if name in ("torch", "matplotlib", "jinja2") and "extra ==" not in req:
        problems.append(f"{name} is required without an extra: {req}")
print("Requires-Dist:", "; ".join(requires))
methods = re.search(r"^\[odmd_bench\.methods\]\n((?:.+\n?)*)", entry_points, flags=re.M)
print("methods:", ", ".join(line.split("=")[0].strip() for line in methods.group(1).splitlines()) if methods else "none")
if not methods:
    problems.append("no entry points in the group odmd_bench.methods")
for p in problems:
    print(f"  PROBLEM: {p}", file=sys.stderr)
sys.exit(1 if problems else 0)
EOF
took "its contents checked"

# --- 3. installed apart, run from elsewhere --------------------------------------------------
deps=$("$py" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')
make_venv() {  # make_venv DIR [BLOCKED_MODULE...]: a venv with the wheel, deps from $deps
    local dir=$1
    shift
    "$py" -m venv --without-pip "$dir"  # the running pip installs into it (pip --python): no ensurepip
    local sp
    sp=$("$dir/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')
    echo "$deps" >"$sp/deps.pth"
    if [ $# -gt 0 ]; then  # a .pth line runs at start-up: these modules cannot be imported
        printf 'import sys; sys.modules.update(dict.fromkeys((%s)))\n' "$(printf '"%s",' "$@")" >"$sp/blocked.pth"
    fi
    "$py" -m pip --python "$dir/bin/python" install -q --no-deps --ignore-installed "$wheel" >"$work/install.log" 2>&1 \
        || { cat "$work/install.log" >&2; fail "the wheel does not install into $dir"; }
}
make_venv "$work/full"
make_venv "$work/base" torch matplotlib jinja2 markupsafe
took "two venvs made"
mkdir "$work/run"
cd "$work/run"  # outside the repository: only the installed wheel can be imported
export ODMD_BENCH_DATA="$work/data"
unset PYTHONPATH

run() {  # run VENV ARGS...: odmd-bench of that venv, its output kept on failure
    local venv=$1
    shift
    echo "  [$venv] odmd-bench $*"
    "$work/$venv/bin/odmd-bench" "$@" >"$work/out" 2>&1 || { cat "$work/out" >&2; fail "[$venv] odmd-bench $*"; }
}

where=$("$work/full/bin/python" -c 'import odmd_bench, odmd_bench_baselines; print(odmd_bench.__file__, odmd_bench_baselines.__file__)')
case "$where" in
    "$work/full/"*" $work/full/"*) ;;
    *) fail "the venv imports odmd-bench from elsewhere: $where" ;;
esac
echo "installed wheel, full (torch and matplotlib from the running environment):"
run full --version
run full generate --split test
run full baseline box-ls -o box.csv
run full baseline dbox -o dbox.csv
run full evaluate box.csv
run full evaluate dbox.csv
run full select-dbox --help
if [ -n "$original" ]; then
    run full import "$original"
else
    echo "  SKIPPED import: the original ODMD release is not at ${ODMD_ORIGINAL:-../shared/odmd-original} (set ODMD_ORIGINAL); CI runs it"
fi
took "the full venv's commands"

echo "installed wheel, base (torch, matplotlib and Jinja2 cannot be imported):"
"$work/base/bin/python" -c 'import sys
for m in ("torch", "matplotlib", "jinja2"):
    try:
        __import__(m)
    except ImportError:
        continue
    sys.exit(m + " can be imported")' || fail "the base venv can import torch, matplotlib or jinja2"
rm -rf "$ODMD_BENCH_DATA/odmd-v1"  # generated again, without torch
run base generate --split test
run base baseline box-ls -o box-base.csv
cmp -s box.csv box-base.csv || fail "box-ls gives other predictions without torch"
run base evaluate box-base.csv
run base compare box.csv dbox.csv
if [ -n "$original" ]; then
    run base import "$original" --data-dir "$work/data-base"
    # CI's leaderboard gate: every entry re-scored from its committed predictions (a line per board).
    run base leaderboard check --root "$repo/leaderboard" --original "$original"
    grep -v "up to date" "$work/out" | sed 's/^/    /'
    # The recorded fresh-seed audits re-run (they run DBox, so in the venv with torch): a
    # committed audit that a re-run does not give fails. On one thread, as the test suite's
    # workers (two threads cost it a fifth more CPU), and on the other core while the commands
    # below run: the check above imported what the data folder lacked, so none of them writes there.
    OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 MKL_NUM_THREADS=1 "$work/full/bin/odmd-bench" leaderboard check \
        --audits --root "$repo/leaderboard" --original "$original" >"$work/audits.out" 2>&1 &
    audits=$!
    # The core install builds the views too (not committed): the plot is skipped, and said.
    run base leaderboard build --root "$repo/leaderboard" --original "$original" -o "$work/views"
    grep -q "skipped the plot" "$work/out" && [ -s "$work/views/leaderboard.json" ] \
        || { cat "$work/out" >&2; fail "[base] leaderboard build did not write the views without the plot"; }
else
    echo "  SKIPPED leaderboard check: no original release (see above)"
fi
needs_extra() {  # needs_extra EXTRA WHAT ARGS...: the command must exit 2 naming the extra
    local extra=$1 what=$2
    shift 2
    echo "  [base] odmd-bench $what (must exit 2 naming the extra)"
    set +e
    "$work/base/bin/odmd-bench" "$@" >"$work/out" 2>&1
    local status=$?
    set -e
    grep -qF "pip install 'odmd-bench[$extra]'" "$work/out" && [ $status -eq 2 ] \
        || { cat "$work/out" >&2; fail "[base] $what exited $status, without naming the [$extra] extra"; }
    sed 's/^/    /' "$work/out"
}
needs_extra dbox "baseline dbox" baseline dbox -o dbox-base.csv
[ ! -e dbox-base.csv ] || fail "[base] baseline dbox wrote a file"
needs_extra dbox "train-dbox" train-dbox --steps 1 --out train-base
needs_extra plot "plot" plot box.csv --set normal -o fig.png
needs_extra site "leaderboard site" leaderboard site -o site-base
[ ! -e site-base ] || fail "[base] leaderboard site wrote a folder"
if [ -n "$original" ]; then
    echo "  [full] odmd-bench leaderboard check --audits --root $repo/leaderboard --original $original (run beside the commands above)"
    wait "$audits" || { cat "$work/audits.out" >&2; fail "[full] odmd-bench leaderboard check --audits"; }
    audits=""
    grep -v "up to date" "$work/audits.out" | sed 's/^/    /'
fi
took "the base venv's commands"

# --- 4. the test suite on the installed wheel ------------------------------------------------
# From the repository (the tests read its leaderboard, docs and ../shared), with -P so that
# the checkout's odmd_bench/ is not put before the installed one: what users get is tested.
echo "installed wheel, full: the test suite"
cd "$repo"
where=$("$work/full/bin/python" -P -c 'import odmd_bench, odmd_bench_baselines; print(odmd_bench.__file__, odmd_bench_baselines.__file__)')
case "$where" in
    "$work/full/"*" $work/full/"*) ;;
    *) fail "from the repository, the venv imports odmd-bench from elsewhere: $where" ;;
esac
# PYTHONSAFEPATH=1 is -P for the Python processes the tests start too (`python -m odmd_bench`,
# `python -c ...` from the checkout): they import the installed wheel as well. The suite runs
# on two worker processes (pytest-xdist), a test file to a worker (--dist loadfile: a file's
# module fixtures, a board, a site, a browser, DBox's scores, are made by one worker, not by
# both), each on one thread (two workers with two BLAS/OpenMP threads each on 2 cores spend
# CPU waiting on each other; a test that sets its threads still does); its progress and its
# slowest tests are shown; pytest's cache stays off (the checkout may be read-only).
OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 MKL_NUM_THREADS=1 PYTHONSAFEPATH=1 \
    "$work/full/bin/python" -P -m pytest -p no:cacheprovider -n 2 --dist loadfile --durations=10 \
    || fail "the test suite on the installed wheel"
took "the test suite"
echo "check_wheel: OK ($((SECONDS - start)) s)"
