# Sourced by the scripts that build the board image (build-firmware.sh, board-emu.sh, test.sh,
# .ci/run): panic locations of dependencies carry their source path; without the registry
# prefix each is ≈ 58 bytes shorter (≈ 1.9 KiB of flash in all) and the image does not depend on
# where this machine keeps cargo's registry. The prefix is found here, not written into
# .cargo/config.toml (which would name one machine's path). Cargo reads the flags from this
# variable for the thumbv7em target only (host builds are unaffected); every build of the image
# must see the same flags, or cargo rebuilds it.
cargo_home="${CARGO_HOME:-$HOME/.cargo}"
flags=""
for reg in "$cargo_home"/registry/src/*/; do
  [ -d "$reg" ] && flags="$flags --remap-path-prefix=${reg%/}=crates"
done
export CARGO_TARGET_THUMBV7EM_NONE_EABIHF_RUSTFLAGS="${flags# }"
unset cargo_home flags reg
