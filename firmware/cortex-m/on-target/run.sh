#!/usr/bin/env bash
# On-target testing on an emulated Cortex-M4 (QEMU mps2-an386: Cortex-M4F, semihosting).
#
#   firmware/cortex-m/on-target/run.sh          tests + tick-cost table
#   firmware/cortex-m/on-target/run.sh tests    only the on-target tests
#   firmware/cortex-m/on-target/run.sh cost     only the tick-cost measurement
#
# 1. installs qemu-system-arm with apt when it is missing (non-interactive);
# 2. builds the firmware images for thumbv7em-none-eabihf (the Cortex-M4 workspace's
#    release profile, the board image's: opt-level 2, fat LTO, codegen-units 1);
# 3. runs the on-target tests under QEMU: they print `N passed, M failed` and exit non-zero
#    on any failure (this script then exits non-zero too);
# 4. builds the instruction-count TCG plugin (gcc), runs the tick-cost image under QEMU with
#    -icount shift=0 and the plugin, twice (the counts must be identical), and prints the
#    table of instructions per call and the profile of the full control tick.
#
# Environment: CPI (cycles per instruction assumed for the % column, default 1.3), MHZ
# and RATE_HZ (default: the board profile's clock and rate), PROFILE (cargo profile, default release; `os`,
# `o3`, `hot3`: see opt-levels.sh), QEMU_TIMEOUT (seconds per QEMU run, default 300),
# TICK_BUDGET (the script fails when the worst control tick of the scenario, from the
# readings to the outputs, exceeds it; default 8000, issue 18's target) and PERIOD_BUDGET
# (the same for the whole period: the tick and the work after its outputs; default 20000);
# set either empty to turn its check off.
set -euo pipefail

HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
source "$HERE/../scripts.sh"
cd "$HERE"
WHAT="${1:-all}"
PROFILE="${PROFILE:-release}"
CPI="${CPI:-1.3}"
# The board's clock and rate: the board profile's (firmware/profile/reference.toml).
PROFILE_TOML="$HERE/../../profile/reference.toml"
MHZ="${MHZ:-$(awk '$1 == "cpu_hz" { print $3 / 1e6 }' "$PROFILE_TOML")}"
RATE_HZ="${RATE_HZ:-$(awk '$1 == "control_period_us" { print 1e6 / $3 }' "$PROFILE_TOML")}"
QEMU_TIMEOUT="${QEMU_TIMEOUT:-300}"
TARGET_DIR="$(target_dir)"
OUT="$TARGET_DIR/$TARGET/$PROFILE"
WORK="$TARGET_DIR/qemu-run"
mkdir -p "$WORK"
start_time=$(date +%s)

log() { printf '==> %s\n' "$*"; }
# The opt-level of the cargo profile in use, as Cargo.toml sets it.
opt_level() {
    awk -v p="[profile.$PROFILE]" '$0 == p { on = 1; next } /^\[/ { on = 0 }
        on && $1 == "opt-level" { v = $3 } on && $1 == "inherits" { i = $3 }
        END { if (v == "") v = "as " i; print "opt-level " v }' "$CORTEX_M/Cargo.toml"
}

# --- 1. QEMU -----------------------------------------------------------------------------
ensure_target
ensure_apt qemu-system-arm qemu-system-arm
QEMU=(qemu-system-arm -M mps2-an386 -nographic -monitor none -serial none
      -semihosting-config enable=on,target=native -icount shift=0)
log "$(qemu-system-arm --version | head -n 1)"

# --- 2. Build ------------------------------------------------------------------------------
log "building the firmware images (cargo --profile $PROFILE, $TARGET)"
cargo build --profile "$PROFILE" -p on-target --bins
if command -v arm-none-eabi-size >/dev/null 2>&1; then
    arm-none-eabi-size "$OUT/on-target-tests" "$OUT/tick-cost"
fi

status=0

# --- 3. On-target tests --------------------------------------------------------------------
if [ "$WHAT" = all ] || [ "$WHAT" = tests ]; then
    log "on-target tests (f32 on the Cortex-M4 FPU, under QEMU)"
    t0=$(date +%s)
    set +e
    timeout "$QEMU_TIMEOUT" "${QEMU[@]}" -kernel "$OUT/on-target-tests" 2>&1 | tee "$WORK/tests.log"
    test_status=${PIPESTATUS[0]}
    set -e
    log "on-target tests: QEMU exit status $test_status ($(( $(date +%s) - t0 )) s)"
    if [ "$test_status" != 0 ] || ! grep -Eq '^[0-9]+ passed, 0 failed$' "$WORK/tests.log"; then
        status=1
    fi
fi

# --- 4. Tick cost --------------------------------------------------------------------------
if [ "$WHAT" = all ] || [ "$WHAT" = cost ]; then
    log "tick cost: building the instruction-count plugin"
    gcc -O2 -shared -fPIC -Wall -o "$WORK/libinsncount.so" plugin/insncount.c
    NM=nm
    if command -v arm-none-eabi-nm >/dev/null 2>&1; then NM=arm-none-eabi-nm; fi
    IMG="$OUT/tick-cost"
    # Function symbols "ADDR SIZE NAME" for the profile.
    "$NM" -S --demangle --defined-only "$IMG" |
        awk 'NF >= 4 && ($3 == "T" || $3 == "t" || $3 == "W" || $3 == "w") {
                 a = $1; s = $2; $1 = $2 = $3 = ""; sub(/^ +/, ""); print a, s, $0 }' > "$WORK/syms.txt"
    addr() { "$NM" --defined-only "$IMG" | awk -v s="$1" '$3 == s { print "0x" $1 }'; }
    PLUGIN="$WORK/libinsncount.so,start=$(addr bench_start),stop=$(addr bench_stop)"
    PLUGIN="$PLUGIN,on=$(addr bench_profile_on),off=$(addr bench_profile_off),syms=$WORK/syms.txt"
    cost_ok=1
    for run in 1 2; do
        t0=$(date +%s)
        set +e
        timeout "$QEMU_TIMEOUT" "${QEMU[@]}" -plugin "$PLUGIN,out=$WORK/counts$run.txt" \
            -kernel "$IMG" > "$WORK/cost$run.log" 2> "$WORK/cost$run.err"
        rc=$?
        set -e
        log "tick cost run $run: QEMU exit status $rc ($(( $(date +%s) - t0 )) s)"
        if [ "$rc" != 0 ]; then
            cat "$WORK/cost$run.err" "$WORK/cost$run.log" | tail -n 20
            cost_ok=0
            break
        fi
    done
    if [ "$cost_ok" = 1 ]; then
        if cmp -s <(grep '^count' "$WORK/counts1.txt") <(grep '^count' "$WORK/counts2.txt"); then
            log "repeatable: both runs counted the same instructions in all $(grep -c '^count' "$WORK/counts1.txt") regions"
        else
            log "NOT repeatable: the two runs' counts differ"
            cost_ok=0
        fi
        awk -f report.awk -v cpi="$CPI" -v mhz="$MHZ" -v rate="$RATE_HZ" -v top=25 \
            -v build="cargo profile $PROFILE ($(opt_level))" -v budget="${TICK_BUDGET-8000}" \
            -v period_budget="${PERIOD_BUDGET-20000}" "$WORK/counts1.txt" "$WORK/cost1.log" | tee "$WORK/tick-cost.txt" ||
            cost_ok=0
    fi
    if [ "$cost_ok" != 1 ]; then
        log "tick-cost measurement failed"
        status=1
    fi
fi

log "run.sh finished in $(( $(date +%s) - start_time )) s, status $status"
exit "$status"
