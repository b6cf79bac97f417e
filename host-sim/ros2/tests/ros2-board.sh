#!/usr/bin/env bash
# ROS 2 against the board: `host-sim ros2` in front of the simulated board (or
# $RSPR_BOARD_SOCKET: see host-sim/operator/tests/board.sh), brought up (homed, enabled),
# and a peer the project did not write: CycloneDDS's Python binding (PyPI `cyclonedds`,
# installed when missing) with the ROS 2 type names and topic mangling written out in
# crtk_peer.py (what it checks: its docstring). DDS stays on the loopback on both sides:
# `host-sim ros2 --network loopback` (the default) and CYCLONEDDS_URI =
# cyclonedds-loopback.xml (no multicast, unicast discovery on 127.0.0.1).
#
#   bash host-sim/ros2/tests/ros2-board.sh
#
# TOLERANCE_MM (default 0.05): how close measured_cp must come to a servo_cp.
set -euo pipefail
cd "$(dirname "$0")/../../.."
here=host-sim/ros2/tests
source host-sim/operator/tests/board.sh

if ! python3 -c "import cyclonedds" 2>/dev/null; then
    python3 -m pip install -q --user cyclonedds 2>/dev/null || python3 -m pip install -q cyclonedds
fi
python3 -c "import importlib.metadata as m; print('cyclonedds', m.version('cyclonedds'))"

export CYCLONEDDS_URI="file://$PWD/$here/cyclonedds-loopback.xml"
# A domain of its own, so that another test's node on this machine is not in the way.
export ROS_DOMAIN_ID="${ROS_DOMAIN_ID:-$(( 100 + $$ % 100 ))}"

"$bin" ros2 --connect "$sock" --enable >"$work/ros2.out" 2>"$work/ros2.err" &
bridge=$!
started $bridge
for _ in $(seq 1200); do
    grep -q '^ROS 2 node ' "$work/ros2.out" 2>/dev/null && break
    kill -0 $bridge 2>/dev/null || break
    sleep 0.1
done
grep -q '^ROS 2 node ' "$work/ros2.out" || { cat "$work/ros2.out" "$work/ros2.err"; echo "host-sim ros2 did not start"; exit 1; }
cat "$work/ros2.out"
echo "node ready after $(elapsed) s (domain $ROS_DOMAIN_ID)"

# The URDF of the geometry the node runs, whose joint names /joint_states must carry.
"$bin" describe --urdf --out "$work/rspr.urdf"

status=0
TOLERANCE_MM="${TOLERANCE_MM:-0.05}" RSPR_URDF="$work/rspr.urdf" HOST_SIM="$bin" \
    timeout 300 python3 "$here/crtk_peer.py" || status=$?

kill -INT $bridge
for _ in $(seq 50); do kill -0 $bridge 2>/dev/null || break; sleep 0.1; done
echo "--- host-sim ros2"
cat "$work/ros2.out" "$work/ros2.err"
[ "$status" = 0 ] || { echo "the ROS 2 peer failed"; exit 1; }
rate="$(sed -n 's/^ros2: [0-9]* statuses published at \([0-9.]*\) Hz.*/\1/p' "$work/ros2.out")"
[ -n "$rate" ] || { echo "no summary from host-sim ros2"; exit 1; }
python3 -c "import sys; r = float('$rate'); sys.exit(0 if r >= 99.0 else 1)" \
    || { echo "the node published at $rate Hz of the board's clock, not 100"; exit 1; }
echo
echo "ROS 2 against the board: OK ($(elapsed) s; $rate Hz on the board's clock)"
