#!/usr/bin/env bash
# Builds the release board image for the STM32F405 (thumbv7em-none-eabihf) and prints its
# text / data / bss sizes; fails when over budget: text <= 256 KiB (a quarter of the
# STM32F405's 1 MiB flash: room for a second image for safe updates and a configuration
# sector), data + bss <= 32 KiB (a quarter of the 128 KiB main SRAM: the stack, which
# grows down from its top, and the DMA buffers keep the rest; the 64 KiB CCM stays free).
# Uses arm-none-eabi-size (Debian: binutils-arm-none-eabi, installed when missing).
set -euo pipefail
source "$(dirname "$0")/../scripts.sh"
cd "$CORTEX_M"

TEXT_BUDGET=$((256 * 1024))
RAM_BUDGET=$((32 * 1024))
ensure_target
ensure_apt arm-none-eabi-size binutils-arm-none-eabi
cargo build --release -p board
ELF="$(target_dir)/$TARGET/release/rspr-board"

arm-none-eabi-size "$ELF"
read -r text data bss _ < <(arm-none-eabi-size "$ELF" | awk 'NR == 2 { print $1, $2, $3 }')
ram=$((data + bss))
printf 'rspr-board release: text %d B (budget %d), data %d B, bss %d B, data+bss %d B (budget %d)\n' \
    "$text" "$TEXT_BUDGET" "$data" "$bss" "$ram" "$RAM_BUDGET"
status=0
if [ "$text" -gt "$TEXT_BUDGET" ]; then
    echo "error: text over budget by $((text - TEXT_BUDGET)) B" >&2
    status=1
fi
if [ "$ram" -gt "$RAM_BUDGET" ]; then
    echo "error: data+bss over budget by $((ram - RAM_BUDGET)) B" >&2
    status=1
fi
exit $status
