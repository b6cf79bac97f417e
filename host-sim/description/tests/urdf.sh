#!/usr/bin/env bash
# The robot description against peers the project did not write: Debian's check_urdf
# (liburdfdom-tools) accepts the URDF of every geometry (reference RSPR, USR, a calibrated
# per-chain RSPR), and yourdfpy (PyPI) poses it from the joint states of 60 poses across the
# task box (both orientations) to the controller's forward kinematics within 1e-6 m
# (urdf_peer.py). Installs liburdfdom-tools and yourdfpy when missing.
#
#   bash host-sim/description/tests/urdf.sh [HOST_SIM_BINARY]
set -euo pipefail
cd "$(dirname "$0")/../../.."
bin="${1:-}"
if [ -z "$bin" ]; then
    source tests/host-sim-bin.sh
    bin="$(host_sim_bin)"
fi
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT

if ! command -v check_urdf >/dev/null; then
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq && apt-get install -y -qq liburdfdom-tools >/dev/null
fi
if ! python3 -c "import yourdfpy" 2>/dev/null; then
    python3 -m pip install --user -q yourdfpy
fi

# A calibrated geometry: identified from the measurements `calibrate simulate` makes.
"$bin" calibrate simulate --out "$work/sim" >"$work/cal.log" 2>&1 || { cat "$work/cal.log"; exit 1; }
"$bin" calibrate --measurements "$work/sim/measurements.csv" --out "$work/cal" >>"$work/cal.log" 2>&1 || { cat "$work/cal.log"; exit 1; }
for g in rspr usr calibrated; do
    case $g in
        rspr) sel=(--robot rspr) ;;
        usr) sel=(--robot usr) ;;
        calibrated) sel=(--geometry "$work/cal/calibrated.toml") ;;
    esac
    "$bin" "${sel[@]}" describe --urdf --out "$work/$g.urdf"
    check_urdf "$work/$g.urdf" >"$work/$g.check" || { cat "$work/$g.check"; echo "check_urdf refused the $g URDF"; exit 1; }
    echo "check_urdf accepts the $g URDF: $(grep -c '^ *child(' "$work/$g.check" || true) child entries, root $(sed -n 's/^root Link: \([a-z_0-9]*\).*/\1/p' "$work/$g.check")"
    # 60 poses across the task box (scaled to the robot: the USR's box is half the RSPR's),
    # platform parallel and tilted up to 20 deg, from a fixed seed.
    python3 - "$g" >"$work/$g.poses.csv" <<'PY'
import random, sys
random.seed(35)
s = 0.5 if sys.argv[1] == "usr" else 1.0
hc = 80.0 if sys.argv[1] == "usr" else 160.0
print("x_mm,y_mm,z_mm,rx_deg,ry_deg,rz_deg")
for k in range(60):
    tilt = 0.0 if k % 2 == 0 else 20.0
    print(f"{random.uniform(-20, 20) * s},{random.uniform(-20, 20) * s},{hc + random.uniform(-10, 10) * s},"
          f"{random.uniform(-1, 1) * tilt / 1.4142},{random.uniform(-1, 1) * tilt / 1.4142},{random.uniform(-5, 5)}")
PY
    "$bin" "${sel[@]}" ik --csv <"$work/$g.poses.csv" >"$work/$g.joints.csv" 2>/dev/null
    "$bin" "${sel[@]}" fk --csv <"$work/$g.joints.csv" >"$work/$g.fk.csv" 2>/dev/null
    "$bin" "${sel[@]}" describe --joint-states <"$work/$g.joints.csv" >"$work/$g.states.csv"
    # The controller's FK pose beside the description's joint states, row by row.
    python3 - "$work/$g.fk.csv" "$work/$g.states.csv" >"$work/$g.csv" <<'PY'
import csv, sys
fk = list(csv.DictReader(open(sys.argv[1])))
st = list(csv.DictReader(open(sys.argv[2])))
assert len(fk) == len(st), (len(fk), len(st))
pose = ["x_mm", "y_mm", "z_mm", "rx_deg", "ry_deg", "rz_deg"]
names = [c for c in st[0].keys() if c not in pose and c != "error"]
w = csv.writer(sys.stdout)
w.writerow([f"fk_{c}" for c in pose] + names + ["error"])
for a, b in zip(fk, st):
    if a["error"] or b["error"]:
        w.writerow([""] * (6 + len(names)) + [a["error"] or b["error"]])
        continue
    w.writerow([a[c] for c in pose] + [b[c] for c in names] + [""])
PY
    python3 host-sim/description/tests/urdf_peer.py "$work/$g.urdf" "$work/$g.csv" $([ $g = calibrated ] || echo --symmetric)
done
echo "robot description against check_urdf and yourdfpy: OK"
