#!/usr/bin/env bash
# Builds the SKR 2 image, writes target/firmware.bin for the SD-card bootloader, and prints the
# flash and static RAM use.
set -euo pipefail
cd "$(dirname "$0")/.."
if ! grep -q 'embassy' firmware/Cargo.toml; then
  echo "firmware image: board binary not built yet (see README)"; exit 0
fi
cargo fw
elf=target/thumbv7em-none-eabihf/fw/skr2
arm-none-eabi-objcopy -O binary "$elf" target/firmware.bin
arm-none-eabi-size -A "$elf" | awk '
  $1==".vector_table"||$1==".text"||$1==".rodata"||$1==".data" {flash+=$2}
  $1==".data"||$1==".bss"||$1==".uninit" {ram+=$2}
  END {printf "firmware.bin: flash %.1f KiB of 256 KiB target, static RAM %.1f KiB of 64 KiB target\n", flash/1024, ram/1024}'
ls -l target/firmware.bin
