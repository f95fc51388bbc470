//! SKR 2 board image (being written; built only with `--features board` for thumbv7em).
#![cfg_attr(target_os = "none", no_std, no_main)]
#[cfg(not(target_os = "none"))]
fn main() {}
