#!/usr/bin/env bash
# The Python module `rspr` (host-sim/python): builds the wheel with maturin (release,
# stripped), installs it into a virtual environment under target/, and runs its pytest
# suite against the `host-sim` binary of this workspace (RSPR_HOST_SIM, else the test
# profile's target/debug/host-sim, built here when missing: `cargo test --workspace`
# has normally built it already). Installs what it needs when missing: maturin (pip
# --user), pytest and NumPy (into the venv). Fails loudly: any step that fails stops it.
set -euo pipefail
cd "$(dirname "$0")/../../.."
started=$(date +%s)
step() { printf '  [python %3d s] %s\n' "$(( $(date +%s) - started ))" "$*"; }

export PATH="$(python3 -m site --user-base)/bin:$PATH"
if ! command -v maturin >/dev/null; then
    step "installing maturin (pip --user)"
    python3 -m pip install --user --quiet --disable-pip-version-check 'maturin>=1.9,<2'
fi
venv=$PWD/target/python-venv
if [ ! -x "$venv/bin/python" ]; then
    step "creating $venv"
    python3 -m venv --system-site-packages "$venv"
fi
if ! "$venv/bin/python" -c 'import numpy, pytest' 2>/dev/null; then
    step "installing pytest and numpy into $venv"
    "$venv/bin/python" -m pip install --quiet --disable-pip-version-check pytest numpy
fi

step "maturin build --release --strip ($(maturin --version))"
rm -f target/wheels/rspr-*.whl
(cd host-sim/python && maturin build --release --strip --quiet --out ../../target/wheels)
"$venv/bin/python" -m pip install --quiet --disable-pip-version-check --force-reinstall --no-deps target/wheels/rspr-*.whl

export RSPR_HOST_SIM=${RSPR_HOST_SIM:-$PWD/target/debug/host-sim}
if [ ! -x "$RSPR_HOST_SIM" ]; then
    step "building host-sim (test profile) for the CLI comparisons"
    cargo build --quiet --profile test -p host-sim
fi
step "pytest"
# From the tests' folder, so that `import rspr` finds the installed wheel, not the source.
(cd host-sim/python/tests && "$venv/bin/python" -m pytest -q -p no:cacheprovider .)
step "done"
