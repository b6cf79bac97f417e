#!/usr/bin/env bash
# The optimisation level chosen by measurement: for each cargo profile of this
# workspace, the instructions per control tick (readings to outputs) and per whole period
# of the on-target scenario (QEMU, instruction count) against the board image's text size.
#
#   firmware/cortex-m/opt-levels.sh [PROFILE ...]   default: release os o3 hot3
#
# release: opt-level 2 everywhere (what is flashed); os, o3: the whole image at "s" or 3;
# hot3: the release profile with the crates that instantiate the (generic) control code,
# the images `board` and `on-target`, at 3. Prints one table row per profile; builds into the workspace's target directory
# (one directory per profile: several GB each, delete them afterwards).
set -euo pipefail
HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
source "$HERE/scripts.sh"
cd "$HERE"
profiles=("$@")
[ ${#profiles[@]} -gt 0 ] || profiles=(release os o3 hot3)
TARGET_DIR="$(target_dir)"
rows=()
for p in "${profiles[@]}"; do
    echo "==> profile $p: tick cost"
    PROFILE="$p" TICK_BUDGET= PERIOD_BUDGET= bash on-target/run.sh cost >"$TARGET_DIR/opt-$p.log" 2>&1 || {
        tail -30 "$TARGET_DIR/opt-$p.log"
        echo "error: the tick-cost run of profile $p failed" >&2
        exit 1
    }
    line=$(grep '^Full tick over the scenario' "$TARGET_DIR/qemu-run/tick-cost.txt")
    mean=$(sed -n 's/.*mean \([0-9]*\), max.*/\1/p' <<<"$line")
    max=$(sed -n 's/.*max \([0-9]*\) instructions.*/\1/p' <<<"$line")
    line=$(grep '^the whole period' "$TARGET_DIR/qemu-run/tick-cost.txt")
    pmean=$(sed -n 's/.*mean \([0-9]*\), max.*/\1/p' <<<"$line")
    pmax=$(sed -n 's/.*max \([0-9]*\) instructions.*/\1/p' <<<"$line")
    echo "==> profile $p: board image"
    cargo build --profile "$p" -p board --quiet
    read -r text data bss _ < <(arm-none-eabi-size "$TARGET_DIR/$TARGET/$p/rspr-board" | awk 'NR == 2')
    rows+=("$(printf '%-8s %10s %10s %12s %12s %12s %8s %8s' "$p" "$mean" "$max" "$pmean" "$pmax" "$text" "$data" "$bss")")
done
printf '\n%-8s %10s %10s %12s %12s %12s %8s %8s\n' profile "tick mean" "tick max" "period mean" "period max" "board text" data bss
printf '%s\n' "${rows[@]}"
