#!/usr/bin/env bash
# The emulated SKR 2 (docs/board-emu.md): builds the F407 image as scripts/build-firmware.sh
# does (or the F429 one with --f429), then boots it on the emulated board and streams the job
# over USART1. Every other argument goes to board-emu; the usual ones:
#   bash scripts/board-emu.sh --job FILE [--pause-at-layer N] [--fault NAME] --json OUT
# Faults: motion-stall, executor-stall, hard-fault, unexpected-irq (board-emu --help).
# Honours CARGO_TARGET_DIR. Needs arm-none-eabi-objcopy (scripts/setup.sh).
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/fw-env.sh
target_dir="${CARGO_TARGET_DIR:-target}"
features=f407
chip=f407
args=()
for a in "$@"; do
  if [ "$a" = "--f429" ]; then features=f429; chip=f429; args+=("--f429"); else args+=("$a"); fi
done
cargo build --quiet -p skr2 --features "$features" --target thumbv7em-none-eabihf --profile fw
elf="$target_dir/thumbv7em-none-eabihf/fw/skr2"
mkdir -p "$target_dir/board-emu"
cp "$elf" "$target_dir/board-emu/skr2-$chip.elf"
arm-none-eabi-objcopy -O binary "$elf" "$target_dir/board-emu/firmware-$chip.bin"
cargo build --quiet -p board-emu
exec "$target_dir/debug/board-emu" --image "$target_dir/board-emu/firmware-$chip.bin" \
  --elf "$target_dir/board-emu/skr2-$chip.elf" "${args[@]}"
