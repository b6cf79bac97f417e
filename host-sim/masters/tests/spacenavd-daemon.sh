#!/usr/bin/env bash
# The spacenavd client against Debian's real daemon (no device needed): installs
# spacenavd when missing, then runs the ignored test tests/spacenavd_daemon.rs.
set -euo pipefail
cd "$(dirname "$0")/../../.."
if ! command -v spacenavd >/dev/null 2>&1; then
    echo "installing spacenavd (Debian package)"
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq
    apt-get install -y -qq --no-install-recommends spacenavd >/dev/null
fi
spacenavd -V 2>&1 | head -1 || true
cargo test -p masters --test spacenavd_daemon -- --ignored
