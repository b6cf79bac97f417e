#!/usr/bin/env bash
# The full test run: what a newcomer types (README) and what CI runs (.ci/run).
# Installs what it needs when missing (the Cortex-M4F target, Debian packages, PyPI test
# clients). Every check passes or fails: nothing is retried. Property tests run from a fixed
# seed (tests/proptest-config); RSPR_PROPTEST_FRESH=1 draws fresh seeds and more cases.
#
# Load cannot fail it (tests/under-load.sh runs it beside CPU burners): every test that
# talks to a board runs in the board's time, on a board of its own or one in a known state.
# - The emulated board in lockstep, in process (board-emulator's tests, board-scenarios):
#   virtual time only, the master driven by the emulator's clock; one board per run.
# - The simulated board in process (the control, simulation, board-on-plant and faults
#   tests): virtual time, a board per test.
# - The simulated board served on a socket (`simulation::serve`: scripted_operator,
#   latency_recording, faultlog, served_board, hand_controller, igtl-board.sh): a board per
#   test, its clock virtual, paced by the wall clock and its master (it pauses, never
#   jumps, and waits for a master its host holds up).
# - The emulated board served on a socket (against-emulator.sh): `serve --master-lead-ms`,
#   the same pacing; a fresh board after any test that failed or left it not Ready.
# - The exception: teleop_fake_board's small fake board keeps the host's clock (its
#   heartbeat hold and stop, and the master's windows for them, are host time).
# The masters of the Rust tests and the warm-up run on the board's clock
# (teleop::pacing); wall-clock bounds are failure detectors only.
#
# The order: the builds and the board's own tests one after the other (the fuzz targets'
# and the Python wheel's builds beside them, at low priority), then three lanes side by
# side: the host's tests (cargo-nextest, six at a time) with the fuzz and Python runs, the
# front ends on the emulated board, and those on simulated boards; that is how the run
# fits CI's 25 minutes on two cores. Each section prints the seconds since the start and
# the CPU seconds used so far.
set -euo pipefail
cd "$(dirname "$0")/.."
source firmware/cortex-m/scripts.sh
# One build from scratch: incremental compilation's caches would only cost time here.
export CARGO_INCREMENTAL=${CARGO_INCREMENTAL:-0}
started=$(date +%s)

