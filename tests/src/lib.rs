//! Shared helpers for the workspace-level tests in `tests/tests/`.
#![deny(missing_docs)]

use std::path::PathBuf;

pub mod corpus;
pub mod gcode;
pub mod imports;
pub mod judge;
pub mod pty;

/// Root of the workspace (where `Cargo.toml`, `memory.x` and `tests/fixtures` live).
pub fn workspace_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("."))
}

/// A host-tools example script (`host-tools/examples/<name>`) compiled for the Ender-3 by
/// host-tools' own script runner and G-code writer (its markers: `;LAYER_CHANGE` per layer, or
/// per turn of a helix), as lines. Panics, naming the file, if it does not compile.
pub fn compile_example(name: &str) -> Vec<String> {
    use host_tools::design::profile::Profile;
    use host_tools::design::script::ScriptRunner;
    use host_tools::design::writer::{GcodeWriter, WriteOptions};
    let p = Profile::ender3();
    let path = workspace_root().join("host-tools/examples").join(name);
    let out = ScriptRunner::new(p.clone())
        .run_file(&path)
        .unwrap_or_else(|e| panic!("{name}: {e}"));
    let (g, _) = GcodeWriter::new(&p, WriteOptions::default())
        .to_string(&out.model)
        .unwrap_or_else(|e| panic!("{name}: {e}"));
    g.lines().map(str::to_string).collect()
}
