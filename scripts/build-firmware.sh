#!/usr/bin/env bash
# Builds the SKR 2 image (`cargo fw`), writes firmware.bin for the SD-card bootloader next to the
# ELF, and prints the flash and static RAM use against the targets (flash <= 256 KiB, static
# RAM <= 64 KiB). Honours CARGO_TARGET_DIR. Needs arm-none-eabi-objcopy/size
# (Debian: binutils-arm-none-eabi, installed by scripts/setup.sh).
set -euo pipefail
cd "$(dirname "$0")/.."
target_dir="${CARGO_TARGET_DIR:-target}"
cargo fw
elf="$target_dir/thumbv7em-none-eabihf/fw/skr2"
bin="$target_dir/firmware.bin"
arm-none-eabi-objcopy -O binary "$elf" "$bin"
arm-none-eabi-size -A "$elf" | awk '
  $1==".vector_table"||$1==".text"||$1==".rodata"||$1==".data" {flash+=$2}
  $1==".data"||$1==".bss"||$1==".uninit" {ram+=$2}
  END {
    printf "firmware image: flash %.1f KiB (target <= 256 KiB), static RAM %.1f KiB (target <= 64 KiB)\n", flash/1024, ram/1024
    if (flash > 256*1024 || ram > 64*1024) { print "firmware image: OVER BUDGET"; exit 1 }
  }'
ls -l "$bin"
echo "copy $bin to the SD card as firmware.bin (see docs/board.md)"
