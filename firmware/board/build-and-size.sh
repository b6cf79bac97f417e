#!/usr/bin/env bash
# Builds the release firmware for the STM32F405 (thumbv7em-none-eabihf) and prints its
# text / data / bss sizes; fails when over budget: text <= 96 KiB, data + bss <= 24 KiB.
# Uses arm-none-eabi-size (Debian: binutils-arm-none-eabi, installed here when missing);
# falls back to llvm-size (same Berkeley format) if it cannot be installed.
set -euo pipefail
cd "$(dirname "$0")"

TEXT_BUDGET=$((96 * 1024))
RAM_BUDGET=$((24 * 1024))
TARGET=thumbv7em-none-eabihf
ELF=target/$TARGET/release/rspr-board

if ! rustup target list --installed | grep -qx "$TARGET"; then
    rustup target add "$TARGET"
fi

cargo build --release

SIZE=arm-none-eabi-size
if ! command -v "$SIZE" >/dev/null 2>&1; then
    SUDO=""
    if [ "$(id -u)" -ne 0 ] && command -v sudo >/dev/null 2>&1; then SUDO=sudo; fi
    if command -v apt-get >/dev/null 2>&1; then
        echo "installing binutils-arm-none-eabi (for arm-none-eabi-size)"
        $SUDO apt-get update -qq || true
        $SUDO env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq binutils-arm-none-eabi || true
    fi
fi
if ! command -v "$SIZE" >/dev/null 2>&1; then
    if command -v llvm-size >/dev/null 2>&1; then
        echo "warning: arm-none-eabi-size unavailable, using llvm-size" >&2
        SIZE=llvm-size
    else
        echo "error: neither arm-none-eabi-size nor llvm-size is available" >&2
        exit 1
    fi
fi

"$SIZE" "$ELF"
read -r text data bss _ < <("$SIZE" "$ELF" | awk 'NR == 2 { print $1, $2, $3 }')
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
