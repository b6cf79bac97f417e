#!/usr/bin/env bash
# The full test run: what a newcomer types (README) and what CI runs (.ci/run).
# Installs what it needs when missing (the Cortex-M4F target; Debian packages later steps use).
set -euo pipefail
cd "$(dirname "$0")/.."

section() { printf '\n==> %s\n' "$*"; }

section "toolchain (rust-toolchain.toml: stable with thumbv7em-none-eabihf)"
rustup show active-toolchain
if ! rustup target list --installed | grep -qx thumbv7em-none-eabihf; then
    rustup target add thumbv7em-none-eabihf
fi

section "format"
cargo fmt --all -- --check

section "lint (clippy, warnings are errors)"
cargo clippy --workspace --all-targets -- -D warnings

section "no_std crates build for the Cortex-M4F (thumbv7em-none-eabihf)"
cargo build --release --target thumbv7em-none-eabihf -p kinematics-core -p master-link

section "board firmware (STM32F405): format, lint, release build and sizes"
(cd firmware/board && cargo fmt -- --check && cargo clippy --release -q -- -D warnings)
bash firmware/board/build-and-size.sh

section "on-target tests and cost per control tick on the emulated Cortex-M4 (QEMU mps2-an386)"
(cd firmware/qemu && cargo fmt -- --check)
bash firmware/qemu/run.sh

section "the firmware in the emulator, in closed loop with the host master (host-sim teleop)"
(cd firmware/qemu-board && cargo fmt -- --check && cargo clippy --release -q -- -D warnings)
bash firmware/qemu-board/run.sh

section "tests (unit, property, integration, CLI)"
cargo test --workspace
