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
#   3. its tests (the figures the scenarios compute, e.g. the best-fitting delay);
#   4. every closed-loop scenario, twice at once (this process and a child process), each
#      check printed with its figures, the two runs' digests compared.
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
export RSPR_BOARD_ELF="$ELF"

cd "$HERE"
TARGET_DIR="$(cargo metadata --format-version 1 --no-deps |
    python3 -c 'import json, sys; print(json.load(sys.stdin)["target_directory"])')"
OUT="$TARGET_DIR/scenarios"

section "board-scenarios: build (release)"
cargo build --release --locked --ignore-rust-version --all-targets

section "board-scenarios: tests (the scenarios' own figures)"
cargo test --release --locked --ignore-rust-version

section "board-scenarios: the closed-loop scenarios, two runs at once, digests compared"
status=0
"$TARGET_DIR/release/board-scenarios" --firmware "$ELF" --runs 2 --out "$OUT" || status=$?

section "board-scenarios stage done (exit $status)"
exit $status
