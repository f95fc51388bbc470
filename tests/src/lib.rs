//! Shared helpers for the workspace-level tests in `tests/tests/`.
#![deny(missing_docs)]

use std::path::PathBuf;

pub mod gcode;
pub mod judge;
pub mod pty;

/// Root of the workspace (where `Cargo.toml`, `memory.x` and `tests/fixtures` live).
pub fn workspace_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("."))
}
