//! The state a design sets is final, the profile's a default (issue 23): fan, temperatures,
//! travel speed, primer; raw G-code is followed by the writer. Every output is read back by
//! the tests' own tracker (`tests/track`), not by the code under test. Cost: ~0.1 s.

mod track;

use glam::DVec3;
use host_tools::design::model::Model;
use host_tools::design::profile::{Primer, Profile};
use host_tools::design::script::ScriptRunner;
use host_tools::design::turtle::Turtle;
use host_tools::design::writer::{GcodeWriter, WriteOptions};
use std::path::Path;

fn write(p: &Profile, m: &Model) -> String {
    GcodeWriter::new(p, WriteOptions::default())
        .to_string(m)
        .map(|(s, _)| s)
        .unwrap_or_else(|e| panic!("{}: {e}", p.name))
}

/// Three layers of a 20 mm square at the bed centre; `setup` runs before the first move.
fn squares(setup: impl FnOnce(&mut Turtle)) -> Model {
    let mut t = Turtle::at(DVec3::new(100.0, 100.0, 0.2), 0.08, 20.0);
    setup(&mut t);
    for k in 0..3 {
        let z = 0.2 * (k + 1) as f64;
        t.mark_layer(0.2);
        for (x, y) in [
            (120.0, 100.0),
            (120.0, 120.0),
            (100.0, 120.0),
            (100.0, 100.0),
        ] {
            t.extrude_to(DVec3::new(x, y, z)).expect("move");
        }
        if k < 2 {
            t.travel_straight_to(DVec3::new(100.0, 100.0, z + 0.2))
                .expect("step");
        }
    }
    t.into_model()
}

fn profiles() -> Vec<Profile> {
    ["ender3", "mk3s"]
        .iter()
        .map(|n| Profile::builtin(n).expect("profile"))
        .collect()
}

/// `t.fan(0)` / `t.fan(30)` before the first move: every extrusion of every layer runs at
/// that fan, on profiles whose own fan comes on at layer 1 (ender3, mk3s).
#[test]
fn the_designs_fan_is_final() {
    for p in profiles() {
        assert_eq!(p.fan_off_layers, 1, "{}", p.name);
        for (percent, duty) in [(0.0, 0.0), (30.0, 77.0 / 255.0)] {
            let g = write(&p, &squares(|t| t.fan(percent).expect("fan")));
            let tr = track::track(&g);
            let ext: Vec<_> = tr
                .moves
                .iter()
                .filter(|m| m.extrudes() && m.to[2] >= 0.19)
                .collect();
            assert!(ext.len() >= 12, "{}: {}", p.name, ext.len());
            for m in ext.iter().filter(|m| m.to[0] >= 100.0 && m.to[1] >= 100.0) {
                assert!(
                    (m.fan - duty).abs() < 1e-9,
                    "{} fan({percent}): line {} runs at fan {}",
                    p.name,
                    m.line,
                    m.fan
                );
            }
            assert!(!g.contains("M106 S255"), "{}: {g}", p.name);
        }
        // Without a fan of the design's own the profile's default holds: on from layer 1.
        let g = write(&p, &squares(|_| {}));
        let tr = track::track(&g);
        let top = tr
            .moves
            .iter()
            .filter(|m| m.extrudes() && (m.to[2] - 0.6).abs() < 1e-6)
            .collect::<Vec<_>>();
        assert!(
            !top.is_empty() && top.iter().all(|m| m.fan == 1.0),
            "{}",
            p.name
        );
    }
}

fn script(p: &Profile, src: &str) -> Model {
    ScriptRunner::new(p.clone())
        .run("t.rhai", src, Path::new("."))
        .unwrap_or_else(|e| panic!("{e}"))
        .model
}

const LAYERS: &str = "
for k in 0..3 {
    let z = 0.2 * (k + 1);
    t.mark_layer(0.2);
    t.polyline([point(100, 100, z), point(120, 100, z), point(120, 120, z), point(100, 120, z), point(100, 100, z)]);
}
t";

/// The named `init`: its temperatures are the start code's, no other hot-end target is
/// written before the end code; what it leaves out is the profile's.
#[test]
fn named_init_sets_temperatures_and_leaves_the_rest_to_the_profile() {
    let p = Profile::builtin("ender3").expect("ender3");
    let m = script(
        &p,
        &format!(
            "let t = init(#{{ nozzle_temp: 240, bed_temp: 0, extrusion_width: 0.45 }});{LAYERS}"
        ),
    );
    let g = write(&p, &m);
    let tr = track::track(&g);
    let hot: Vec<f64> = tr.hotend_lines.iter().map(|(_, c)| *c).collect();
    // Heat-up (M104, M109) at 240, the end code's switch-off at 0.
    assert_eq!(hot, [240.0, 240.0, 0.0], "{g}");
    assert!(g.contains("M190 S0") && g.contains("M140 S0"));
    assert!(tr
        .moves
        .iter()
        .filter(|m| m.extrudes())
        .all(|m| m.hotend == 240.0));
    // The old positional form still works.
    let m = script(
        &p,
        &format!("let t = init(1.75, 210, 60, 0.08, 100, 100, 0.2);{LAYERS}"),
    );
    assert!(write(&p, &m).contains("M109 S210"));
}

