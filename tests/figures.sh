#!/usr/bin/env bash
# Measures the figures the READMEs point to and writes them to FIGURES.md at the top of the
# repository (or to the file named as the first argument):
#
#   * the board image's text / data / bss (firmware/cortex-m/board/build-and-size.sh);
#   * the instructions of a control tick and of the whole period on the Cortex-M4, mean and
#     worst over the on-target scenario (firmware/cortex-m/on-target/run.sh cost);
#   * the default closed-loop simulation's headline figures: tracking and target error, the
#     setpoint's lag behind the master's stream, the real-time factor
#     (cargo run --release -p host-sim -- sim), and the same path without the backlash
#     compensation (sim --scenario backlash-off);
#   * the fault-injection campaign's pass counts (cargo run --release -p host-sim -- faults).
#
# Every figure is a line the measuring command prints, copied verbatim. The file states the
# commit measured (and whether the work tree differed from it) and when. Run time: a few
# minutes with warm caches, 20 minutes or more from clean target directories (release
# builds of the board image, the on-target images and host-sim).
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT="$(pwd)"
OUT="${1:-$ROOT/FIGURES.md}"
WORK="$(mktemp -d)"
trap 'rm -rf "$WORK"' EXIT

log() { printf '==> %s\n' "$*" >&2; }

# The lines of FILE that match the extended regular expression RE; fails when none does
# (the measuring command changed its output: this script must follow it).
lines() {
    local re="$1" file="$2"
    if ! grep -E -- "$re" "$file"; then
        echo "error: no line matching /$re/ in the output of $(basename "$file" .log)" >&2
        return 1
    fi
}

commit="$(git rev-parse --short=12 HEAD)"
subject="$(git log -1 --format=%s HEAD)"
dirty=""
if ! git diff --quiet HEAD -- . ':(exclude)FIGURES.md'; then
    dirty=" (with uncommitted changes in the work tree)"
fi
rustc_version="$(rustc --version)"
started="$(date -u '+%Y-%m-%d %H:%M UTC')"

log "board image: firmware/cortex-m/board/build-and-size.sh"
bash firmware/cortex-m/board/build-and-size.sh > "$WORK/size.log" 2>&1 ||
    { tail -n 20 "$WORK/size.log" >&2; exit 1; }

log "tick cost: firmware/cortex-m/on-target/run.sh cost"
bash firmware/cortex-m/on-target/run.sh cost > "$WORK/cost.log" 2>&1 ||
    { tail -n 20 "$WORK/cost.log" >&2; exit 1; }

log "default simulation: cargo run --release -p host-sim -- sim"
cargo run --quiet --release -p host-sim -- sim > "$WORK/sim.log" 2>&1 ||
    { tail -n 20 "$WORK/sim.log" >&2; exit 1; }

log "without backlash compensation: cargo run --release -p host-sim -- sim --scenario backlash-off"
cargo run --quiet --release -p host-sim -- sim --scenario backlash-off > "$WORK/sim-off.log" 2>&1 ||
    { tail -n 20 "$WORK/sim-off.log" >&2; exit 1; }

log "fault-injection campaign: cargo run --release -p host-sim -- faults"
# The campaign exits non-zero when a cell fails; its counts and the failing cells are the
# figures, so a failing cell is reported, and only a run that printed no counts fails here.
cargo run --quiet --release -p host-sim -- faults > "$WORK/faults.log" 2>&1 || true

{
    cat <<EOF
# Measured figures

Written by \`tests/figures.sh\`; do not edit by hand: run \`bash tests/figures.sh\` and commit
the result. Every line in the blocks below is printed by the command named above it.

* commit measured: \`$commit\` ("$subject")$dirty
* measured on: $started, on a machine with $(nproc) cores (load average when done:
  $(cut -d' ' -f1-3 /proc/loadavg))
* compiler: $rustc_version

## The board image

The release images (the STM32F405 board, the NUCLEO-F429ZI) and their budgets
(\`bash firmware/cortex-m/board/build-and-size.sh\`):

\`\`\`text
EOF
    lines '^rspr-.* release:' "$WORK/size.log"
    cat <<EOF
\`\`\`

## Instructions per control tick on the Cortex-M4

The control tick (the readings to the outputs) and the whole period (the tick and the work
after its outputs) over the on-target scenario, counted under QEMU
(\`bash firmware/cortex-m/on-target/run.sh cost\`; the per-part table and the profile are
in its output, \`firmware/cortex-m/on-target/README.md\` explains them):

\`\`\`text
EOF
    lines '^Full tick over the scenario|^at the max:|^After the outputs|^the whole period' "$WORK/cost.log"
    cat <<EOF
\`\`\`

## The default closed-loop simulation

The \`laparoscope\` scenario with the default settings
(\`cargo run --release -p host-sim -- sim\`; the real-time factor depends on the machine
and its load):

\`\`\`text
EOF
    lines '^sim |^  control |^  simulated |^  tracking error|^  target error|^  lag of the setpoint|^  pass [0-9]+:|^    the stream asks|^  accuracy target|^  supervisor:' "$WORK/sim.log"
    cat <<EOF
\`\`\`

The same path without the servo's backlash compensation, for comparison
(\`cargo run --release -p host-sim -- sim --scenario backlash-off\`):

\`\`\`text
EOF
    lines '^sim |^  tracking error|^  target error|^  pass [0-9]+:' "$WORK/sim-off.log"
    cat <<EOF
\`\`\`

## The fault-injection campaign

Every fault kind under every condition against the board application in simulation
(\`cargo run --release -p host-sim -- faults\`):

\`\`\`text
EOF
    lines '^cells: ' "$WORK/faults.log"
    grep -E '^FAILED ' "$WORK/faults.log" || true
    cat <<EOF
\`\`\`
EOF
} > "$WORK/FIGURES.md"
mv "$WORK/FIGURES.md" "$OUT"
log "wrote $OUT"
