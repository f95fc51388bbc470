//! Runs the shared scenario (`src/scenario.rs`) with the firmware library on the host and writes
//! the digest the emulated Cortex-M4 must reproduce to `$OUT_DIR/expected.rs`. Also puts this
//! crate's `memory.x` (QEMU's flash at 0x08000000) on the linker path.

#[allow(dead_code)]
#[path = "src/scenario.rs"]
mod scenario;

use std::{env, fs, path::PathBuf};

fn main() {
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    let digest = match scenario::run(&mut scenario::NoMeter) {
        Ok(d) => d,
        Err(e) => panic!("the scenario fails on the host: {e:?}"),
    };
    fs::write(
        out.join("expected.rs"),
        format!(
            "/// The host's result for the scenario (written by build.rs).\n\
             pub const EXPECTED: scenario::Digest = scenario::Digest {{ hash: {:#018x}, events: {}, blocks: {}, lines: {}, final_pos: {:?} }};\n",
            digest.hash, digest.events, digest.blocks, digest.lines, digest.final_pos
        ),
    )
    .expect("write expected.rs");
    let target_os = env::var("CARGO_CFG_TARGET_OS").unwrap_or_default();
    if target_os == "none" {
        fs::copy("memory.x", out.join("memory.x")).expect("copy memory.x");
        println!("cargo:rustc-link-search={}", out.display());
        println!("cargo:rustc-link-arg-bins=-Tlink.x");
    }
    println!("cargo:rerun-if-changed=memory.x");
    println!("cargo:rerun-if-changed=src/scenario.rs");
    println!("cargo:rerun-if-changed=build.rs");
    // The scenario runs the firmware library: rerun when it changes.
    println!("cargo:rerun-if-changed=../src");
}
