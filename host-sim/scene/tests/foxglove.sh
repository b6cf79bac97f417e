#!/usr/bin/env bash
# The robot's 3-D scene against peers the project did not write (foxglove_peer.py): a
# WebSocket client written to the Foxglove SDK's protocol on `host-sim view` in front of
# the simulated board (homed first by `host-sim teleop --path line`, which leaves it Ready)
# and on `host-sim teleop --device scripted:... --view` (the targets as /servo_cp), and the
# `mcap` library on the simulation's MCAP. Installs websockets, protobuf, mcap and
# yourdfpy (PyPI) when missing.
#
#   bash host-sim/scene/tests/foxglove.sh
set -euo pipefail
cd "$(dirname "$0")/../../.."
source host-sim/operator/tests/board.sh

if ! python3 -c "import websockets, google.protobuf, mcap, yourdfpy" 2>/dev/null; then
    python3 -m pip install --user -q websockets protobuf mcap yourdfpy
fi

# Home the robot with another master, which disables it on the way out.
"$bin" teleop --connect "$sock" --path line --out "$work/teleop" >"$work/teleop.log" 2>&1 \
    || { cat "$work/teleop.log"; echo "teleop could not bring the board up"; exit 1; }
echo "board homed by teleop ($(elapsed) s)"

"$bin" view --connect "$sock" --listen 0 >"$work/view.out" 2>"$work/view.err" &
view=$!
started $view
for _ in $(seq 200); do
    grep -q '^Foxglove WebSocket on ' "$work/view.out" 2>/dev/null && break
    kill -0 $view 2>/dev/null || break
    sleep 0.05
done
url="$(sed -n 's/^Foxglove WebSocket on \(ws:[^ ]*\) .*/\1/p' "$work/view.out")"
[ -n "$url" ] || { cat "$work/view.out" "$work/view.err"; echo "host-sim view did not start"; exit 1; }
python3 host-sim/scene/tests/foxglove_peer.py ws "$url" "$work/teleop/status.csv"
kill -INT $view
for _ in $(seq 50); do kill -0 $view 2>/dev/null || break; sleep 0.1; done
cat "$work/view.out"
grep -q '^view: statuses [1-9]' "$work/view.out" || { cat "$work/view.err"; echo "the view put no status on its channels"; exit 1; }

# Teleoperation with the live view: a scripted operator moves 3 mm in x, then 2 mm in y,
# and back; the view carries its targets as /servo_cp.
cat >"$work/script.txt" <<'SCRIPT'
0.0  0 0 0  0 0 0  present
1.0  0 0 0  0 0 0  present
2.0  3 0 0  0 0 0  present
3.0  3 2 0  0 0 0  present
4.5  0 0 0  0 0 0  present
SCRIPT
"$bin" teleop --connect "$sock" --device "scripted:$work/script.txt" --view 0 --duration-s 6 \
    --record "$work/session.mcap" >"$work/tele.out" 2>"$work/tele.err" &
tele=$!
started $tele
for _ in $(seq 200); do
    grep -q '^Foxglove WebSocket on ' "$work/tele.out" 2>/dev/null && break
    kill -0 $tele 2>/dev/null || break
    sleep 0.05
done
url="$(sed -n 's/^Foxglove WebSocket on \(ws:[^ ]*\) .*/\1/p' "$work/tele.out")"
[ -n "$url" ] || { cat "$work/tele.out" "$work/tele.err"; echo "host-sim teleop --view did not start"; exit 1; }
python3 host-sim/scene/tests/foxglove_peer.py ws-teleop "$url"
wait $tele || { cat "$work/tele.out" "$work/tele.err"; echo "host-sim teleop --view failed"; exit 1; }

"$bin" sim --scenario step --out "$work/sim" >"$work/sim.log" 2>&1 || { cat "$work/sim.log"; exit 1; }
python3 host-sim/scene/tests/foxglove_peer.py mcap "$work/sim/scene.mcap"
echo "the scene against a Foxglove WebSocket client and mcap: OK ($(elapsed) s)"
