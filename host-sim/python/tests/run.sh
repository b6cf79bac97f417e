#!/usr/bin/env bash
# The Python module `rspr` (host-sim/python): installs it the way a user does (`pip install
# ./host-sim/python`, maturin building the wheel) into a virtual environment under target/,
# and runs its pytest suite against the `host-sim` binary of this workspace (RSPR_HOST_SIM,
# else the test profile's target/debug/host-sim, built here when missing: `cargo test
# --workspace` has normally built it already). Installs what it needs when missing:
# maturin, pytest, NumPy and matplotlib (into the venv). Fails loudly: any step that fails
# stops it.
#
# The build: the workspace's target directory (CARGO_TARGET_DIR, so a second run reuses
# the wheel's compiled crates) and the `wheel` profile (Cargo.toml: release without
# debug info, opt-level 2), with no build isolation (maturin is in the venv). The wheel's
# crates cannot reuse the workspace stage's: Cargo resolves the features of a build per
# selected package, and the wheel's build (rspr-python alone, with PyO3) enables fewer
# features on serde, syn, proc-macro2, typenum, memchr than `cargo test --workspace` does,
# so every crate above them differs (README.md, "Tests").
set -euo pipefail
cd "$(dirname "$0")/../../.."
started=$(date +%s)
step() { printf '  [python %3d s] %s\n' "$(( $(date +%s) - started ))" "$*"; }

export CARGO_TARGET_DIR=${CARGO_TARGET_DIR:-$PWD/target}
venv=$CARGO_TARGET_DIR/python-venv
if [ ! -x "$venv/bin/python" ]; then
    step "creating $venv"
    python3 -m venv "$venv"
fi
if ! "$venv/bin/python" -c 'import maturin, numpy, pytest, matplotlib' 2>/dev/null; then
    step "installing maturin, pytest, numpy and matplotlib into $venv"
    "$venv/bin/python" -m pip install --quiet --disable-pip-version-check \
        'maturin>=1.9,<2' pytest numpy matplotlib
fi

step "pip install ./host-sim/python (maturin $("$venv/bin/maturin" --version | cut -d' ' -f2), profile wheel, target $CARGO_TARGET_DIR)"
PATH="$venv/bin:$PATH" MATURIN_PEP517_ARGS="--profile wheel" \
    "$venv/bin/python" -m pip install --quiet --disable-pip-version-check \
    --no-build-isolation --force-reinstall --no-deps ./host-sim/python
step "wheel built and installed"

export RSPR_HOST_SIM=${RSPR_HOST_SIM:-$CARGO_TARGET_DIR/debug/host-sim}
if [ ! -x "$RSPR_HOST_SIM" ]; then
    step "building host-sim (test profile) for the CLI comparisons"
    cargo build --quiet --profile test -p host-sim
fi
step "pytest"
# From the tests' folder, so that `import rspr` finds the installed wheel, not the source.
(cd host-sim/python/tests && MPLBACKEND=Agg "$venv/bin/python" -m pytest -q -p no:cacheprovider .)
step "done"
