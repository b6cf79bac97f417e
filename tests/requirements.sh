# Sourced by tests/run-all.sh: installs, before any stage runs, what the stages that run side
# by side need from Debian and PyPI (each stage's script checks again and installs what is
# still missing, so it also runs alone). Installing up front keeps two stages from running
# apt-get or pip at the same moment: apt-get refuses a second run while one holds dpkg's
# lock, and two pip runs may write the same package at once.
install_requirements() {
    local apt_missing=()
    command -v /usr/bin/time >/dev/null 2>&1 || apt_missing+=(time)
    command -v arm-none-eabi-size >/dev/null 2>&1 || apt_missing+=(binutils-arm-none-eabi)
    command -v qemu-system-arm >/dev/null 2>&1 || apt_missing+=(qemu-system-arm)
    command -v tmux >/dev/null 2>&1 || apt_missing+=(tmux)
    command -v socat >/dev/null 2>&1 || apt_missing+=(socat)
    command -v spacenavd >/dev/null 2>&1 || apt_missing+=(spacenavd)
    command -v check_urdf >/dev/null 2>&1 || apt_missing+=(liburdfdom-tools)
    command -v g++ >/dev/null 2>&1 || apt_missing+=(g++)
    [ -f /usr/include/openigtlink/igtlClientSocket.h ] || apt_missing+=(libopenigtlink-dev)
    if [ ${#apt_missing[@]} -gt 0 ] || [ ! -d /usr/share/doc/openigtlink-examples/examples ]; then
        local sudo=""
        if [ "$(id -u)" != 0 ]; then sudo="sudo -n"; fi
        $sudo env DEBIAN_FRONTEND=noninteractive apt-get update -qq
        if apt-cache show openigtlink-examples >/dev/null 2>&1 &&
            [ ! -d /usr/share/doc/openigtlink-examples/examples ]; then
            apt_missing+=(openigtlink-examples)
        fi
        if [ ${#apt_missing[@]} -gt 0 ]; then
            echo "==> apt: installing ${apt_missing[*]}"
            $sudo env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq \
                --no-install-recommends "${apt_missing[@]}" >/dev/null
        fi
    fi
    # The Python test clients (the Python module's own tests use a venv of their own).
    local pip_missing=()
    python3 -c "import pyigtl" 2>/dev/null || pip_missing+=(pyigtl)
    python3 -c "import yourdfpy" 2>/dev/null || pip_missing+=(yourdfpy)
    python3 -c "import websockets" 2>/dev/null || pip_missing+=(websockets)
    python3 -c "import google.protobuf" 2>/dev/null || pip_missing+=(protobuf)
    python3 -c "import mcap" 2>/dev/null || pip_missing+=(mcap)
    python3 -c "import cyclonedds" 2>/dev/null || pip_missing+=(cyclonedds)
    if [ ${#pip_missing[@]} -gt 0 ]; then
        echo "==> pip (--user): installing ${pip_missing[*]}"
        python3 -m pip install --user -q "${pip_missing[@]}"
    fi
}
