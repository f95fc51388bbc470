//! Real slicer output through the firmware front end: every line parses, the machine state
//! takes every command, and the layer detector finds exactly the slicer's layers, with each
//! boundary between the last extrusion of one layer and the first of the next.
//!
//! Fixtures: `tests/fixtures/slicer/*.gcode`, made by `scripts/make-fixtures.sh` (PrusaSlicer
//! 2.5, CuraEngine 4.13, Slic3r 1.3 slicing `part.scad`). Run with `--nocapture` to see the
//! unknown commands of each file.

use firmware::config::MachineConfig;
use firmware::gcode::{parse_line, Command};
use firmware::machine::{Action, Interpreter};
use firmware::motion::{LayerMark, LayerSource};
use std::collections::BTreeMap;
use std::path::PathBuf;

fn fixture(name: &str) -> String {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("fixtures/slicer")
        .join(name);
    std::fs::read_to_string(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

/// What one pass over a file found.
struct Report {
    marks: Vec<LayerMark>,
    /// For each extruding move: (layer index = marks before it, Z in steps).
    extrusions: Vec<(usize, i32)>,
    unknown: BTreeMap<String, usize>,
    moves: usize,
}

fn run(name: &str) -> Report {
    let text = fixture(name);
    let cfg = MachineConfig::ENDER3;
    let mut it = Interpreter::new(&cfg);
    let mut r = Report {
        marks: Vec::new(),
        extrusions: Vec::new(),
        unknown: BTreeMap::new(),
        moves: 0,
    };
    for (n, raw) in text.lines().enumerate() {
        let line =
            parse_line(raw.as_bytes()).unwrap_or_else(|e| panic!("{name}:{}: {raw:?}: {e}", n + 1));
        if let Some(Command::Unknown(t)) = &line.command {
            let code = t.split_whitespace().next().unwrap_or("").to_string();
            *r.unknown.entry(code).or_default() += 1;
        }
        let before = it.machine.position_steps(&cfg);
        let step = it
            .line(&line, &cfg)
            .unwrap_or_else(|e| panic!("{name}:{}: {raw:?}: {e}", n + 1));
        if let Some(m) = step.mark {
            r.marks.push(m);
        }
        let after = it.machine.position_steps(&cfg);
        if let Action::Move(_) | Action::Arc(_) = step.action {
            r.moves += 1;
            let extrudes = after[3] > before[3] && (after[0] != before[0] || after[1] != before[1]);
            if extrudes {
                r.extrusions.push((r.marks.len(), after[2]));
            }
        }
    }
    if let Some(m) = it.finish() {
        r.marks.push(m);
    }
    println!(
        "{name}: {} lines, {} moves, {} layers, unknown commands: {:?}",
        text.lines().count(),
        r.moves,
        r.marks.len(),
        r.unknown
    );
    r
}

/// Every extruding move of layer k is at one height, and heights rise with k: the boundaries
/// sit exactly between the layers' extrusions.
fn check_boundaries(name: &str, r: &Report) {
    let mut heights: BTreeMap<usize, i32> = BTreeMap::new();
    for &(layer, z) in &r.extrusions {
        assert!(layer > 0, "{name}: extrusion before the first layer mark");
        let h = *heights.entry(layer).or_insert(z);
        assert_eq!(h, z, "{name}: layer {layer} extrudes at two heights");
    }
    let hs: Vec<i32> = heights.values().copied().collect();
    assert!(hs.windows(2).all(|w| w[0] < w[1]), "{name}: {hs:?}");
    // Every layer has extrusions.
    assert_eq!(heights.len(), r.marks.len(), "{name}");
    // Marks are numbered 1, 2, 3, ... (the n-th layer printed, as the slicers' previews show).
    for (i, m) in r.marks.iter().enumerate() {
        assert_eq!(m.layer as usize, i + 1, "{name}");
    }
}

#[test]
fn prusaslicer_fixture() {
    let text = fixture("prusaslicer.gcode");
    let expected = text.lines().filter(|l| *l == ";LAYER_CHANGE").count();
    assert_eq!(expected, 30);
    let r = run("prusaslicer.gcode");
    assert_eq!(r.marks.len(), expected);
    assert!(r.marks.iter().all(|m| m.source == LayerSource::Comment));
    // Heights from ;Z:.
    let zs: Vec<Option<i32>> = text
        .lines()
        .filter_map(|l| l.strip_prefix(";Z:"))
        .map(|z| z.parse::<f64>().ok().map(|v| (v * 1000.0).round() as i32))
        .collect();
    assert_eq!(r.marks.iter().map(|m| m.z_um).collect::<Vec<_>>(), zs);
    check_boundaries("prusaslicer.gcode", &r);
}

#[test]
fn cura_fixture() {
    let text = fixture("cura.gcode");
    let expected = text.lines().filter(|l| l.starts_with(";LAYER:")).count();
    assert_eq!(expected, 30);
    let r = run("cura.gcode");
    assert_eq!(r.marks.len(), expected);
    check_boundaries("cura.gcode", &r);
    // Cura moved Z before ;LAYER:n, so the mark knows the new height: 0.3, 0.5, ...
    assert_eq!(r.marks[0].z_um, Some(300));
    assert_eq!(r.marks[1].z_um, Some(500));
}

#[test]
fn slic3r_fixture_without_markers() {
    let text = fixture("slic3r.gcode");
    // One `G1 Z<z> F…` per layer, plus the start G-code's lift.
    let expected = text
        .lines()
        .filter(|l| l.starts_with("G1 Z") && !l.contains("lift"))
        .count();
    assert_eq!(expected, 30);
    let r = run("slic3r.gcode");
    assert_eq!(r.marks.len(), expected);
    assert!(r.marks.iter().all(|m| m.source == LayerSource::ZRise));
    check_boundaries("slic3r.gcode", &r);
}
