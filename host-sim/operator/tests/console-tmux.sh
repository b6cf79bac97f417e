#!/usr/bin/env bash
# The console as a person uses it: `host-sim console` in an 80x24 tmux window
# against the board (the simulated board, or $RSPR_BOARD_SOCKET: see board.sh), driven
# with send-keys and read with capture-pane. It homes, enables, jogs joint l1, triggers
# refused commands (Enable and a typed pose target before homing; re-homing, confirmed,
# while enabled), types pose targets that the board's guards refuse (the workspace, the
# platform tilt, the stroke: each named on the screen with its value and limit), stops
# and clears the fault, and reads each on the screen. Installs tmux when missing.
#
#   bash host-sim/operator/tests/console-tmux.sh
#
# RSPR_CONSOLE_NOT_HOMED_ONLY=1: only the steps on a board not homed (the screen, the
# Hello, a refused Enable), then quit: what a serial device must carry, whatever its
# timing (the board watches the master's heartbeat only while it homes or is enabled).
#
# Every wait is for a text to appear on the screen within a bound (homing 60 s, the rest
# 5 s, as the board takes them on a desk), times RSPR_WAIT_SCALE (default 4): the bounds
# are failure detectors on the host's clock, generous enough for a machine whose cores are
# busy, never what the test checks. Nothing is retried. Exits non-zero on the first
# failure, printing the screen.
set -euo pipefail
cd "$(dirname "$0")/../../.."
if ! command -v tmux >/dev/null; then
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq && apt-get install -y -qq tmux >/dev/null
fi
tmux -V
source host-sim/operator/tests/board.sh

session="rspr-console-$$"
tmux -L "$session" new-session -d -s console -x 80 -y 24 "$bin console --connect $sock; sleep 5"
quit_tmux() { tmux -L "$session" kill-server 2>/dev/null || true; }
trap 'quit_tmux; cleanup' EXIT

screen() { tmux -L "$session" capture-pane -p -t console; }
keys() { tmux -L "$session" send-keys -t console "$@"; }
fail() { echo "FAILED: $*"; echo "--- screen:"; screen; exit 1; }
wait_scale="${RSPR_WAIT_SCALE:-4}"
# wait_for TEXT SECONDS: the screen shows TEXT (a fixed string) within SECONDS times
# wait_scale.
wait_for() {
    local bound=$(( $2 * wait_scale ))
    local end=$(( $(date +%s) + bound ))
    while ! screen | grep -qF -- "$1"; do
        [ "$(date +%s)" -lt "$end" ] || fail "'$1' not on the screen within $bound s"
        sleep 0.1
    done
    echo "  [$(elapsed) s] on screen: $1"
}
# The joint values of the Joints line: l1 l2 l3 (mm) th1 th2 th3 (deg).
joints() { screen | sed -n 's/.*Joints   l1-l3 *\([-0-9.]*\) *\([-0-9.]*\) *\([-0-9.]*\) mm  th1-th3 *\([-0-9.]*\) *\([-0-9.]*\) *\([-0-9.]*\) deg.*/\1 \2 \3 \4 \5 \6/p'; }

# quit: q, and the console quits (the pane runs "console; sleep 5": once the console has
# quit, its command is sleep).
quit_console() {
    echo "==> quit"
    keys q
    local cmd
    for _ in $(seq 50); do
        cmd=$(tmux -L "$session" list-panes -t console -F '#{pane_current_command}')
        [ "$cmd" = sleep ] && break
        sleep 0.1
    done
    [ "$cmd" = sleep ] || fail "the console did not quit (pane runs $cmd)"
    echo
    echo "console under tmux: OK ($(elapsed) s)"
}

echo "==> the console at 80x24: keys on screen, the board's state"
wait_for "h hello o home e enable d disable c clear fault s/SPACE stop q quit" 5
wait_for "1-6 joint +/- jog [ ] speed k clutch p dead-man a ack reset t target" 5
wait_for "Hello -> firmware" 10
wait_for "Homed no" 5
# Characters, not bytes (the frame's box-drawing characters are 3 bytes each in UTF-8, and
# Debian's default awk, mawk, counts bytes).
lines=$(screen | wc -l)
cols=$(screen | python3 -c 'import sys; print(max((len(l) for l in sys.stdin.buffer.read().decode("utf-8").splitlines()), default=0))')
echo "  screen: $lines lines, widest $cols columns"
[ "$lines" -le 24 ] && [ "$cols" -le 80 ] || fail "the screen is not 80x24"

echo "==> a refused command: Enable before homing"
keys e
wait_for "Enable REFUSED: not homed: home the robot first" 5

# target LINE: types a pose target (t, the line, Enter) and waits for the console to
# echo it as sent.
target() {
    keys t
    wait_for "Target x y z [mm] rx ry rz [deg]: _" 5
    keys -l "$1"
    keys Enter
}
echo "==> a typed target: a line that is not six numbers is refused on the spot, then Esc"
keys t
keys -l "0 0 abc 0 0 0"
keys Enter
wait_for 'target not sent: z mm is "abc", not a number' 5
keys Escape
wait_for "target cancelled" 5
echo "==> a refused target: before homing"
target "0 0 160 0 0 0"
wait_for "Target REFUSED: not homed: home the robot first" 5
if [ "${RSPR_CONSOLE_NOT_HOMED_ONLY:-0}" = 1 ]; then
    quit_console
    exit 0
fi

echo "==> home"
keys o
wait_for "Home -> Ack" 5
wait_for "State Ready" 60
wait_for "Homed yes" 5

echo "==> the dead-man: a new session starts with the operator absent"
keys p
wait_for "Operator present -> Ack" 5

