//! Our G-code read back with the firmware's own parser (`firmware::gcode`, which the host
//! tools' reader is built on): every line parses, every printing move lands on the model's
//! string end points, and the firmware's layer detector sees one layer per helix turn (so a
//! layer pause stops at a turn boundary). The slicer fixtures read back with the totals the
//! slicers themselves wrote into the files.

use firmware::config::MachineConfig;
use firmware::gcode::parse_line;
use firmware::layer::{LayerDetector, MoveFacts};
use firmware::machine::MachineState;
use host_tools::design::modulate::{globe, Bitmap, Globe};
use host_tools::design::parts::Helix;
use host_tools::design::profile::Profile;
use host_tools::design::writer::{GcodeWriter, WriteOptions};
use host_tools::gcode::read::{default_reader, Event, GcodeReader, LayerSource};

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
    for name in ["reference", "skr2"] {
        let p = match name {
            "skr2" => Profile::builtin(name).expect("profile"),
            _ => Profile::ender3(),
        };
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
fn printing_moves_land_on_the_model_points() {
    // Straight strings (no arcs, no thinning): every printing move read back ends on the next
    // string's end point, within the writer's 3 decimals and the firmware's f32.
    let helix = Helix {
        turns: 12.0,
        ..Helix::default()
    }
    .build()
    .expect("helix");
    let want: Vec<_> = helix.strings().map(|s| s.end).collect();
    for name in ["reference", "skr2"] {
        let p = match name {
            "skr2" => Profile::builtin(name).expect("profile"),
            _ => Profile::ender3(),
        };
        let (g, _) = GcodeWriter::new(&p, WriteOptions::default())
            .to_string(&helix)
            .expect("write");
        let mut got = Vec::new();
        let mut layers = 0;
        default_reader()
            .read(g.as_bytes(), &mut |e| match e {
                Event::Move { from, to, .. } => {
                    let xy = to[0] != from[0] || to[1] != from[1];
                    if xy && to[3] > from[3] {
                        got.push(to);
                    }
                }
                Event::Layer { source, .. } => {
                    assert_eq!(source, LayerSource::Comment);
                    layers += 1;
                }
                _ => {}
            })
            .unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(got.len(), want.len(), "{name}");
        for (q, w) in got.iter().zip(&want) {
            for k in 0..3 {
                let tol = 5e-4 + 2e-7 * w[k].abs();
                assert!((q[k] - w[k]).abs() <= tol, "{name}: {q:?} vs {w}");
            }
        }
        assert_eq!(layers, 12, "{name}: one layer per turn");
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

/// The filament a slicer reports in its footer, mm.
fn slicer_filament_mm(g: &str) -> Option<f64> {
    g.lines().find_map(|l| {
        let rest = l
            .strip_prefix("; filament used [mm] = ")
            .or_else(|| l.strip_prefix("; filament used = "))?;
        rest.trim_end_matches(|c: char| !c.is_ascii_digit())
            .split("mm")
            .next()?
            .parse()
            .ok()
    })
}

#[test]
fn slicer_fixtures_read_back_with_the_slicers_own_totals() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/fixtures/slicer");
    // (file, layers the slicer wrote, filament it reported in mm or none, net E = Σ of every
    // E change outside G92, worked out once with a ten-line Python script over the file)
    for (name, want_layers, want_e, net_e) in [
        ("prusaslicer.gcode", 30, Some(481.91), Some(479.90584)),
        ("cura.gcode", 30, None, None),
        ("slic3r.gcode", 0, Some(193.7), Some(191.66225)),
    ] {
        let Ok(g) = std::fs::read_to_string(dir.join(name)) else {
            continue; // fixtures belong to the firmware front end; absent in partial checkouts
        };
        assert_eq!(slicer_filament_mm(&g), want_e, "{name}: footer");
        let mut comment_layers = 0;
        let mut z_layers = 0;
        let mut e_printed = 0.0;
        let mut last = [0.0; 4];
        let counts = default_reader()
            .read(g.as_bytes(), &mut |e| match e {
                Event::Move { from, to, .. } => {
                    e_printed += to[3] - from[3];
                    last = to;
                }
                Event::Layer { source, .. } => match source {
                    LayerSource::Comment => comment_layers += 1,
                    LayerSource::ZRise => z_layers += 1,
                    s => panic!("{name}: unexpected layer source {s:?}"),
                },
                _ => {}
            })
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(
            counts.lines as usize,
            g.lines().filter(|l| !l.is_empty()).count()
        );
        assert_eq!(comment_layers, want_layers, "{name}");
        if want_layers == 0 {
            // Slic3r writes no markers: one Z-rise layer per 0.2 mm of the 6 mm part.
            assert_eq!(z_layers, 30, "{name}");
        }
        // Net filament (retractions cancel primes) as worked out independently ...
        if let Some(net) = net_e {
            assert!(
                (e_printed - net).abs() < 0.01,
                "{name}: {e_printed} vs {net}"
            );
        }
        // ... and within 1.5 % of what the slicer reports (slicers count slightly differently).
        if let Some(want) = want_e {
            assert!(
                (e_printed - want).abs() < 0.015 * want,
                "{name}: {e_printed} vs {want}"
            );
        }
        assert!(last.iter().all(|v| v.is_finite()));
    }
}
