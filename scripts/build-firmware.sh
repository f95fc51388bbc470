#!/usr/bin/env bash
# Builds the SKR 2 images, one per MCU the board has shipped with: STM32F407VG (`--features
# board`, the `cargo fw` alias) and STM32F429VG (`--features board-f429`, boards sold since late
# 2021). Writes target/firmware-f407.bin and target/firmware-f429.bin for the SD-card bootloader
# (copy the one for your chip to the card as firmware.bin; docs/board.md), keeps each ELF next to
# it, and prints each image's flash and static RAM use against the targets (flash <= 256 KiB,
# static RAM <= 64 KiB). Honours CARGO_TARGET_DIR. Needs arm-none-eabi-objcopy/size (Debian:
# binutils-arm-none-eabi, installed by scripts/setup.sh).
set -euo pipefail
cd "$(dirname "$0")/.."
target_dir="${CARGO_TARGET_DIR:-target}"
elf="$target_dir/thumbv7em-none-eabihf/fw/skr2"
for chip in f407 f429; do
  case "$chip" in
    f407) features=board ;;
    f429) features=board-f429 ;;
  esac
  cargo build -p firmware --bin skr2 --features "$features" --target thumbv7em-none-eabihf --profile fw
  cp "$elf" "$target_dir/skr2-$chip.elf"
  bin="$target_dir/firmware-$chip.bin"
  arm-none-eabi-objcopy -O binary "$elf" "$bin"
  arm-none-eabi-size -A "$elf" | awk -v chip="$chip" '
    $1==".vector_table"||$1==".text"||$1==".rodata"||$1==".data" {flash+=$2}
    $1==".data"||$1==".bss"||$1==".uninit" {ram+=$2}
    $1==".vector_table" {vt=$3}
    END {
      printf "firmware image %s: flash %.1f KiB (target <= 256 KiB), static RAM %.1f KiB (target <= 64 KiB), vector table at 0x%08x\n", chip, flash/1024, ram/1024, vt
      if (flash > 256*1024 || ram > 64*1024) { print "firmware image: OVER BUDGET"; exit 1 }
      if (vt != 134250496) { print "firmware image: vector table not at 0x08008000"; exit 1 }
    }'
  ls -l "$bin"
done
# The F407 image stays the default target/firmware.bin (as before).
cp "$target_dir/firmware-f407.bin" "$target_dir/firmware.bin"
echo "copy target/firmware-f407.bin or target/firmware-f429.bin (the chip printed on your board) to the SD card as firmware.bin (see docs/board.md)"
