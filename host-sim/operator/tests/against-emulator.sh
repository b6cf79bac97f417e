#!/usr/bin/env bash
# The operator's end-to-end tests against the EMULATED BOARD: the board's release image
# (firmware/cortex-m/board, the ELF build-and-size.sh builds and measures) on the rigless
# STM32F4 emulator with the plant, `board-emulator serve`, virtual time paced to the wall
# clock, instead of the simulated board (the board application compiled for the host).
#
#   bash host-sim/operator/tests/against-emulator.sh
#
#   1. the board image (build-and-size.sh: release, sizes against the budgets);
#   2. the board emulator (its own workspace: release, --locked, --ignore-rust-version);
#   3. the host side: host-sim and the Rust test binaries, built as tests/run-all.sh
#      builds them (`cargo test --workspace`: the test profile, the workspace's features;
#      tests/host-sim-bin.sh), so that nothing is built twice;
#   4. a fresh emulated board, warmed up (see warm_up): the tests of
#      tests/latency_recording.rs and tests/scripted_operator.rs, one at a time (a board
#      serves one master at a time), each in a process of its own, so that the board's log
#      gives the pacing of each test's masters. A board outlives a test that passed and
#      left it Ready (homed, disabled): each test sends the robot to the central pose once
#      enabled, and leaves it there, disabled (tests/common/mod.rs). After a test that
#      failed, or left the board in any other state, the next test gets a fresh board,
#      warmed up (see known_state): one failure cannot cascade into the tests after it;
#   5. the chain benchmark (tests/chain_on_board.rs, ignored by `cargo test`: about 28 s of
#      the board's time): the synthetic operator through the scripted path, the canceller
#      against the classic filter, the canceller's start, the tremor's stop and the
#      clutch, on the board the tests left Ready, or a fresh one; in lockstep with the
#      board's shared clock (--clock-lead-ms), so its figures are the board's time and
#      judged on every run, whatever the machine's load;
#   6. igtl-board.sh (the bridge enables it) on the board the Rust tests left Ready, or a
#      fresh one;
#   7. a fresh emulated board, not homed: console-tmux.sh's steps on a board not homed
#      (the screen, the Hello, Enable refused) through a serial device (a pseudo-terminal
#      that socat bridges to the board's socket: the front ends' serial path), then the
#      whole of console-tmux.sh (it homes, enables, jogs, stops) on the socket.
#
# Through a serial device only what does not depend on the link's timing: a
# pseudo-terminal's bytes are carried by the kernel's workers at the machine's normal
# priority, and with another build loading both cores they were held for up to 0.52 s
# (socat's log; the console's own heartbeats were at most 0.38 s apart): the board rightly
# stopped homing with HeartbeatTimeout (500 ms without a heartbeat). A real board's
# serial adapter on a loaded PC would do the same. The board watches the heartbeat only
# while it homes or is enabled, so the steps on a board not homed are safe from it.
#
# The console gets a board of its own (it starts from a board not homed); the Rust tests
# and the bridge share one while each leaves it Ready (a warm-up takes about 40 s).
# `serve` puts the tool (1.2 kg on 0.1 m) on once the board is Ready.
#
# Virtual time (see start_emulator): the emulated board's clock follows the wall clock
# where its host lets it and pauses where it does not (--catch-up-ms), and it runs at most
# 50 ms beyond its master's last message (--master-lead-ms): a master that a loaded
# machine holds up holds the board with it, so the board never takes a loaded host for a
# lost master (HeartbeatTimeout). The Rust tests' masters and the warm-up run on the
# board's clock (teleop::pacing): their replies are awaited in the board's time. The board
# also shares its clock in $RSPR_BOARD_SOCKET.clock (--clock-lead-ms 2): the Rust tests'
# masters read their clock there and write back each reading, and the board runs at most
# 2 ms beyond their last reading (lockstep: each waits for the other, so what they measure
# is the board's time); masters that only read it, or not at all (the console, the bridge,
# the warm-up), are paced by their bytes (--master-lead-ms). The
# host's clock bounds only failure detectors (a board silent for 5 s, a socket that does
# not appear within 30 s), never what a test checks. --report-lag-ms: when the board's
# clock falls behind the wall clock, the log says by how much and for how long, and for
# each master how often and how long the board waited for it; each group prints its
# boards' logs. Every check passes or fails; nothing is retried. Every group runs; the
# script exits non-zero when any step failed, after the table of the steps with their wall
# times.
set -uo pipefail
cd "$(dirname "$0")/../../.."
source firmware/cortex-m/scripts.sh