/// `set_travel_speed` and `init(#{ travel_speed })`: every travel of the design runs at it.
#[test]
fn the_designs_travel_speed_is_final() {
    let p = Profile::builtin("mk3s").expect("mk3s");
    for src in [
        "let t = turtle(100, 100, 0.2); t.set_cross_section(0.08); t.set_travel_speed(50);",
        "let t = init(#{ travel_speed: 50 });",
    ] {
        let g = write(&p, &script(&p, &format!("{src}{LAYERS}")));
        let tr = track::track(&g);
        let first = tr
            .moves
            .iter()
            .position(|m| m.extrudes() && m.to[0] >= 100.0)
            .expect("prints");
        let travels: Vec<_> = tr.moves[first..]
            .iter()
            .filter(|m| m.rapid && m.de == 0.0)
            .collect();
        assert!(!travels.is_empty(), "{g}");
        for m in travels {
            assert_eq!(m.f, 3000.0, "line {}", m.line);
        }
    }
}

/// `set_primer("none")` leaves the profile's purge line out of its start code (and only
/// that); the default keeps it.
#[test]
fn the_design_chooses_the_primer() {
    for name in ["ender3", "mk3s", "mk4", "i3mega", "cr10"] {
        let p = Profile::builtin(name).expect("profile");
        let with = write(&p, &squares(|_| {}));
        let without = write(
            &p,
            &squares(|t| t.set_primer(Primer::None).expect("primer")),
        );
        let before_design = |g: &str| {
            let tr = track::track(g);
            let first = tr
                .moves
                .iter()
                .position(|m| {
                    m.extrudes()
                        && (100.0..=120.0).contains(&m.to[0])
                        && (100.0..=120.0).contains(&m.to[1])
                })
                .expect("design prints");
            tr.moves[..first].iter().filter(|m| m.extrudes()).count()
        };
        assert!(before_design(&with) > 0, "{name}: the purge line extrudes");
        assert_eq!(before_design(&without), 0, "{name}: no purge:\n{without}");
        assert!(without.contains("G28"), "{name}: still homes");
        assert!(without.len() < with.len());
    }
    // Chosen after the first move: an error.
    let mut t = Turtle::at(DVec3::new(100.0, 100.0, 0.2), 0.08, 20.0);
    t.extrude_to(DVec3::new(110.0, 100.0, 0.2)).expect("line");
    assert!(t.set_primer(Primer::None).is_err());
}

/// Raw lines that move the head or E: the writer continues from where they leave them —
/// a lift written as raw lines is undone by a travel back down before the next string, a
/// raw `G92 E0` in absolute E does not make the next string push the whole total again.
#[test]
fn the_writer_continues_after_raw_moves_and_e() {
    for name in ["ender3", "mk3s"] {
        let p = Profile::builtin(name).expect("profile");
        let m = squares(|t| {
            t.extrude_to(DVec3::new(110.0, 100.0, 0.2)).expect("line");
            t.gcode("G91\nG1 Z5 F600\nG90\nG92 E0").expect("raw");
        });
        let g = write(&p, &m);
        let tr = track::track(&g);
        for mv in tr
            .moves
            .iter()
            .filter(|m| m.extrudes() && m.to[0] >= 100.0 && m.to[1] >= 100.0)
        {
            let z = mv.to[2];
            assert!(
                [0.2, 0.4, 0.6].iter().any(|want| (z - want).abs() < 1e-6),
                "{name}: line {} prints at z {z}",
                mv.line
            );
            assert!(mv.de < 2.0, "{name}: line {} pushes {} mm", mv.line, mv.de);
        }
        // What the design extrudes: its strings' volume over the filament's area.
        let want = m.volume_mm3() / (std::f64::consts::PI * 0.875 * 0.875);
        let design: f64 = tr
            .moves
            .iter()
            .filter(|m| m.extrudes() && m.to[0] >= 100.0 && m.to[1] >= 100.0 && m.to[2] < 1.0)
            .map(|m| m.de)
            .sum();
        assert!((design - want).abs() < 0.01, "{name}: {design} vs {want}");
    }
}

/// Raw lines the printer's parser rejects, or that would break the writer's frame, are
/// refused where the script gives them.
#[test]
fn raw_lines_are_parsed_when_given() {
    let p = Profile::ender3();
    for (raw, want) in [
        ("G1 Xnan", "gcode line 1"),
        ("M104 S0\nM83", "absolute/relative E"),
        ("G91\nG1 Z2", "G90"),
        ("G92 X0", "coordinates"),
    ] {
        let e = ScriptRunner::new(p.clone())
            .run(
                "t.rhai",
                &format!("let t = turtle(100, 100, 0.2);\nt.gcode({raw:?});\nt"),
                Path::new("."),
            )
            .expect_err(raw);
        assert!(e.line == 2 && e.msg.contains(want), "{raw}: {e}");
    }
}
