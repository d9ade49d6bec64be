#!/usr/bin/env bash
# Issue 20's corrected user's bound on the device, in ONE call of at most ~420 s:
#   1. tests_bound (110 s): pytest -m gpu on the bound's test file (with the regression test of
#      two cut-overs, the second at the first's lb) and the cut-over's two files;
#   2. tests_suite (170 s): pytest -m gpu over tests/daemon/planning but harmonic (issue 21's
#      own check) and the files of step 1, test by test (-v), so a cut-off run still says
#      which tests passed;
#   3. bench_new1, bench_base1, bench_new2, bench_base2 (30, 40, 30, 30 s): the 400² walk of the four
#      scenarios, this tree then main's ($BASE, a `git archive` of main), alternated so that
#      the machine's drift shows as the spread between the pairs.
# Every step's output is written to $OUT/<step>.log as it runs and the tarball
# $OUT/tail17_check.tar.gz is written again after every step, so what ran before a limit or a
# lost call comes back. Usage on the device, from this tree's root:
#   BASE=../tail17_base TREE=<commit> BASE_TREE=<commit> bash scripts/tail17_check.sh
set -uo pipefail
cd "$(dirname "$0")/.."
OUT=${OUT:-out/tail17_check}
BASE=${BASE:-../tail17_base}
mkdir -p "$OUT"
rm -f "$OUT/steps.txt"
source scripts/device_env.sh
SITE=${CLI_SITE:+:$CLI_SITE}
fail=0
{
    nvidia-smi --query-gpu=name,driver_version --format=csv,noheader
    date -u +%Y-%m-%dT%H:%M:%SZ
    echo "tree ${TREE:-unknown} base ${BASE_TREE:-unknown} ($BASE)"
} | tee "$OUT/device.txt"
# Packed outside $OUT, then moved in: tar fails on a folder that changes while it reads it.
pack() { tar -czf "${TMPDIR:-/tmp}/tail17_check.tar.gz" -C "$OUT" --exclude=tail17_check.tar.gz . &&
    mv "${TMPDIR:-/tmp}/tail17_check.tar.gz" "$OUT/tail17_check.tar.gz"; }
T=tests/daemon/planning
BOUND="$T/cuda/test_user_bound.py $T/cuda/test_cut_over.py $T/cuda/test_cut_over_rule.py"
ok=1
for f in $BOUND; do [ -f "$f" ] || { echo "missing $f" | tee -a "$OUT/steps.txt"; ok=0; }; done
[ -d "$BASE/daemon" ] || { echo "missing the base tree $BASE" | tee -a "$OUT/steps.txt"; ok=0; }
[ "$ok" -eq 1 ] || { pack; exit 1; }

export PYTHONPATH="$PWD$SITE"
# shellcheck disable=SC2086  # $BOUND: one word per file
step tests_bound 110 python3 -m pytest -m gpu -v -p no:cacheprovider --timeout 100 $BOUND \
    --durations=8
pack
# shellcheck disable=SC2046  # one --ignore per file of step 1
step tests_suite 170 python3 -m pytest -m gpu -v -p no:cacheprovider --timeout 120 "$T" \
    --ignore="$T/harmonic" $(printf -- '--ignore=%s ' $BOUND) --durations=10
pack
bench() {  # bench NAME SECONDS TREE: the 400² walk of the four scenarios on TREE, from its root
    local name=$1 limit=$2 tree=$3
    step "$name" "$limit" env PYTHONPATH="$tree$SITE" bash -c 'cd "$1" && python3 -m cli.app bench \
        --grid 400 --unknown 0.4 --scenario courtyard,explore,building,streets \
        --backend cuda --json "$2"' _ "$tree" "$(cd "$OUT" && pwd)/$name.json"
    pack
}
# The base's first run compiles its kernels (CuPy's cache is keyed by the source): 40 s.
bench bench_new1 30 "$PWD"
bench bench_base1 40 "$(cd "$BASE" && pwd)"
bench bench_new2 30 "$PWD"
bench bench_base2 30 "$(cd "$BASE" && pwd)"
echo "steps: $(tr '\n' ' ' <"$OUT/steps.txt")"
exit "$fail"