t_start=$(date +%s.%N)
now() { date +%s.%N; }
since() { python3 -c "print(f'{$(now) - $1:.1f}')"; }
work="$(mktemp -d)"
emu_pid=""
steps=()
failed=0

stop_emulator() {
    if [ -n "$emu_pid" ]; then
        # A background job of a script ignores SIGINT: TERM.
        kill "$emu_pid" 2>/dev/null || true
        wait "$emu_pid" 2>/dev/null || true
        emu_pid=""
    fi
}
cleanup() {
    stop_emulator
    rm -rf "$work"
}
trap cleanup EXIT
trap 'exit 130' INT
trap 'exit 143' TERM

# step NAME COMMAND...: runs COMMAND, prints and records its wall time and verdict.
step() {
    local name="$1"
    shift
    printf '\n==> %s (at %s s)\n' "$name" "$(since "$t_start")"
    local t0 status=0
    t0=$(now)
    "$@" || status=$?
    local dt
    dt=$(since "$t0")
    if [ "$status" -eq 0 ]; then
        steps+=("$(printf '%-62s %7s s  PASS' "$name" "$dt")")
    else
        steps+=("$(printf '%-62s %7s s  FAIL (exit %d)' "$name" "$dt" "$status")")
        failed=1
    fi
    printf '<== %s: %s s, exit %d\n' "$name" "$dt" "$status"
    return "$status"
}

summary() {
    printf '\n==> against the emulated board: steps\n'
    printf '%s\n' "${steps[@]}"
    local verdict=FAILED
    [ "$failed" -ne 0 ] || verdict="all passed"
    printf 'total %s s: %s\n' "$(since "$t_start")" "$verdict"
}

# Builds: a failed build ends the run (there is nothing to test).
build_image() { bash firmware/cortex-m/board/build-and-size.sh; }
build_emulator() {
    # --all-targets as firmware/board-emulator/run.sh builds it: the same features of
    # rigless, so that nothing is compiled again after that stage.
    (cd firmware/board-emulator &&
        cargo build --release --locked --ignore-rust-version --all-targets)
}
build_host() {
    cargo test --workspace --no-run -q
}
for s in "the board image (release, thumbv7em-none-eabihf):build_image" \
    "the board emulator (release, --locked, --ignore-rust-version):build_emulator" \
    "host-sim and the test binaries (test profile):build_host"; do
    step "${s%%:*}" "${s##*:}" || { summary; exit 1; }
done
# raise_priority: the emulated board and its masters (the tests, the console in tmux, the
# bridge, socat) stand for a board with a processor of its own and the operator's PC:
# from here on they run before the other work of the machine (ten steps of nice above the
# caller's, where allowed; inherited by every process this script starts). A master that another build holds up
# misses its heartbeats: the board holds after 100 ms without one and stops after 500 ms
# (HeartbeatTimeout).
raise_priority() {
    # renice -n sets the value (util-linux), so the step is added here.
    local raised=$(($(nice) - 10))
    [ "$raised" -ge -20 ] || raised=-20
    if renice -n "$raised" -p $$ >/dev/null 2>&1; then
        echo "the emulated board and its masters at nice $(nice)"
    else
        echo "not allowed to raise the priority: the emulated board and its masters at nice $(nice)"
    fi
}
raise_priority
export RSPR_BOARD_ELF
RSPR_BOARD_ELF="$(target_dir)/$TARGET/release/rspr-board"
# The target directory of the workspace in the current directory.
target_of() {
    cargo metadata --format-version 1 --no-deps |
        python3 -c 'import json, sys; print(json.load(sys.stdin)["target_directory"])'
}
emulator="$(cd firmware/board-emulator && target_of)/release/board-emulator"
host_sim="$(target_of)/debug/host-sim"
echo "image $RSPR_BOARD_ELF"
echo "emulator $emulator"

