#!/usr/bin/env bash
# The robot's 3-D scene against peers the project did not write (foxglove_peer.py): a
# WebSocket client written to the Foxglove SDK's protocol on `host-sim view` in front of
# the simulated board (homed first by `host-sim teleop --path line`, which leaves it Ready),
# and the `mcap` library on the simulation's MCAP. Installs websockets, protobuf, mcap and
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

"$bin" sim --scenario step --out "$work/sim" >"$work/sim.log" 2>&1 || { cat "$work/sim.log"; exit 1; }
python3 host-sim/scene/tests/foxglove_peer.py mcap "$work/sim/scene.mcap"
echo "the scene against a Foxglove WebSocket client and mcap: OK ($(elapsed) s)"
