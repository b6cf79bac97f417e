#!/usr/bin/env bash
# The board emulator's stage: the release board image (the ELF build-and-size.sh measures)
# on the emulated STM32F4 with the robot of sim/ around it.
#
#   1. the image: firmware/cortex-m/board/build-and-size.sh (honours CARGO_TARGET_DIR);
#   2. this crate (its own workspace and Cargo.lock), release profile, --locked;
#   3. its tests: the added register models against RM0090, the pin maps against the
#      board.rs tables, the image's fit on the STM32F405, the board and mechanics models,
#      the NUCLEO-F429ZI's image booting on its pins (tests/nucleo_boot.rs), the second
#      position channel's image with its AD7689 on SPI3 (tests/position_channel.rs) and StoreGeometry's
#      flash write on the pins (tests/store_geometry.rs).
#
# The closed-loop scenarios with the host's master come after it, from
# host-sim/board-scenarios/run.sh, which builds into this crate's target directory.
# rigless 0.4.0 declares rust-version 1.98 and builds and runs with the pinned 1.95: every
# cargo command of this crate passes --ignore-rust-version (README.md, "Toolchain").
set -euo pipefail
HERE="$(cd "$(dirname "$0")" && pwd)"
source "$HERE/../cortex-m/scripts.sh"
started=$(date +%s)
section() { printf '\n==> %s (%d s)\n' "$*" "$(( $(date +%s) - started ))"; }

section "the board image (release, thumbv7em-none-eabihf)"
bash "$HERE/../cortex-m/board/build-and-size.sh"
export RSPR_BOARD_ELF="$(target_dir)/$TARGET/release/rspr-board"
export RSPR_NUCLEO_ELF="$(target_dir)/$TARGET/release/rspr-nucleo-f429zi"
export RSPR_BOARD_PC_ELF="$(target_dir)/$TARGET/release/rspr-board-position-channel"

cd "$HERE"
section "board-emulator: build (release)"
cargo build --release --locked --ignore-rust-version --all-targets

section "board-emulator: tests (register models vs RM0090, pin map vs board.rs, F405 fit)"
cargo test --release --locked --ignore-rust-version

section "board-emulator stage done"