# start_emulator NAME [SERVE-OPTION...]: a fresh board on $work/NAME.sock, its output in
# $work/NAME-N.log (N counts the boards of the group; logs lists them). The socket must
# appear within 30 s (the image boots in milliseconds of wall time).
logs=()
start_emulator() {
    stop_emulator
    export RSPR_BOARD_SOCKET="$work/$1.sock"
    log="$work/$1-$((${#logs[@]} + 1)).log"
    logs+=("$log")
    shift
    # The emulated board stands for a board with a processor of its own: it runs before
    # the other work of the machine (see raise_priority), so that its virtual time keeps
    # up with the wall clock as far as the machine can. When it cannot, its clock slips
    # beyond 10 ms behind (--catch-up-ms): the board pauses rather than run fast to catch
    # up, which would make the masters on the wall clock late for it (heartbeats) and
    # their targets stale (more than 50 ms later than the fastest). The Rust tests' masters
    # are paced by the board's clock (tests/common/mod.rs) and pause with it.
    # --master-lead-ms: the board waits for a master its host holds up (at most 50 ms of
    # the board's time beyond the master's last message; a master silent for 2 s of host
    # time is let go: the board's own heartbeat watch judges it).
    # --report-lag-ms says when and by how much the board's clock slipped.
    # --clock-lead-ms: the board's clock shared beside the socket, the Rust tests' masters
    # in lockstep with it (see the top of this file).
    "$emulator" --firmware "$RSPR_BOARD_ELF" serve --socket "$RSPR_BOARD_SOCKET" \
        --catch-up-ms 10 --report-lag-ms 20 --master-lead-ms 50 --clock-lead-ms 2 "$@" \
        >"$log" 2>&1 &
    emu_pid=$!
    local end=$(($(date +%s) + 30))
    while [ ! -S "$RSPR_BOARD_SOCKET" ]; do
        if ! kill -0 "$emu_pid" 2>/dev/null || [ "$(date +%s)" -ge "$end" ]; then
            cat "$log"
            echo "the emulated board did not serve $RSPR_BOARD_SOCKET within 30 s"
            return 1
        fi
        sleep 0.05
    done
    echo "emulated board on $RSPR_BOARD_SOCKET (pid $emu_pid)"
}

# warm_up: the emulator translates the image's code the first time it runs (rigless's
# Cranelift JIT): the first homing, the first Enable, the first targets stall the
# emulated core, and its virtual clock falls behind the wall clock by up to 1.9 s
# (measured here), which a master on the wall clock sees as a board that stops answering
# for that long. A real board has no such thing. Before the tests, `host-sim teleop` (a
# master paced by the board's telemetry, made for an emulated board that its host stalls;
# it reads the board's own time in $RSPR_BOARD_SOCKET.clock from its first message on, so
# that while the image boots its `Hello` retries and heartbeats follow the board's time
# rather than piling up on the host's and reaching the board all at once) homes, enables, streams a 10 mm line and back and disables, which runs those paths
# once. Not a verdict: its own checks run through those stalls; it must leave the board
# homed and Ready, which the tests then check for themselves.
warm_up() {
    local t0 status=0
    t0=$(now)
    "$host_sim" teleop --connect "$RSPR_BOARD_SOCKET" --scenario path --path line --clock board \
        --out "$work/warm-up-$1" || status=$?
    echo "warm-up: $(since "$t0") s (host-sim teleop exit $status: not a verdict, see above)"
}

# wait_on_time: until the emulated board keeps up with the wall clock again (every
# "behind the wall clock" of its log followed by an "on time again"), for at most 30 s,
# so that each test starts with a board on time where the machine allows (the warm-up's
# master leaves it behind). Not a verdict: on a machine too loaded to run the board in
# real time the test starts anyway (its masters wait for the board in the board's time).
wait_on_time() {
    local t0 end behind back
    t0=$(now)
    end=$(($(date +%s) + 30))
    while :; do
        behind=$(grep -c 'behind the wall clock by more than' "$log")
        back=$(grep -c 'on time again' "$log")
        [ "$behind" -gt "$back" ] || break
        if [ "$(date +%s)" -ge "$end" ]; then
            echo "the emulated board is still behind the wall clock after 30 s:" \
                "this machine does not run it in real time now (not a verdict)"
            return 0
        fi
        sleep 0.1
    done
    echo "the emulated board on the wall clock (waited $(since "$t0") s)"
}

# board_state: the emulated board's state by its log (the last "board STATE" line), or
# "stopped" when the emulator no longer runs.
board_state() {
    if [ -z "$emu_pid" ] || ! kill -0 "$emu_pid" 2>/dev/null; then
        echo stopped
        return
    fi
    sed -n 's/^[0-9.]* s: board \([A-Za-z]*\) .*/\1/p' "$log" | tail -1
}

# fresh_board NAME: a fresh emulated board, warmed up (homed, Ready).
fresh_board() {
    start_emulator "$1" || return 1
    warm_up "$1"
}

# known_state NAME: the board the next test starts from is Ready (homed, disabled): the
# current one when it is, else a fresh one, warmed up. A test that failed leaves nothing
# behind it: `dirty` (set after a failure) forces a fresh board too.
dirty=0
known_state() {
    local state
    state="$(board_state)"
    if [ "$dirty" -eq 0 ] && [ "$state" = Ready ]; then
        return 0
    fi
    echo "--- a fresh board for the next test (the last one: ${state:-no state yet}$([ "$dirty" -eq 0 ] || echo ', after a failed test'))"
    dirty=0
    fresh_board "$1"
}

