#!/usr/bin/env bash
# Builds the SKR 2 images (crate `firmware/skr2`), one per MCU the board has shipped with:
# STM32F407VG (`--features f407`, the `cargo fw` alias) and STM32F429VG (`--features f429`,
# boards sold since late 2021). Writes target/firmware-f407.bin and target/firmware-f429.bin for the SD-card bootloader
# (copy the one for your chip to the card as firmware.bin; docs/board.md), keeps each ELF next to
# it, and prints each image's flash and static RAM use against the targets (flash <= 384 KiB,
# static RAM <= 64 KiB), and fails if a loadable ELF segment would touch the bootloader or the
# settings sectors. Honours CARGO_TARGET_DIR. Needs arm-none-eabi-objcopy/size and readelf
# (Debian: binutils-arm-none-eabi and binutils, installed by scripts/setup.sh).
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/fw-env.sh
target_dir="${CARGO_TARGET_DIR:-target}"
elf="$target_dir/thumbv7em-none-eabihf/fw/skr2"
for chip in f407 f429; do
  case "$chip" in
    f407) features=f407 ;;
    f429) features=f429 ;;
  esac
  cargo build -p skr2 --features "$features" --target thumbv7em-none-eabihf --profile fw
  cp "$elf" "$target_dir/skr2-$chip.elf"
  bin="$target_dir/firmware-$chip.bin"
  arm-none-eabi-objcopy -O binary "$elf" "$bin"
  arm-none-eabi-size -A "$elf" | awk -v chip="$chip" '
    $1==".vector_table"||$1==".text"||$1==".rodata"||$1==".data" {flash+=$2}
    $1==".data"||$1==".bss"||$1==".uninit" {ram+=$2}
    $1==".vector_table" {vt=$3}
    END {
      printf "firmware image %s: flash %.1f KiB (target <= 384 KiB), static RAM %.1f KiB (target <= 64 KiB), vector table at 0x%08x\n", chip, flash/1024, ram/1024, vt
      if (flash > 384*1024 || ram > 64*1024) { print "firmware image: OVER BUDGET"; exit 1 }
      if (vt != 134250496) { print "firmware image: vector table not at 0x08008000"; exit 1 }
    }'
  # No loadable segment may reach into the SD bootloader (0x08000000-0x08007FFF, sectors 0-1)
  # or the settings sectors (0x080C0000-0x080FFFFF): a tool that loads the ELF (OpenOCD,
  # pyOCD, STM32CubeProgrammer) erases every sector a PT_LOAD touches. Both its virtual and its
  # physical (load) address are checked, from the start to the end of its file image.
  readelf -lW "$elf" | awk -v chip="$chip" '
    function hex(s,   i, v) {
      s = tolower(s); sub(/^0x/, "", s); v = 0
      for (i = 1; i <= length(s); i++) v = v * 16 + index("0123456789abcdef", substr(s, i, 1)) - 1
      return v
    }
    $1=="LOAD" {
      n++
      va=hex($3); pa=hex($4); fs=hex($5)
      for (i = 0; i < 2; i++) {
        a = (i == 0) ? va : pa
        # (decimal: mawk has no hex constants) 0x08000000, 0x08100000, 0x08008000, 0x080C0000
        if (a >= 134217728 && a < 135266304 && fs > 0) {
          if (a < 134250496 || a + fs > 135004160) {
            printf "firmware image %s: PT_LOAD at 0x%08x (%s, 0x%x bytes) outside 0x08008000-0x080BFFFF\n", chip, a, (i == 0 ? "VirtAddr" : "PhysAddr"), fs
            bad = 1
          }
        }
      }
    }
    END {
      if (n == 0) { print "firmware image: no PT_LOAD segment found"; exit 1 }
      if (bad) exit 1
      printf "firmware image %s: %d loadable segments, all in flash within 0x08008000-0x080BFFFF or in RAM\n", chip, n
    }'
  ls -l "$bin"
done
# The F407 image stays the default target/firmware.bin (as before).
cp "$target_dir/firmware-f407.bin" "$target_dir/firmware.bin"
echo "copy target/firmware-f407.bin or target/firmware-f429.bin (the chip printed on your board) to the SD card as firmware.bin (see docs/board.md)"
