#!/usr/bin/env bash
# The emulated-core test: builds firmware/qemu (the portable firmware core with a shared
# scenario; build.rs computes the host's digest), runs it on qemu-system-arm (netduinoplus2,
# STM32F405 Cortex-M4F) with -icount shift=0, and fails unless the emulated digest matches the
# host's. Prints instructions per planned segment and per step event.
# Needs qemu-system-arm (Debian: qemu-system-arm; scripts/setup.sh installs it).
set -euo pipefail
cd "$(dirname "$0")/.."
if ! command -v qemu-system-arm >/dev/null; then
  echo "qemu-test: qemu-system-arm not installed (apt-get install qemu-system-arm)" >&2
  exit 1
fi
# The host's view of the same scenario first (fails fast if the scenario itself breaks).
cargo run --quiet --manifest-path firmware/qemu/Cargo.toml
# Then the emulated Cortex-M4: the `qemu-test` alias (.cargo/config.toml) builds for
# thumbv7em-none-eabihf and runs the ELF with qemu-system-arm as the cargo runner; the binary
# exits through semihosting with 0 only when its digest matches the host's.
exec cargo qemu-test