# group NAME WARM COMMAND...: COMMAND against a fresh emulated board (warmed up first when
# WARM is warm), then the logs of the group's boards (their state changes, the masters,
# the pacing). The board must still be running after.
group() {
    local name="$1" warm="$2"
    shift 2
    logs=()
    dirty=0
    start_emulator "$name" || return 1
    local status=0
    if [ "$warm" = warm ]; then warm_up "$name"; fi
    wait_on_time && "$@" || status=$?
    local l
    for l in "${logs[@]}"; do
        echo "--- the emulated board ($name, $(basename "$l" .log)):"
        cat "$l"
        echo "pacing: per master, the largest lag behind the wall clock (ms) and what the" \
            "board's clock slipped (ms):" \
            "$(sed -n "s/.*meanwhile \([0-9.]*\) ms; the board's clock slipped \([0-9.]*\) ms.*/\1 (\2)/p" \
                "$l" | paste -sd',')"
        echo "waits for the masters: $(sed -n 's/.*(the board waited for it \([^)]*\)).*/\1/p' "$l" | paste -sd';')"
    done
    if ! kill -0 "$emu_pid" 2>/dev/null; then
        echo "the emulated board stopped during the tests"
        status=1
    fi
    stop_emulator
    return "$status"
}

# Each test of both binaries in a process of its own, in order; all run, the failures are
# listed.
rust_tests() {
    local bin name names status=0 failures=()
    for bin in latency_recording scripted_operator; do
        names="$(cargo test -q --workspace --test "$bin" -- --list --format terse)" &&
            names="$(sed -n 's/: test$//p' <<<"$names")" && [ -n "$names" ] ||
            { echo "no tests listed in $bin"; return 1; }
        for name in $names; do
            printf '\n--- %s: %s\n' "$bin" "$name"
            local before
            if ! known_state rust; then
                failures+=("$bin::$name (no board)")
                status=1
                continue
            fi
            before=$(grep -c 'master gone' "$log")
            if ! wait_on_time ||
                ! cargo test -q --workspace --test "$bin" -- --exact "$name" --nocapture; then
                failures+=("$bin::$name")
                status=1
                dirty=1
            fi
            # The board's pacing while the test's master was connected (the emulator logs it
            # when the master goes, at the latest 2 s after the test's process ends).
            for _ in $(seq 20); do
                [ "$(grep -c 'master gone' "$log")" -gt "$before" ] && break
                sleep 0.1
            done
            echo "pacing during $name: $(grep 'master gone' "$log" | tail -1)"
        done
    done
    [ "$status" -eq 0 ] || printf 'failed: %s\n' "${failures[@]}"
    return "$status"
}
# The chain benchmark on a board in a known state (Ready), its pacing as for the tests.
chain_bench() {
    local before status=0
    known_state rust || return 1
    before=$(grep -c 'master gone' "$log")
    wait_on_time &&
        cargo test -q --workspace --test chain_on_board -- --ignored --exact \
            chain_on_the_served_board --nocapture || { status=1; dirty=1; }
    for _ in $(seq 20); do
        [ "$(grep -c 'master gone' "$log")" -gt "$before" ] && break
        sleep 0.1
    done
    echo "pacing during the chain benchmark: $(grep 'master gone' "$log" | tail -1)"
    return "$status"
}
# The Rust tests, the chain benchmark, then the OpenIGTLink bridge on the board they left
# Ready (homed, centred, disabled; the bridge enables it), or a fresh one.
rust_then_igtl() {
    local status=0
    step "Rust tests: latency_recording, scripted_operator" rust_tests || status=1
    step "chain benchmark: chain_on_board (about 28 s of the board's time)" chain_bench ||
        status=1
    step "igtl-board.sh, on the board the tests left Ready (or a fresh one)" \
        igtl_on_known_state || status=1
    return "$status"
}
igtl_on_known_state() { known_state rust && on_time bash host-sim/operator/tests/igtl-board.sh; }
on_time() { wait_on_time && "$@"; }
group rust warm rust_then_igtl || failed=1
# The console on a board not homed, through a serial device, then the whole of its test on
# the socket, on the same board (the first leaves it not homed and disabled). No warm-up:
# it would home the board.
console_tests() {
    local status=0
    step "console-tmux.sh, a board not homed, through a serial device" \
        env RSPR_BOARD_VIA_PTY=1 RSPR_CONSOLE_NOT_HOMED_ONLY=1 \
        bash host-sim/operator/tests/console-tmux.sh || status=1
    step "console-tmux.sh, on the same board" \
        on_time bash host-sim/operator/tests/console-tmux.sh || status=1
    return "$status"
}
group console cold console_tests || failed=1

summary
exit "$failed"
