#!/usr/bin/env bash
# libFuzzer runs of the board's master link (cargo-fuzz): the frame decoder (`decoder`) and
# the board's command handling (`commands`). See fuzz/README.md.
#
#   fuzz/run.sh ci      every target >= 100 000 executions from the seeds, fixed -seed,
#                       fresh corpus; non-zero exit on any crash, timeout or OOM
#   fuzz/run.sh bench   every target >= 10 000 000 executions (corpus kept in
#                       fuzz/corpus/<target>), then every corpus input replayed one by one
#                       for the slowest input time
#   fuzz/run.sh build   only the build (cargo-fuzz installed when missing, seeds generated)
#
# Settings (environment): FUZZ_RUNS (executions per target), FUZZ_SEED (libFuzzer -seed,
# default 1), FUZZ_TARGETS (default "decoder commands"), FUZZ_PARALLEL (1: the targets at
# the same time), FUZZ_SANITIZER (default none: the
# project's crates are safe Rust, see the README), CARGO_TARGET_DIR (default fuzz/target),
# CARGO_FUZZ_ROOT (where cargo-fuzz is installed when missing, default cargo's own bin
# directory), RSPR_FUZZ_STRICT (1: the known findings fail the checks, see the README).
#
# One libFuzzer process per target, no -fork, no -jobs; the targets one after the other, or
# at the same time with FUZZ_PARALLEL=1 (each process uses at most one core).
set -euo pipefail
cd "$(dirname "$0")"
FUZZ_DIR=$PWD

mode=${1:-ci}
case "$mode" in
ci) runs=${FUZZ_RUNS:-100000} ;;
bench) runs=${FUZZ_RUNS:-10000000} ;;
build) runs=0 ;;
*)
    echo "usage: fuzz/run.sh ci|bench|build" >&2
    exit 2
    ;;
esac
seed=${FUZZ_SEED:-1}
read -r -a targets <<<"${FUZZ_TARGETS:-decoder commands}"
sanitizer=${FUZZ_SANITIZER:-none}
target_dir=${CARGO_TARGET_DIR:-$FUZZ_DIR/target}
triple=x86_64-unknown-linux-gnu
bin_dir=$target_dir/$triple/release
seeds=$target_dir/fuzz-seeds
max_len=4096
# Per-input time limit, s: an input running longer is reported as a crash (unbounded work).
timeout_s=10

now() { date +%s.%N; }
elapsed() { awk -v a="$1" -v b="$(now)" 'BEGIN { printf "%.1f", b - a }'; }

# --- tools -------------------------------------------------------------------------------
if ! rustup toolchain list | grep -q '^nightly'; then
    echo "==> installing the nightly toolchain (cargo-fuzz needs it)"
    rustup toolchain install nightly --profile minimal
fi
if [ -n "${CARGO_FUZZ_ROOT:-}" ]; then
    export PATH="$CARGO_FUZZ_ROOT/bin:$PATH"
fi
if ! cargo +nightly fuzz --version >/dev/null 2>&1; then
    echo "==> installing cargo-fuzz${CARGO_FUZZ_ROOT:+ into $CARGO_FUZZ_ROOT}"
    (cd / && cargo install cargo-fuzz --locked ${CARGO_FUZZ_ROOT:+--root "$CARGO_FUZZ_ROOT"})
fi
echo "==> $(cargo +nightly fuzz --version), $(rustc +nightly --version)"
# GNU time: the CPU time and peak RSS of each run (load-independent figures).
if [ ! -x /usr/bin/time ]; then
    echo "==> installing GNU time"
    apt-get install -y -qq time >/dev/null
fi

# --- build -------------------------------------------------------------------------------
t0=$(now)
cargo +nightly fuzz build -O -a -s "$sanitizer" --target-dir "$target_dir"
echo "==> fuzz build (optimised, debug assertions and overflow checks, sanitizer $sanitizer): $(elapsed "$t0") s"
t0=$(now)
cargo build --release --example seeds --example replay --target-dir "$target_dir" --quiet
rm -rf "$seeds"
"$target_dir/release/examples/seeds" "$seeds"
echo "==> seeds build and generation: $(elapsed "$t0") s"
[ "$mode" = build ] && exit 0

# --- runs --------------------------------------------------------------------------------
# Reproducible runs: the same binary, seed and seeds give the same executions, so a crash
# in CI is found again by the same command anywhere. Two things made the commands target's
# runs differ: the comparisons libFuzzer traces for its dictionary (CMP) include pointers,
# whose values change with address-space randomisation (stack addresses 0x7ffe... entered
# the mutations), and -reload (the corpus directory re-read every second, by the clock).
# So: -reload=0, and the run without randomisation (setarch -R) where the machine allows
# it (a container may refuse the personality call: then the run says so).
no_aslr=()
if setarch "$(uname -m)" -R true 2>/dev/null; then
    no_aslr=(setarch "$(uname -m)" -R)
