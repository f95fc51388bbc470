//! Linker scripts for the bare-metal board image only: host builds (tests, sim, host tools)
//! must link as ordinary programs.
fn main() {
    let target_os = std::env::var("CARGO_CFG_TARGET_OS").unwrap_or_default();
    // `board` (F407) and `board-f429` both enable `board-common`.
    let board = std::env::var_os("CARGO_FEATURE_BOARD_COMMON").is_some();
    if target_os == "none" && board {
        // `memory.x` lives at the workspace root; cortex-m-rt's link.x includes it.
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
        println!("cargo:rustc-link-search={}", root.display());
        println!("cargo:rustc-link-arg-bins=-Tlink.x");
        println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
    }
    println!("cargo:rerun-if-changed=../memory.x");
    println!("cargo:rerun-if-changed=build.rs");
}
