#!/usr/bin/env bash
# Third-party OpenIGTLink clients against the server: pyigtl (PyPI) and a C++ client built
# on the reference library (Debian's libopenigtlink-dev), plus the reference library's own
# example ReceiveClient (openigtlink-examples) as an unmodified receiver.
#
#   bash host-sim/igtl/tests/third_party.sh              # starts the fake_robot example
#   bash host-sim/igtl/tests/third_party.sh HOST:PORT    # any running server
#   IGTL_SERVER=HOST:PORT bash host-sim/igtl/tests/third_party.sh
#
# IGTL_TOLERANCE_MM (default 0.05) is how close the measured pose must come to a target.
# Installs pyigtl, libopenigtlink-dev, g++ and openigtlink-examples when missing.
# Exits non-zero on any failure; prints the figures (latencies, messages, counters).
set -euo pipefail
cd "$(dirname "$0")/../../.."
here=host-sim/igtl/tests/third_party
addr="${1:-${IGTL_SERVER:-}}"
tol="${IGTL_TOLERANCE_MM:-0.05}"
work="$(mktemp -d)"
server_pid=""
cleanup() {
    if [ -n "$server_pid" ]; then kill "$server_pid" 2>/dev/null || true; wait "$server_pid" 2>/dev/null || true; fi
    rm -rf "$work"
}
trap cleanup EXIT

section() { printf '\n==> %s\n' "$*"; }

section "third-party OpenIGTLink clients: installing what is missing"
if ! python3 -c "import pyigtl" 2>/dev/null; then
    python3 -m pip install -q pyigtl
fi
python3 -c "import pyigtl, importlib.metadata as m; print('pyigtl', m.version('pyigtl'))"
apt_install() {
    export DEBIAN_FRONTEND=noninteractive
    if [ -z "${apt_updated:-}" ]; then apt-get update -qq; apt_updated=1; fi
    apt-get install -y -qq "$@" >/dev/null
}
if [ ! -f /usr/include/openigtlink/igtlClientSocket.h ] || ! command -v g++ >/dev/null; then
    apt_install libopenigtlink-dev g++
fi
examples=/usr/share/doc/openigtlink-examples/examples
if [ ! -d "$examples" ]; then
    if [ -z "${apt_updated:-}" ]; then export DEBIAN_FRONTEND=noninteractive; apt-get update -qq; apt_updated=1; fi
    if apt-cache show openigtlink-examples >/dev/null 2>&1; then apt_install openigtlink-examples; fi
fi
dpkg-query -W -f='${Package} ${Version}\n' libopenigtlink-dev

if [ -z "$addr" ]; then
    section "starting the fake_robot example on a free loopback port"
    cargo build -q -p igtl --example fake_robot
    target_dir="$(cargo metadata --format-version 1 --no-deps | python3 -c 'import json,sys; print(json.load(sys.stdin)["target_directory"])')"
    "$target_dir/debug/examples/fake_robot" --bind 127.0.0.1:0 >"$work/server.out" 2>"$work/server.err" &
    server_pid=$!
    for _ in $(seq 100); do
        grep -q '^listening on ' "$work/server.out" 2>/dev/null && break
        sleep 0.05
    done
    addr="$(sed -n 's/^listening on //p' "$work/server.out")"
    [ -n "$addr" ] || { cat "$work/server.err"; echo "fake_robot did not start"; exit 1; }
    fake=(--fake)
else
    fake=()
fi
host="${addr%:*}"
port="${addr##*:}"
echo "server: $addr"

section "pyigtl client"
timeout 180 python3 "$here/pyigtl_client.py" "$addr" --tolerance-mm "$tol" "${fake[@]}"

section "C++ client on libOpenIGTLink"
g++ -O2 -std=c++11 -I/usr/include/openigtlink "$here/cpp_client.cxx" -lOpenIGTLink -o "$work/cpp_client"
timeout 120 "$work/cpp_client" "$host" "$port" "$tol"

if [ -f "$examples/Receiver/ReceiveClient.cxx" ]; then
    section "the reference library's example ReceiveClient, unmodified, for 1.5 s"
    g++ -O2 -w -I/usr/include/openigtlink "$examples/Receiver/ReceiveClient.cxx" -lOpenIGTLink -o "$work/ReceiveClient"
    # It loops forever: stopped by timeout (exit status 124 expected).
    status=0
    timeout 1.5 "$work/ReceiveClient" "$host" "$port" >"$work/receive.log" 2>&1 || status=$?
    [ "$status" -eq 124 ] || { cat "$work/receive.log"; echo "ReceiveClient ended with status $status"; exit 1; }
    transforms=$(grep -c 'Receiving TRANSFORM data type' "$work/receive.log" || true)
    # PrintMatrix frames each matrix with two lines of '='; printed only when the CRC passed.
    matrices=$(( $(grep -c '^=============$' "$work/receive.log" || true) / 2 ))
    statuses=$(grep -c '========== STATUS ==========' "$work/receive.log" || true)
    strings=$(grep -c '^Encoding: ' "$work/receive.log" || true)
    echo "ReceiveClient: $transforms TRANSFORM received, $matrices CRC-checked and printed; $statuses STATUS and $strings STRING CRC-checked and printed"
    if [ "$transforms" -eq 0 ] && [ ${#fake[@]} -eq 0 ] && ! grep -q 'Time stamp' "$work/receive.log"; then
        echo "ReceiveClient: the server pushed nothing on connection (it streams on STT_TRANS only): not checked"
    else
        if [ "$transforms" -eq 0 ] || [ "$matrices" -ne "$transforms" ]; then
            tail -30 "$work/receive.log"; echo "ReceiveClient: TRANSFORM missing or failing its CRC check"; exit 1
        fi
        if [ "$strings" -eq 0 ]; then
            tail -30 "$work/receive.log"; echo "ReceiveClient: no STRING passed its CRC check"; exit 1
        fi
        grep -m1 '^Encoding: ' "$work/receive.log"
        grep -m1 -A4 '========== STATUS ==========' "$work/receive.log" || true
    fi
else
    echo "openigtlink-examples not available: ReceiveClient skipped"
fi

if [ -n "$server_pid" ]; then
    section "fake_robot log"
    cat "$work/server.err"
fi
echo
echo "third-party clients: OK"
