#!/usr/bin/env bash
# Installs what a fresh machine lacks: the pinned toolchain with the thumbv7em target
# (rust-toolchain.toml), and the Debian packages the tests and the image build use.
set -euo pipefail
cd "$(dirname "$0")/.."
rustup show active-toolchain >/dev/null 2>&1 || rustup toolchain install
rustup target list --installed | grep -q thumbv7em-none-eabihf || rustup target add thumbv7em-none-eabihf
need=()
command -v qemu-system-arm >/dev/null || need+=(qemu-system-arm)
command -v arm-none-eabi-objcopy >/dev/null || need+=(binutils-arm-none-eabi)
# The emulated board (board-emu) builds the Unicorn engine's C with cmake, and its Rust
# bindings with bindgen, which needs libclang.
command -v cmake >/dev/null || need+=(cmake)
dpkg -s libclang-dev >/dev/null 2>&1 || need+=(libclang-dev)
# Headless browser for the 3D preview's screenshot test (host-tools/tests/preview_html.rs).
command -v chromium >/dev/null || need+=(chromium)
if [ ${#need[@]} -gt 0 ]; then
  echo "setup: installing ${need[*]}"
  if [ "$(id -u)" = 0 ]; then SUDO=""; else SUDO="sudo"; fi
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${need[@]}" >/dev/null
fi
# The real host programs (OctoPrint, printcore) for the host tests, into .hosts/ (ignored).
bash scripts/setup-hosts.sh