echo "==> enable (the board answers Busy while its brakes engage: the console sends it again)"
keys e
wait_for "Enable -> Ack" 5
wait_for "State Enabled" 5

echo "==> jog joint l1 at +1 mm/s"
keys 1
wait_for "joint l1 (1-6)  speed 1 mm/s" 5
# As a person jogs: + again every 0.2 s (each press keeps the jog going for 0.3 s) until
# l1 has moved 1 mm on the screen (at most 15 s times wait_scale), then let go. By the board's own clock,
# not the host's: an emulated board that its host stalls moves less in a wall-clock
# second (its first jog also runs the jog's code for the first time, which stalls it),
# but it moves as far on as many of its own seconds.
read -r l1 l2 l3 a1 a2 a3 <<<"$(joints)"
echo "  joints before: l1 $l1 l2 $l2 l3 $l3 mm, th $a1 $a2 $a3 deg"
presses=0
end=$(( $(date +%s) + 15 * wait_scale ))
while awk -v a="$l1" -v b="$(joints | cut -d' ' -f1)" 'BEGIN { exit !(b - a < 1.0) }'; do
    [ "$(date +%s)" -lt "$end" ] || fail "l1 did not move 1 mm within $(( 15 * wait_scale )) s of jogging"
    keys +
    presses=$((presses + 1))
    sleep 0.2
done
echo "  [$(elapsed) s] l1 moved 1 mm on the screen after $presses presses"
wait_for "Jog l1 +1.0 mm/s -> Ack" 5
# Let go: the jog stream ends 0.3 s after the last press, the board stops the jog 0.1 s
# after the last Jog; then l1 stands still (two readings 0.5 s apart).
sleep 1.0
read -r m1 m2 m3 b1 b2 b3 <<<"$(joints)"
sleep 0.5
read -r n1 _ <<<"$(joints)"
echo "  joints after:  l1 $m1 l2 $m2 l3 $m3 mm, th $b1 $b2 $b3 deg; 0.5 s later l1 $n1 mm"
# l1 moved at least the 1 mm it was jogged for and at most 1 mm more: the last press came
# while the screen showed less than 1 mm (the screen trails l1 by up to 70 ms: a 50 ms
# redraw and a 20 ms status), and it keeps the jog going for its 0.3 s stream and the
# board's 0.1 s run-on; at 1 mm/s, about 0.5 mm more. Then l1 stands still: within two
# counts (0.003 mm) and the screen's rounding (0.001 mm). The other joints hold under
# their servos: as l1 moves, the load on them changes and their following error by up to
# two counts (legs 0.003 mm, links 0.010 deg); the screen rounds to 0.001 mm and 0.01
# deg, so a difference of two readings is off by up to one more step. Bounds: 0.01 mm,
# and 0.02 deg (+1e-9 for the decimal strings' float difference).
python3 - "$l1 $l2 $l3 $a1 $a2 $a3" "$m1 $m2 $m3 $b1 $b2 $b3" "$n1" <<'PY' || fail "jog"
import sys
a = [float(x) for x in sys.argv[1].split()]
b = [float(x) for x in sys.argv[2].split()]
later = float(sys.argv[3])
d = [y - x for x, y in zip(a, b)]
print(f"  l1 moved {d[0]:.3f} mm, then {later - b[0]:.3f} mm; the others {max(abs(x) for x in d[1:3]):.3f} mm, {max(abs(x) for x in d[3:]):.3f} deg")
assert 1.0 <= d[0] <= 2.0, "l1 did not move between 1 and 2 mm"
assert abs(later - b[0]) <= 0.004 + 1e-9, "l1 did not stop after the jog"
assert max(abs(x) for x in d[1:3]) <= 0.01 and max(abs(x) for x in d[3:]) <= 0.02 + 1e-9, "another joint moved"
PY

# Targets the guards refuse, each named with its value and limit (the board checks a
# target's end first, so the value is the target's): z 177 mm against the workspace box
# (hc 160 mm + 10 mm + its 5 mm margin); 28 deg about x against the 25 deg platform tilt;
# and a pose inside the box and the tilt cone (x 20, y 20, z 148 mm, rotation vector
# (0, 22, 17) deg: platform tilt 21.9 deg, link angles within 35 deg) whose leg 1 is
# 134.0 mm, below the 144 mm stroke (the inverse kinematics, Eq. 6.22; `host-sim check
# --pose 20,20,148,0,22,17` lists it as the first stop).
echo "==> targets the guards refuse: the workspace, the platform tilt, the stroke"
target "0 0 177 0 0 0"
wait_for "workspace z 177.0 mm > 175.0 mm" 5
target "0 0 160 28 0 0"
wait_for "platform tilt 28.0 deg > 25.0 deg" 5
target "20 20 148 0 22 17"
wait_for "stroke leg 1 134.0 mm < 144.0 mm" 5
wait_for "State Enabled" 5

echo "==> a refused command: re-homing (confirmed) while enabled"
keys o
wait_for "Robot is homed. Re-home" 5
keys y
wait_for "Re-home REFUSED" 5

echo "==> stop, then clear the fault"
keys s
wait_for "Stop -> Ack" 5
wait_for "State Fault" 5
wait_for "Fault    e-stop message" 5
keys c
wait_for "Clear fault -> Ack" 5

# The console's own timing: the longest interval between two of its heartbeats (due
# every 20 ms; the board holds after 100 ms without one, and turns the drives off after
# 500 ms). Printed, not judged: a loaded host may delay it; the board judges it.
echo "  the console's heartbeats: $(screen | grep -o 'beat gap [0-9]* ms') at most"

quit_console
