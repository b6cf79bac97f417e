# Shared by the Cortex-M4 workspace's scripts (source it): the target, the workspace's
# target directory (honours CARGO_TARGET_DIR and build.target-dir), and installing what
# a script needs when it is missing.
TARGET=thumbv7em-none-eabihf
CORTEX_M="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"

# The target directory cargo uses for this workspace.
target_dir() {
    (cd "$CORTEX_M" && cargo metadata --format-version 1 --no-deps) |
        python3 -c 'import json, sys; print(json.load(sys.stdin)["target_directory"])'
}

# The rustup target of rust-toolchain.toml (rustup fetches it on first use; this covers
# toolchains installed before the file named it).
ensure_target() {
    if ! rustup target list --installed | grep -qx "$TARGET"; then
        rustup target add "$TARGET"
    fi
}

# Installs Debian packages with apt when a command is missing: ensure_apt CMD PACKAGE...
ensure_apt() {
    local cmd="$1"
    shift
    if ! command -v "$cmd" >/dev/null 2>&1; then
        echo "==> $cmd is missing: installing $* with apt"
        local sudo=""
        if [ "$(id -u)" != 0 ]; then sudo="sudo -n"; fi
        $sudo env DEBIAN_FRONTEND=noninteractive apt-get update -qq
        $sudo env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "$@" >/dev/null
    fi
    command -v "$cmd" >/dev/null 2>&1 || { echo "error: $cmd is still missing" >&2; return 1; }
}
