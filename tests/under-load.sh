#!/usr/bin/env bash
# The proof that load cannot fail the CI: clones this repository fresh into a temporary
# folder and runs its `.ci/run` there while busy processes (plain CPU burners, `sh -c
# 'while :; do :; done'`, twice as many as the machine has cores by default) load every
# core; records each run's duration and result; repeats.
#
#   bash tests/under-load.sh [--runs N] [--burners K] [--stage 'COMMAND'] [--keep]
#
#   --runs N      how many loaded runs, one after the other (default 1);
#   --burners K   how many CPU burners beside each run (default: 2 per core, 4 on the
#                 two-core machines CI runs on);
#   --stage CMD   run CMD (a command line, run by bash in the clone) instead of the whole
#                 `.ci/run`: one board-facing stage of tests/run-all.sh, e.g.
#                 'bash host-sim/operator/tests/against-emulator.sh';
#   --keep        keep the clones (default: each is removed after its run).
#
# The clone is of the committed HEAD (what CI would check out), built from nothing in its
# own target directories: the run takes as long as a fresh CI run under that load (each
# burner weighs as much as each process of the run, so beside four burners on two cores a
# run with two busy processes gets a third of the machine). Every run checks out the commit
# that was HEAD when the script started, whatever is committed meanwhile. Each run's output
# is kept in the report folder (target/under-load/ of this checkout, or $UNDER_LOAD_OUT),
# with runs.tsv: run, started, seconds, exit status, result. Exits non-zero when any run failed.
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
runs=1
burners=$(($(nproc) * 2))
stage=""
keep=0
while [ $# -gt 0 ]; do
    case "$1" in
    --runs) runs="$2"; shift 2 ;;
    --burners) burners="$2"; shift 2 ;;
    --stage) stage="$2"; shift 2 ;;
    --keep) keep=1; shift ;;
    -h | --help) sed -n '2,23p' "$0"; exit 0 ;;
    *) echo "unknown option $1 (see --help)" >&2; exit 2 ;;
    esac
done
[[ "$runs" =~ ^[1-9][0-9]*$ ]] || { echo "--runs must be a positive integer" >&2; exit 2; }
[[ "$burners" =~ ^[0-9]+$ ]] || { echo "--burners must be an integer" >&2; exit 2; }

out="${UNDER_LOAD_OUT:-$here/target/under-load}"
mkdir -p "$out"
table="$out/runs.tsv"
printf 'run\tstarted\tseconds\texit\tresult\n' >"$table"

burner_pids=()
clone=""
stop_burners() {
    local p
    for p in "${burner_pids[@]}"; do kill "$p" 2>/dev/null || true; done
    for p in "${burner_pids[@]}"; do wait "$p" 2>/dev/null || true; done
    burner_pids=()
}
cleanup() {
    stop_burners
    if [ -n "$clone" ] && [ "$keep" -eq 0 ]; then rm -rf "$clone"; fi
}
trap cleanup EXIT
trap 'exit 130' INT
trap 'exit 143' TERM

start_burners() {
    local i
    for i in $(seq "$burners"); do
        sh -c 'while :; do :; done' &
        burner_pids+=("$!")
    done
}

what="${stage:-.ci/run}"
commit="$(git -C "$here" rev-parse HEAD)"
echo "under load: $runs run(s) of '$what' in a fresh clone of ${commit:0:7}, beside $burners CPU burners on $(nproc) cores; report in $out"
failed=0
for run in $(seq "$runs"); do
    clone="$(mktemp -d "${TMPDIR:-/tmp}/rspr-under-load-XXXXXX")"
    git clone -q --no-hardlinks "$here" "$clone/repo"
    git -C "$clone/repo" checkout -q "$commit"
    log="$out/run-$run.log"
    started="$(date -Is)"
    t0=$(date +%s)
    start_burners
    status=0
    # The clone builds in its own target directories, however this shell was set up.
    (cd "$clone/repo" && env -u CARGO_TARGET_DIR CARGO_INCREMENTAL=0 \
        bash -c "${stage:-bash .ci/run}") >"$log" 2>&1 || status=$?
    stop_burners
    seconds=$(($(date +%s) - t0))
    result=PASS
    [ "$status" -eq 0 ] || { result=FAIL; failed=1; }
    printf '%s\t%s\t%s\t%s\t%s\n' "$run" "$started" "$seconds" "$status" "$result" >>"$table"
    echo "run $run: $result in $seconds s (exit $status; log $log)"
    if [ "$keep" -eq 0 ]; then rm -rf "$clone"; fi
    clone=""
done
echo "--- runs"
column -t -s $'\t' "$table"
exit "$failed"
