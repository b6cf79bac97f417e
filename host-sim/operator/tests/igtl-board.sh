#!/usr/bin/env bash
# OpenIGTLink against the board: `host-sim igtl` in front of the board (the
# simulated board, or $RSPR_BOARD_SOCKET: see board.sh), brought up (homed, enabled) by
# the bridge, and the third-party clients of host-sim/igtl/tests/third_party.sh: pyigtl
# (targets in protocol versions 2 and 3, a refused target's STATUS, garbage on the
# connection, counters), a C++ client on Debian's libopenigtlink-dev (GET_TRANS round
# trips, a 2 mm target read back), and the library's example ReceiveClient. Each sends a
# target and reads the measured pose back. Installs pyigtl, libopenigtlink-dev, g++ and
# openigtlink-examples when missing.
#
#   bash host-sim/operator/tests/igtl-board.sh
#
# IGTL_TOLERANCE_MM (default 0.2 here): how close the measured pose must come to a target.
# The board's measured pose is the forward kinematics of the motor-side encoders; with the
# legs' backlash (0.12 mm in the plant) compensated it stands up to ~0.15 mm from the
# setpoint in the direction of the last motion (host-sim/operator/tests/scripted_operator.rs).
set -euo pipefail
cd "$(dirname "$0")/../../.."
source host-sim/operator/tests/board.sh

"$bin" igtl --connect "$sock" --listen 127.0.0.1:0 --enable >"$work/igtl.out" 2>"$work/igtl.err" &
bridge=$!
started $bridge
for _ in $(seq 1200); do
    grep -q '^OpenIGTLink on ' "$work/igtl.out" 2>/dev/null && break
    kill -0 $bridge 2>/dev/null || break
    sleep 0.1
done
addr="$(sed -n 's/^OpenIGTLink on \([0-9.:]*\) .*/\1/p' "$work/igtl.out")"
[ -n "$addr" ] || { cat "$work/igtl.out" "$work/igtl.err"; echo "host-sim igtl did not start"; exit 1; }
cat "$work/igtl.out"
echo "bridge ready after $(elapsed) s"

IGTL_TOLERANCE_MM="${IGTL_TOLERANCE_MM:-0.2}" bash host-sim/igtl/tests/third_party.sh "$addr"

kill -INT $bridge
for _ in $(seq 50); do kill -0 $bridge 2>/dev/null || break; sleep 0.1; done
echo "--- bridge"
cat "$work/igtl.out" "$work/igtl.err"
grep -q '^igtl: targets accepted [1-9]' "$work/igtl.out" || { echo "the bridge took no target"; exit 1; }
echo
echo "OpenIGTLink against the board: OK ($(elapsed) s)"
