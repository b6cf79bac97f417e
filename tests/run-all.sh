#!/usr/bin/env bash
# The full test run: what a newcomer types (README) and what CI runs (.ci/run).
# Installs what it needs when missing (the Cortex-M4F target, Debian packages, PyPI test
# clients). Every check passes or fails: nothing is retried. Property tests run from a fixed
# seed (tests/proptest-config); RSPR_PROPTEST_FRESH=1 draws fresh seeds and more cases.
set -euo pipefail
cd "$(dirname "$0")/.."
source firmware/cortex-m/scripts.sh
started=$(date +%s)

section() { printf '\n==> %s (%d s)\n' "$*" "$(( $(date +%s) - started ))"; }

section "toolchain (rust-toolchain.toml: $(rustup show active-toolchain | cut -d' ' -f1), thumbv7em-none-eabihf)"
rustup show active-toolchain
ensure_target

section "format (both workspaces)"
cargo fmt --all -- --check
(cd firmware/cortex-m && cargo fmt --all -- --check)

section "lint: clippy on every crate of both workspaces, warnings are errors"
cargo clippy --workspace --all-targets -- -D warnings
(cd firmware/cortex-m && cargo clippy --workspace --release -- -D warnings)

section "the no_std libraries build for the Cortex-M4F"
cargo build --release --target "$TARGET" -p kinematics-core -p hal -p servo -p control -p master-link

section "board image (STM32F405): release build and sizes against the budgets"
bash firmware/cortex-m/board/build-and-size.sh

section "on-target tests and instructions per control tick (QEMU mps2-an386)"
bash firmware/cortex-m/on-target/run.sh

section "the board application in the emulator, in closed loop with the host master"
bash firmware/cortex-m/qemu-board/run.sh

section "tests (unit, property, integration, CLI)"
cargo test --workspace

section "fuzzing: the link's frame decoder and the board's command handling (libFuzzer, fixed seed)"
(cd fuzz && cargo test --release --quiet)
FUZZ_RUNS=${FUZZ_RUNS:-1000000} bash fuzz/run.sh ci

section "all passed in $(( $(date +%s) - started )) s"