fi

# One target: its run, its figures (into $log.summary), exit status 1 on a crash.
run_target() {
    local t=$1 corpus artifacts log rc=0 wall user sys maxrss_kb cpu execs rate rss slow
    if [ "$mode" = ci ]; then
        corpus=$target_dir/fuzz-ci-corpus/$t
        rm -rf "$corpus"
    else
        corpus=$FUZZ_DIR/corpus/$t
    fi
    artifacts=$FUZZ_DIR/artifacts/$t
    mkdir -p "$corpus" "$artifacts"
    log=$target_dir/fuzz-$mode-$t.log
    {
        echo "==> $t: $runs executions, -seed=$seed, corpus $corpus, log $log"
        if [ ${#no_aslr[@]} -eq 0 ]; then
            echo "    (address-space randomisation on: setarch -R refused here; the run may not repeat exactly)"
        fi
        /usr/bin/time -o "$log.time" -f "%e %U %S %M" \
            "${no_aslr[@]}" "$bin_dir/$t" "$corpus" "$seeds/$t" \
            -dict="$seeds/link.dict" -seed="$seed" -runs="$runs" -reload=0 -max_len=$max_len \
            -timeout=$timeout_s -rss_limit_mb=2048 -print_final_stats=1 \
            -artifact_prefix="$artifacts/" >"$log" 2>&1 || rc=$?
        # (GNU time writes "Command exited with non-zero status N" first after a crash.)
        read -r wall user sys maxrss_kb < <(tail -n 1 "$log.time") || true
        cpu=$(awk -v u="$user" -v s="$sys" 'BEGIN { printf "%.1f", u + s }')
        execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log")
        rate=$(sed -n 's/^stat::average_exec_per_sec: *//p' "$log")
        rss=$(sed -n 's/^stat::peak_rss_mb: *//p' "$log")
        slow=$(sed -n 's/^stat::slowest_unit_time_sec: *//p' "$log")
        echo "    exit $rc; executions ${execs:-?} in $wall s wall, $cpu s CPU (load average" \
            "$(cut -d' ' -f1 /proc/loadavg)); $(awk -v n="${execs:-0}" -v w="$wall" -v c="$cpu" \
                'BEGIN { printf "%.0f exec/s wall, %.0f exec/s CPU", n / w, n / c }')"
        echo "    peak RSS $((${maxrss_kb:-0} / 1024)) MB (libFuzzer: ${rss:-?} MB);" \
            "libFuzzer's slowest unit ${slow:-?} s (whole seconds)"
        if [ "$rc" -ne 0 ]; then
            echo "    FAILED: libFuzzer found a crash, timeout or OOM; its report ($log):"
            grep -E "panicked at|^(duty|STO|assertion)|SUMMARY|Test unit written|timeout|out-of-memory" "$log" |
                head -20 | sed 's/^/    | /'
        elif [ "$mode" = bench ]; then
            # Every corpus input once, timed by libFuzzer itself (instrumented, as fuzzed).
            local slowest n
            slowest=$(find "$corpus" -type f -print0 |
                xargs -0 -n 400 "$bin_dir/$t" -runs=1 2>&1 |
                sed -n 's/^Executed \(.*\) in \([0-9]*\) ms$/\2 \1/p' | sort -n | tail -1)
            n=$(find "$corpus" -type f | wc -l)
            echo "    corpus: $n inputs; slowest input: ${slowest%% *} ms (${slowest#* })"
            # What the corpus reaches (uninstrumented replay through the same checks).
            "$target_dir/release/examples/replay" "$t" "$corpus" | sed 's/^/    /'
        fi
    } >"$log.summary"
    [ "$rc" -eq 0 ]
}

# FUZZ_PARALLEL=1: the targets at the same time (one process each, so at most one core
# each); default: one after the other.
status=0
if [ "${FUZZ_PARALLEL:-0}" = 1 ]; then
    echo "==> targets in parallel: ${targets[*]}"
    pids=()
    for t in "${targets[@]}"; do
        { run_target "$t" || exit 1; } &
        pids+=($!)
    done
    for i in "${!pids[@]}"; do
        wait "${pids[$i]}" || status=1
        cat "$target_dir/fuzz-$mode-${targets[$i]}.log.summary"
    done
else
    for t in "${targets[@]}"; do
        run_target "$t" || status=1
        cat "$target_dir/fuzz-$mode-$t.log.summary"
    done
fi
exit $status
