#!/usr/bin/env bash
# The closed-loop scenarios: the release board image (the ELF build-and-size.sh measures)
# on the emulated STM32F4 (firmware/board-emulator), in closed loop with the robot of sim/
# and the host's master, in virtual time.
#
#   1. the image: firmware/cortex-m/board/build-and-size.sh (built already when
#      firmware/board-emulator/run.sh ran before; honours CARGO_TARGET_DIR);
#   2. this crate (its own workspace and Cargo.lock), release profile, --locked, into the
#      emulator's target directory (.cargo/config.toml): rigless and cranelift as the
#      emulator's stage built them;
#   3. its tests (the figures the scenarios compute, e.g. the best-fitting delay; and
#      tests/commissioning.rs: the image with the second position channel, miswired in
#      the emulator's mechanics (every kind of miswiring on every joint: a straight robot
#      and six miswired ones), commissioned by host-sim commission's loop);
#   4. every closed-loop scenario, twice at once (this process and a child process), each
#      check printed with its figures, the two runs' digests compared; at the same time
#   5. the NUCLEO-F429ZI's release image (built by the same build-and-size.sh) on its own
#      pins: the scenarios that drive or read every pin (--scenarios wiring), one run, its
#      output printed after the reference board's.
#
# Every cargo command passes --ignore-rust-version (firmware/board-emulator/README.md,
# "Toolchain"). Deterministic: virtual time only, nothing retried. Exits non-zero on any
# failed check.
set -euo pipefail
HERE="$(cd "$(dirname "$0")" && pwd)"
source "$HERE/../../firmware/cortex-m/scripts.sh"
started=$(date +%s)
section() { printf '\n==> %s (%d s)\n' "$*" "$(( $(date +%s) - started ))"; }

section "the board image (release, thumbv7em-none-eabihf)"
bash "$HERE/../../firmware/cortex-m/board/build-and-size.sh"
ELF="$(target_dir)/$TARGET/release/rspr-board"
NUCLEO_ELF="$(target_dir)/$TARGET/release/rspr-nucleo-f429zi"
export RSPR_BOARD_ELF="$ELF"
export RSPR_NUCLEO_ELF="$NUCLEO_ELF"
# The image with the second position channel: the commissioning test (tests/commissioning.rs).
export RSPR_BOARD_PC_ELF="$(target_dir)/$TARGET/release/rspr-board-position-channel"

cd "$HERE"
TARGET_DIR="$(cargo metadata --format-version 1 --no-deps |
    python3 -c 'import json, sys; print(json.load(sys.stdin)["target_directory"])')"
OUT="$TARGET_DIR/scenarios"

section "board-scenarios: build (release)"
cargo build --release --locked --ignore-rust-version --all-targets

section "board-scenarios: tests (the scenarios' own figures)"
cargo test --release --locked --ignore-rust-version

section "board-scenarios: the closed-loop scenarios, two runs at once, digests compared; the NUCLEO-F429ZI's beside them"
# The NUCLEO-F429ZI's image on its own pins (the wiring's scenarios, one run) runs at the
# same time as the reference board's two runs, its output kept apart and printed after.
status=0
nucleo_log="$OUT/nucleo-f429zi.log"
mkdir -p "$OUT"
"$TARGET_DIR/release/board-scenarios" --board nucleo-f429zi --scenarios wiring \
    --firmware "$NUCLEO_ELF" --runs 1 --out "$OUT/nucleo-f429zi" >"$nucleo_log" 2>&1 &
nucleo_pid=$!
"$TARGET_DIR/release/board-scenarios" --firmware "$ELF" --runs 2 --out "$OUT" || status=$?
nucleo_status=0
wait "$nucleo_pid" || nucleo_status=$?

section "board-scenarios: the NUCLEO-F429ZI image on its pins, the wiring's scenarios (exit $nucleo_status)"
cat "$nucleo_log"
if [ "$nucleo_status" -ne 0 ]; then status=$nucleo_status; fi

section "board-scenarios stage done (exit $status)"
exit $status
