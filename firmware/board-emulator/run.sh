#!/usr/bin/env bash
# The board-emulator stage: the release board image (the ELF build-and-size.sh measures) on
# the emulated STM32F4, in closed loop with the plant and the host master, in virtual time.
#
#   1. the image: firmware/cortex-m/board/build-and-size.sh (honours CARGO_TARGET_DIR);
#   2. this crate (its own workspace and Cargo.lock), release profile, --locked;
#   3. its tests: the added register models against RM0090, the pin map against
#      board.rs's table, the image's fit on the STM32F405, the board and mechanics models;
#   4. every closed-loop scenario, twice at once (this process and a child process), each
#      check printed with its figures, the two runs' digests compared.
#
# rigless 0.4.0 declares rust-version 1.98 and builds and runs with the pinned 1.95: every
# cargo command of this crate passes --ignore-rust-version (README.md, "Toolchain").
# Deterministic: virtual time only, nothing retried. Exits non-zero on any failed check.
set -euo pipefail
HERE="$(cd "$(dirname "$0")" && pwd)"
source "$HERE/../cortex-m/scripts.sh"
started=$(date +%s)
section() { printf '\n==> %s (%d s)\n' "$*" "$(( $(date +%s) - started ))"; }

section "the board image (release, thumbv7em-none-eabihf)"
bash "$HERE/../cortex-m/board/build-and-size.sh"
ELF="$(target_dir)/$TARGET/release/rspr-board"
export RSPR_BOARD_ELF="$ELF"

cd "$HERE"
OUT="$(cargo metadata --format-version 1 --no-deps |
    python3 -c 'import json, sys; print(json.load(sys.stdin)["target_directory"])')/scenarios"

section "board-emulator: build (release)"
cargo build --release --locked --ignore-rust-version --all-targets

section "board-emulator: tests (register models vs RM0090, pin map vs board.rs, F405 fit)"
cargo test --release --locked --ignore-rust-version

section "board-emulator: the closed-loop scenarios, two runs at once, digests compared"
status=0
cargo run --release --locked --ignore-rust-version -q -- \
    --firmware "$ELF" scenarios --runs 2 --out "$OUT" || status=$?

section "board-emulator stage done (exit $status)"
exit $status