# Each section prints the wall-clock seconds since the start and the CPU seconds (user +
# system) its shell's finished children used so far: the measure of what a stage costs.
cpu_file="$(mktemp)"
trap 'rm -f "$cpu_file" "$cpu_file".*' EXIT
cpu_seconds() {
    # `times` in this shell, not in a subshell (a fork starts its children's count at 0),
    # into a file of this shell's own: the lanes call it at the same time, and a read of
    # a file another lane had just truncated ended a lane silently (errexit on `read`).
    local _u _s cu cs t m sec ms=0 f="$cpu_file.$BASHPID"
    times >"$f"
    { read -r _u _s; read -r cu cs; } <"$f"
    rm -f "$f"
    for t in "$cu" "$cs"; do # 1m2.345s
        m=${t%%m*}
        sec=${t#*m}
        sec=${sec%s}
        ms=$((ms + 10#$m * 60000 + 10#${sec%.*} * 1000 + 10#${sec#*.}))
    done
    cpu_now=$((ms / 1000))
}
section() {
    cpu_seconds
    printf '\n==> %s (%d s, CPU %d s)\n' "$*" "$(($(date +%s) - started))" "$cpu_now"
}

section "toolchain (rust-toolchain.toml: $(rustup show active-toolchain | cut -d' ' -f1), thumbv7em-none-eabihf)"
rustup show active-toolchain
ensure_target

section "what the stages need from Debian and PyPI (tests/requirements.sh)"
source tests/requirements.sh
install_requirements

section "in the background, ten steps of nice below the rest: the fuzz targets' and the Python wheel's builds"
# They use the cores the stages below leave idle (each waits on one crate at times, runs
# QEMU on one core, links); their tests run in the first lane below, once both are built.
# When the run comes to wait on them they are raised to its own priority: on a machine
# that other work keeps busy, a build at nice +10 gets about a tenth of the share of each
# busy process beside it (the scheduler's weights, 110 against 1024), and the wait would
# last as long as that work.
# Their own target directories or profiles: no stage below waits on their cargo locks.
# A session of their own (setsid), ended with the run if it stops early.
soak_log="$(mktemp)"
setsid -w nice -n 10 bash -c 'set -euo pipefail
    (cd fuzz && cargo test --release --no-run --quiet)
    bash fuzz/run.sh build
    bash host-sim/python/tests/run.sh build' >"$soak_log" 2>&1 &
soaker=$!
trap 'rm -f "$cpu_file" "$cpu_file".*; if [ -n "$soaker" ]; then kill -- -"$soaker" 2>/dev/null || true; fi' EXIT

section "format (every workspace: host, Cortex-M, board emulator, board scenarios, fuzz)"
cargo fmt --all -- --check
(cd firmware/cortex-m && cargo fmt --all -- --check)
(cd firmware/board-emulator && cargo fmt --all -- --check)
(cd host-sim/board-scenarios && cargo fmt --all -- --check)
(cd fuzz && cargo fmt --all -- --check)

section "lint: clippy on every crate of every workspace, warnings are errors"
# The host's workspace beside the four others (separate target directories, nothing
# shared): the two keep both cores busy through each other's serial stretches. The others'
# output follows the host's; either failing fails the stage.
lint_others() {
    # One chip per cargo invocation (embassy-stm32's chip feature): the NUCLEO-F429ZI apart.
    (cd firmware/cortex-m && cargo clippy --workspace --exclude board-nucleo-f429zi --release -- -D warnings) &&
        (cd firmware/cortex-m && cargo clippy --release -p board-nucleo-f429zi -- -D warnings) &&
        (cd fuzz && cargo clippy --all-targets -- -D warnings) &&
        (cd firmware/board-emulator && cargo clippy --release --locked --ignore-rust-version --all-targets -- -D warnings) &&
        (cd host-sim/board-scenarios && cargo clippy --release --locked --ignore-rust-version --all-targets -- -D warnings)
}
others_log="$(mktemp)"
lint_others >"$others_log" 2>&1 &
others=$!
host_lint=0
cargo clippy --workspace --all-targets -- -D warnings || host_lint=$?
others_lint=0
wait "$others" || others_lint=$?
echo "--- clippy on the Cortex-M, fuzz, board-emulator and board-scenarios workspaces:"
cat "$others_log"
rm -f "$others_log"
if [ "$host_lint" -ne 0 ] || [ "$others_lint" -ne 0 ]; then
    echo "lint FAILED (host workspace: exit $host_lint; the others: exit $others_lint)"
    exit 1
fi

section "the no_std libraries build for the Cortex-M4F"
cargo build --release --target "$TARGET" -p kinematics-core -p hal -p servo -p control -p master-link

section "board images (STM32F405 board, NUCLEO-F429ZI): release builds and sizes against the budgets"
bash firmware/cortex-m/board/build-and-size.sh

section "on-target tests and instructions per control tick (QEMU mps2-an386)"
bash firmware/cortex-m/on-target/run.sh

section "the board's release image in the STM32F4 emulator (rigless), in closed loop with the plant and the master; commissioning a miswired robot on it"
bash firmware/board-emulator/run.sh
bash host-sim/board-scenarios/run.sh

section "the host's tests and binaries (test profile): one build for the tests and the front ends' scripts"
if ! cargo nextest --version >/dev/null 2>&1; then
    echo "==> cargo-nextest is missing: installing it from crates.io"
    cargo install cargo-nextest --locked
fi
cargo nextest --version
cargo test --workspace --no-run

# Three lanes side by side from here. The builds above are done: the first lane is the
# host's tests (nextest: tests of different binaries side by side), the fuzz runs and the
# Python module's tests; the second, the front ends on the emulated board; the third, the
# front ends on simulated boards. The boards' lanes run in the boards' time and wait on
# sockets most of the time. The first lane's output streams; the others' are kept in
# files and printed after it, whole. A lane stops at its first failing stage; every lane
# always finishes.
section "the background builds (fuzz targets, Python wheel): waiting for them, their output"
# Raised to the run's own priority (their session is their process group; renice -n sets
# the value, util-linux). Where that is refused they go on as they are.
renice -n "$(nice)" -g "$soaker" >/dev/null 2>&1 || true
soak_status=0
wait "$soaker" || soak_status=$?
soaker=""
cat "$soak_log"
rm -f "$soak_log"
if [ "$soak_status" -ne 0 ]; then
    echo "the background builds FAILED (exit $soak_status)"
    exit 1
fi

lanes="$(mktemp -d)"
lane_tests() {
    section "tests (unit, property, integration, CLI): cargo nextest, then the doc tests"
    cargo nextest run --workspace --profile ci
    cargo test --workspace --doc

    # Built in the background already. At the run's priority (see the background builds);
    # the emulated board raises its own where allowed: it stands for a processor of its own.
    section "fuzzing: the link's frame decoder and the board's command handling (libFuzzer, fixed seed)"
    (cd fuzz && cargo test --release --quiet)
    FUZZ_RUNS=${FUZZ_RUNS:-300000} FUZZ_PARALLEL=${FUZZ_PARALLEL:-1} bash fuzz/run.sh ci

    section "the analysis from Python: the rspr wheel (maturin, PyO3) against the CLI, pytest"
    bash host-sim/python/tests/run.sh
}
lane_emulated() {
    section "the operator's front ends on the emulated board (the release image): scripted operator, latency, OpenIGTLink; the console in tmux, through a serial device on a board not homed"
    bash host-sim/operator/tests/against-emulator.sh
}
lane_simulated() {
    section "the operator's front ends on the simulated board: OpenIGTLink clients (pyigtl, libopenigtlink), spacenavd"
    bash host-sim/operator/tests/igtl-board.sh
    bash host-sim/masters/tests/spacenavd-daemon.sh

    section "the robot description and the live 3-D scene: check_urdf, yourdfpy, a Foxglove WebSocket client, mcap"
    bash host-sim/description/tests/urdf.sh
    bash host-sim/scene/tests/foxglove.sh

    section "ROS 2 on the simulated board: a CycloneDDS (Python) peer with the ROS 2 type names, on the loopback"
    bash host-sim/ros2/tests/ros2-board.sh
}
# Each lane in a subshell of its own with errexit on; none is run where bash would test its
# status (`|| ...`), which would turn errexit off inside it.
(set -euo pipefail; lane_emulated) >"$lanes/emulated.log" 2>&1 &
emulated=$!
(set -euo pipefail; lane_simulated) >"$lanes/simulated.log" 2>&1 &
simulated=$!
set +e
(set -euo pipefail; lane_tests)
tests_status=$?
wait "$emulated"
emulated_status=$?
wait "$simulated"
simulated_status=$?
set -e
section "the front ends on the emulated board (the second lane): its output"
cat "$lanes/emulated.log"
section "the front ends on simulated boards (the third lane): its output"
cat "$lanes/simulated.log"
rm -rf "$lanes"
if [ "$tests_status" -ne 0 ] || [ "$emulated_status" -ne 0 ] || [ "$simulated_status" -ne 0 ]; then
    section "FAILED: the tests' lane exit $tests_status, the emulated board's $emulated_status, the simulated boards' $simulated_status"
    exit 1
fi

section "all passed in $(( $(date +%s) - started )) s"
