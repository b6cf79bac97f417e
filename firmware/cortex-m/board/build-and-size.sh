#!/usr/bin/env bash
# Builds the release board images (thumbv7em-none-eabihf) and prints their text / data /
# bss sizes; fails when one is over budget. Every target has the same budget, because every
# target has the same memory map (board/memory.x: the STM32F405's 1 MiB of flash, sectors
# 0..11, which the STM32F429ZI's bank 1 repeats, and 128 KiB of SRAM1 + SRAM2):
# text <= 256 KiB (a quarter of that flash: room for a second image for safe updates and a
# configuration sector), data + bss <= 32 KiB (a quarter of the 128 KiB: the stack, which
# grows down from its top, and the DMA buffers keep the rest).
#
#   build-and-size.sh            every target: board (STM32F405RG), board-position-channel,
#                                board-nucleo-f429zi
#   build-and-size.sh board      one target (the package)
#
# board-position-channel is the board package built for the board with the second position
# channel (`--no-default-features --features position-channel`: the STM32F405ZG, a
# potentiometer per joint on an AD7689 on SPI3), measured against the same budgets; its ELF is copied to
# `rspr-board-position-channel` beside the others (the board emulator's tests run it), and
# the default build then puts `rspr-board` back (cargo keeps both builds' artifacts: the
# chip's feature gives them different hashes, so that is a link at most).
#
# One cargo invocation per target: embassy-stm32 selects the chip by a Cargo feature and
# cargo unifies features over an invocation, so two chips cannot be built in one. They
# share the workspace, its lock file and its target directory: the second target rebuilds
# only embassy-stm32 (and its chip's register tables), its own crate and the link.
# Uses arm-none-eabi-size (Debian: binutils-arm-none-eabi, installed when missing).
set -euo pipefail
source "$(dirname "$0")/../scripts.sh"
cd "$CORTEX_M"

TEXT_BUDGET=$((256 * 1024))
RAM_BUDGET=$((32 * 1024))
ensure_target
ensure_apt arm-none-eabi-size binutils-arm-none-eabi

# target -> binary
declare -A BIN=([board]=rspr-board [board-nucleo-f429zi]=rspr-nucleo-f429zi [board-position-channel]=rspr-board)
# target -> cargo arguments (default: -p TARGET)
declare -A ARGS=([board-position-channel]="-p board --no-default-features --features position-channel")
# target -> the name its ELF is copied to (default: none, cargo's own)
declare -A COPY=([board-position-channel]=rspr-board-position-channel)
targets=("$@")
if [ ${#targets[@]} -eq 0 ]; then
    targets=(board board-position-channel board-nucleo-f429zi)
fi

status=0
for pkg in "${targets[@]}"; do
    bin="${BIN[$pkg]:-}"
    if [ -z "$bin" ]; then
        echo "error: unknown board target '$pkg' (known: ${!BIN[*]})" >&2
        exit 2
    fi
    t0=$(date +%s)
    # shellcheck disable=SC2086 # the arguments are words
    cargo build --release ${ARGS[$pkg]:--p $pkg}
    ELF="$(target_dir)/$TARGET/release/$bin"
    if [ -n "${COPY[$pkg]:-}" ]; then
        cp "$ELF" "$(target_dir)/$TARGET/release/${COPY[$pkg]}"
        ELF="$(target_dir)/$TARGET/release/${COPY[$pkg]}"
        bin="${COPY[$pkg]}"
        cargo build --release -p board
    fi
    arm-none-eabi-size "$ELF"
    read -r text data bss _ < <(arm-none-eabi-size "$ELF" | awk 'NR == 2 { print $1, $2, $3 }')
    ram=$((data + bss))
    printf '%s release: text %d B (budget %d), data %d B, bss %d B, data+bss %d B (budget %d)\n' \
        "$bin" "$text" "$TEXT_BUDGET" "$data" "$bss" "$ram" "$RAM_BUDGET"
    echo "($pkg built and measured in $(( $(date +%s) - t0 )) s)"
    if [ "$text" -gt "$TEXT_BUDGET" ]; then
        echo "error: $bin: text over budget by $((text - TEXT_BUDGET)) B" >&2
        status=1
    fi
    if [ "$ram" -gt "$RAM_BUDGET" ]; then
        echo "error: $bin: data+bss over budget by $((ram - RAM_BUDGET)) B" >&2
        status=1
    fi
done
exit $status
