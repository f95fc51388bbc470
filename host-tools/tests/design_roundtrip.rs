//! Our G-code read back with the firmware's own parser (`firmware::gcode`): every line parses,
//! every move lands where our reader says, and the firmware's layer detector sees one layer
//! per helix turn (so a layer pause stops at a turn boundary).

use firmware::config::MachineConfig;
use firmware::gcode::parse_line;
use firmware::layer::{LayerDetector, MoveFacts};
use firmware::machine::MachineState;
use host_tools::gcode_read::{Event, FastReader, FirmwareReader, GcodeReader};
use host_tools::modulate::{globe, Bitmap, Globe};
use host_tools::parts::Helix;
use host_tools::profile::Profile;
use host_tools::writer::{GcodeWriter, WriteOptions};

fn moves(r: &mut dyn GcodeReader, g: &str) -> Vec<[f64; 4]> {
    let mut v = Vec::new();
    r.read(g.as_bytes(), &mut |e| {
        if let Event::Move { to, .. } = e {
            v.push(to);
        }
    })
    .unwrap_or_else(|e| panic!("{e}"));
    v
}

fn outputs() -> Vec<(String, String)> {
    let mut v = Vec::new();
    let helix = Helix {
        turns: 12.0,
        ..Helix::default()
    }
    .build()
    .expect("helix");
    let arcs = Helix {
        turns: 5.0,
        per_turn: 4,
        arcs: true,
        ..Helix::default()
    }
    .build()
    .expect("arcs");
    let (g, _) = globe(
        &Globe {
            turns: 40,
            per_turn: 80,
            ..Globe::default()
        },
        &Bitmap::world_map().expect("map"),
    )
    .expect("globe");
    for name in ["ender3", "skr2"] {
        let p = Profile::builtin(name).expect("profile");
        let w = GcodeWriter::new(&p, WriteOptions::default());
        for (what, m) in [("helix", &helix), ("arcs", &arcs), ("globe", &g)] {
            let (text, _) = w.to_string(m).expect("write");
            v.push((format!("{what}/{name}"), text));
        }
    }
    v
}

#[test]
fn every_line_parses_with_the_firmware() {
    for (name, g) in outputs() {
        for (i, line) in g.lines().enumerate() {
            if let Err(e) = parse_line(line.as_bytes()) {
                panic!("{name}: line {} `{line}`: {e:?}", i + 1);
            }
        }
    }
}

#[test]
fn firmware_reader_agrees_with_ours() {
    for (name, g) in outputs() {
        let a = moves(&mut FastReader::default(), &g);
        let b = moves(&mut FirmwareReader::default(), &g);
        assert_eq!(a.len(), b.len(), "{name}");
        for (p, q) in a.iter().zip(&b) {
            for k in 0..4 {
                // the firmware keeps f32: allow its rounding on a 235 mm bed / long E totals
                let tol = 1e-4 * p[k].abs().max(1.0);
                assert!((p[k] - q[k]).abs() <= tol, "{name}: {p:?} vs {q:?}");
            }
        }
    }
}

#[test]
fn firmware_layer_detector_sees_one_layer_per_turn() {
    let cfg = MachineConfig::ENDER3;
    let p = Profile::builtin("skr2").expect("skr2");
    let helix = Helix {
        turns: 12.0,
        ..Helix::default()
    }
    .build()
    .expect("helix");
    let (g, _) = GcodeWriter::new(&p, WriteOptions::default())
        .to_string(&helix)
        .expect("write");
    let mut m = MachineState::new(&cfg);
    let mut d = LayerDetector::new();
    let mut marks = 0;
    for line in g.lines() {
        let parsed = parse_line(line.as_bytes()).expect("parse");
        let before = m.position_steps(&cfg);
        if let Some(cmd) = &parsed.command {
            let _ = m.apply(cmd, &cfg);
        }
        let facts = MoveFacts::between(&before, &m.position_steps(&cfg), &cfg);
        if d.feed(&parsed, facts).is_some() {
            marks += 1;
        }
    }
    if d.finish().is_some() {
        marks += 1;
    }
    assert!(d.has_explicit_markers());
    assert_eq!(marks, 12, "one layer mark per helix turn");
}

#[test]
fn both_readers_agree_on_the_slicer_fixtures() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/fixtures/slicer");
    for name in ["prusaslicer.gcode", "cura.gcode", "slic3r.gcode"] {
        let Ok(g) = std::fs::read_to_string(dir.join(name)) else {
            continue; // fixtures belong to the firmware front end; absent in partial checkouts
        };
        let a = moves(&mut FastReader::default(), &g);
        let b = moves(&mut FirmwareReader::default(), &g);
        assert_eq!(a.len(), b.len(), "{name}");
        for (p, q) in a.iter().zip(&b) {
            for k in 0..4 {
                let tol = 1e-4 * p[k].abs().max(1.0);
                assert!((p[k] - q[k]).abs() <= tol, "{name}: {p:?} vs {q:?}");
            }
        }
    }
}
