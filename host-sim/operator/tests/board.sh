# Sourced by the operator's test scripts: builds host-sim (tests/host-sim-bin.sh) and starts the board to
# test against: the board at $RSPR_BOARD_SOCKET when set (the emulator of the real board
# image, `serve --socket PATH`, or any board serving the link on a Unix socket), else the
# simulated board, `host-sim board --socket`, in the background (through a serial device
# with RSPR_BOARD_VIA_PTY=1, below). Sets: bin (host-sim, or $RSPR_HOST_SIM),
# work (a temporary directory), sock (the board's socket); `started PID` registers a
# process to stop at exit.
set -euo pipefail
work="$(mktemp -d)"
pids=()
started() { pids+=("$1"); }
cleanup() {
    for p in "${pids[@]}"; do kill -INT "$p" 2>/dev/null || true; done
    for p in "${pids[@]}"; do
        for _ in $(seq 50); do kill -0 "$p" 2>/dev/null || break; sleep 0.1; done
        kill "$p" 2>/dev/null || true
        wait "$p" 2>/dev/null || true
    done
    rm -rf "$work"
}
trap cleanup EXIT

# RSPR_HOST_SIM=PATH: test that host-sim binary (one built elsewhere) instead of the one
# the test stage builds.
if [ -n "${RSPR_HOST_SIM:-}" ]; then
    bin="$RSPR_HOST_SIM"
    [ -x "$bin" ] || { echo "RSPR_HOST_SIM=$bin is not an executable"; exit 1; }
else
    source tests/host-sim-bin.sh
    bin="$(host_sim_bin)"
fi

if [ -n "${RSPR_BOARD_SOCKET:-}" ]; then
    sock="$RSPR_BOARD_SOCKET"
    echo "board: $sock (RSPR_BOARD_SOCKET)"
else
    sock="$work/board.sock"
    "$bin" board --socket "$sock" >"$work/board.log" 2>&1 &
    started $!
    for _ in $(seq 100); do [ -S "$sock" ] && break; sleep 0.05; done
    [ -S "$sock" ] || { cat "$work/board.log"; echo "the simulated board did not start"; exit 1; }
    echo "board: the simulated board on $sock"
fi

# RSPR_BOARD_VIA_PTY=1: the tests reach the board through a serial device, as they would a
# real board's UART: a pseudo-terminal that socat bridges to the board's socket (installed
# when missing). The front ends then take their serial-device path (`stty raw`, the device
# file) instead of the socket's.
if [ "${RSPR_BOARD_VIA_PTY:-0}" = 1 ]; then
    if ! command -v socat >/dev/null; then
        export DEBIAN_FRONTEND=noninteractive
        apt-get update -qq && apt-get install -y -qq socat >/dev/null
    fi
    tty="$work/board.tty"
    socat PTY,link="$tty",raw,echo=0 UNIX-CONNECT:"$sock" 2>"$work/socat.log" &
    started $!
    for _ in $(seq 100); do [ -e "$tty" ] && break; sleep 0.05; done
    [ -e "$tty" ] || { cat "$work/socat.log"; echo "socat did not make the pseudo-terminal"; exit 1; }
    echo "board: through the serial device $tty ($(readlink "$tty"), socat to $sock)"
    sock="$tty"
fi

# Seconds since the script started.
t0=$(date +%s.%N)
elapsed() { python3 -c "import time; print(f'{time.time() - $t0:.1f}')"; }
