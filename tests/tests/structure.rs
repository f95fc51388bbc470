//! The one house (issue 28): every crate's modules form a strict hierarchy. No file imports a
//! file that imports it back (directly or around a loop), and no top-level module of a crate
//! imports one that imports it back — so each floor of a crate builds on the floors below it
//! only. Read from the source text by `tests::imports` (what counts is written there).

use std::path::Path;
use tests::imports::{cycles, module_edges, read_crate};

/// Every crate's source folder, from the workspace root.
const CRATES: &[&str] = &[
    "firmware/src",
    "firmware/skr2/src",
    "firmware/qemu/src",
    "sim/src",
    "host-tools/src",
    "board-emu/src",
    "layerref/src",
    "tests/src",
];

/// Cycles known when this check was written, each being removed by its own change; the check
/// fails on any other, and on one of these once it is gone (so the list only shrinks).
const KNOWN: &[&str] = &[];

#[test]
fn no_import_cycles_in_any_crate() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let mut found = Vec::new();
    for c in CRATES {
        let g = read_crate(&root.join(c)).expect("the crate's sources read");
        assert!(!g.files.is_empty(), "{c}: no sources found");
        for comp in cycles(&g.edges) {
            let names: Vec<String> = comp.iter().map(|f| f.display().to_string()).collect();
            let ties: Vec<String> = g
                .edges
                .iter()
                .filter(|(a, b)| comp.contains(a) && comp.contains(b))
                .map(|(a, b)| format!("{} -> {}", a.display(), b.display()))
                .collect();
            found.push((format!("{c}: files {}", names.join(", ")), ties.join("; ")));
        }
        let me = module_edges(&g);
        for comp in cycles(&me) {
            let ties: Vec<String> = me
                .iter()
                .filter(|(a, b)| comp.contains(a) && comp.contains(b))
                .map(|(a, b)| format!("{a} -> {b}"))
                .collect();
            found.push((format!("{c}: modules {}", comp.join(", ")), ties.join("; ")));
        }
    }
    let new: Vec<String> = found
        .iter()
        .filter(|(k, _)| !KNOWN.contains(&k.as_str()))
        .map(|(k, t)| format!("{k} ({t})"))
        .collect();
    assert!(new.is_empty(), "import cycles:\n{}", new.join("\n"));
    let gone: Vec<&&str> = KNOWN
        .iter()
        .filter(|k| !found.iter().any(|(f, _)| f == **k))
        .collect();
    assert!(
        gone.is_empty(),
        "cycles gone: take them off KNOWN in tests/tests/structure.rs: {gone:?}"
    );
}
