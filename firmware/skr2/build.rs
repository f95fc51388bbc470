//! Linker scripts for the bare-metal board image only: host builds (tests, sim, host tools)
//! must link as ordinary programs.
fn main() {
    let target_os = std::env::var("CARGO_CFG_TARGET_OS").unwrap_or_default();
    // `f407` and `f429` both enable `board`.
    let board = std::env::var_os("CARGO_FEATURE_BOARD").is_some();
    if target_os == "none" && board {
        // `memory.x` lives at the workspace root; cortex-m-rt's link.x includes it.
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
        println!("cargo:rustc-link-search={}", root.display());
        // No loadable segment for the ELF and program headers: without --nmagic the linker
        // maps them into a LOAD segment at 0x08000000 (a page below the image), and OpenOCD,
        // pyOCD or STM32CubeProgrammer loading the ELF would erase sector 0, the SD bootloader.
        // cortex-m-rt's documentation recommends `--nmagic`; `scripts/build-firmware.sh`
        // checks every PT_LOAD segment.
        println!("cargo:rustc-link-arg-bins=--nmagic");
        println!("cargo:rustc-link-arg-bins=-Tlink.x");
        println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
    }
    println!("cargo:rerun-if-changed=../../memory.x");
    println!("cargo:rerun-if-changed=build.rs");
}
