//! What a FullControl user porting a notebook meets (issue 33): speeds in one unit at every
//! entry point, a NaN reported where the script made it, a travel into printed material
//! refused, a lift that retracts before it rises, and a bounding box of what is printed.
//! Checked on the written G-code with the tests' own reader (`tests/track`) and through the
//! `host-tools` binary. Cost: a few small scripts and three `compile` runs, well under 1 s.

mod track;

use host_tools::design::checks::{check, CheckOptions, IssueKind};
use host_tools::design::model::{StateChange, Step};
use host_tools::design::profile::{Profile, Retraction};
use host_tools::design::script::{ScriptError, ScriptOutput, ScriptRunner};
use host_tools::design::writer::{GcodeWriter, WriteOptions};
use std::path::Path;
use std::process::Command;

fn run(src: &str) -> Result<ScriptOutput, ScriptError> {
    ScriptRunner::new(Profile::builtin("ender3").expect("ender3")).run(
        "d.rhai",
        src,
        Path::new("."),
    )
}

#[test]
fn speeds_above_the_axis_limit_are_refused_with_the_unit() {
    // FullControl's mm/min at every entry point: refused at the script line, the conversion
    // named (before, set_travel_speed(9000) wrote `G0 F540000`).
    for (call, line) in [
        ("t.set_travel_speed(9000);", 2),
        ("t.set_speed(1200);", 2),
        ("t.set_velocity(3000);", 2),
        // A retraction speed against the extruder's limit (ender3: 60 mm/s, its profile's own
        // retraction; the firmware's E limit is 50); before, 2700
        // (FullControl's mm/min) wrote `G1 F162000 E-…`.
        ("t.set_retraction(#{ length: 1, speed: 2700 });", 2),
    ] {
        let src =
            format!("let t = turtle(100, 100, 0.2);\n{call}\nt.extrude_to(110, 100, 0.2);\nt");
        let e = run(&src).expect_err(call);
        assert_eq!(e.line, line, "{call}: {e}");
        assert!(
            e.msg.contains("mm/s") && e.msg.contains("mm/min"),
            "{call}: {e}"
        );
    }
    let e = run("let t = init(#{ travel_speed: 8000 });\nt.extrude_to(BED_X + 5, BED_Y, 0.2);\nt")
        .expect_err("init");
    assert!(e.msg.contains("mm/min"), "{e}");
    // A huge value is named readably (not as 309 digits).
    let e = run("let t = turtle(100, 100, 0.2);\nt.set_velocity(1e308);\nt").expect_err("1e308");
    assert!(e.msg.len() < 300 && e.msg.contains("1.000e308"), "{e}");
    // In range: written as mm/min F words (120 mm/s = F7200).
    let ok = run("let t = turtle(100, 100, 0.2);\nt.set_travel_speed(120);\n\
                  t.set_retraction(#{ length: 1, speed: 40 });\n\
                  t.extrude_to(110, 100, 0.2);\nt.travel_to(150, 150, 0.2);\nt.extrude_to(160, 150, 0.2);\nt")
    .expect("in range");
    let p = Profile::builtin("ender3").expect("ender3");
    let (g, _) = GcodeWriter::new(&p, WriteOptions::default())
        .to_string(&ok.model)
        .expect("write");
    assert!(g.lines().any(|l| l.starts_with("G0 F7200")), "{g}");
    // The retraction at 40 mm/s: E back by 1 mm at F2400, read with the tests' own tracker.
    let t = track::track(&g);
    assert!(
        t.moves
            .iter()
            .any(|m| m.de < -0.999 && m.de > -1.001 && m.f == 2400.0 && m.from == m.to),
        "{g}"
    );
    // A model's retraction (not from the turtle) is refused when written, the unit named.
    let mut m = ok.model.clone();
    m.steps.insert(
        0,
        Step::State(StateChange::Retraction(Retraction {
            length_mm: 1.0,
            speed_mm_s: 2700.0,
            min_travel_mm: 1.0,
        })),
    );
    let e = GcodeWriter::new(&p, WriteOptions::default())
        .to_string(&m)
        .expect_err("2700 mm/s retraction");
    assert!(
        e.to_string().contains("extruder") && e.to_string().contains("mm/min"),
        "{e}"
    );
    // Parts and model operations: refused when written, the step and unit named.
    let m = run("helix(#{ speed: 1800, turns: 1 })")
        .expect("a part takes any number")
        .model;
    let e = GcodeWriter::new(&p, WriteOptions::default())
        .to_string(&m)
        .expect_err("1800 mm/s");
    assert!(e.to_string().contains("mm/min"), "{e}");
}

#[test]
fn a_nan_is_reported_where_the_script_makes_it() {
    // Before, the error pointed at `extrude_to` on line 3.
    let e = run("let t = turtle(100, 100, 0.2);\nlet r = 5 - sqrt(-4.0);\nt.extrude_to(100 + r, 100, 0.2);\nt")
        .expect_err("sqrt(-4)");
    assert_eq!(e.line, 2, "{e}");
    assert!(e.msg.contains("sqrt"), "{e}");
    for (expr, name) in [
        ("ln(-1.0)", "ln"),
        ("acos(2.0)", "acos"),
        ("asin(-3)", "asin"),
        ("log(-2.0)", "log"),
    ] {
        let e = run(&format!("let x = {expr};\nturtle(0, 0, 0.2).model()")).expect_err(expr);
        assert!(e.line == 1 && e.msg.contains(name), "{expr}: {e}");
    }
    // Numbers are still numbers.
    run(
        "let a = sqrt(16.0) + sqrt(9) + ln(1.0) + acos(1.0);\nif a != 7.0 { throw \"sqrt\"; }\n\
         let t = turtle(100, 100, 0.2); t.extrude_to(101, 100, 0.2); t",
    )
    .expect("plain math");
}

/// A 15 mm ring wall (75 layers of 0.2 mm), then a travel from inside the ring to outside at
/// the first layer's height.
fn ring_then(travel: &str) -> String {
    format!(
        "let t = turtle(BED_X + 7.5, BED_Y, 0.2);\n\
         t.set_extrusion(#{{ width: 0.45, height: 0.2 }});\n\
         for l in 0..75 {{\n\
           let z = 0.2 * (l + 1);\n\
           t.mark_layer(0.2);\n\
           t.extrude_path(circle_xy(point(BED_X, BED_Y, z), 7.5, 0, 48));\n\
         }}\n\
         t.travel_straight_to(BED_X, BED_Y, 0.2);\n\
         t.extrude_to(BED_X + 1, BED_Y, 0.2);\n\
         t.{travel}(BED_X + 20, BED_Y, 0.2);\n\
         t.extrude_to(BED_X + 21, BED_Y, 0.2);\n\
         t"
    )
}

#[test]
fn a_travel_into_printed_material_is_an_error() {
    let p = Profile::builtin("ender3").expect("ender3");
    // Straight through the wall, 14.8 mm under its top: a collision (before: "passes over
    // printed material (stringing)", exit 0).
    let m = run(&ring_then("travel_straight_to")).expect("script").model;
    let rep = check(&m, &p, &CheckOptions::default());
    assert!(
        rep.count(IssueKind::TravelHitsPrint) >= 1,
        "{:?}",
        rep.issues
    );
    assert!(rep.errors() >= 1);
    // The same travel with travel_to lifts over the wall: no collision.
    let m = run(&ring_then("travel_to")).expect("script").model;
    let rep = check(&m, &p, &CheckOptions::default());
    assert_eq!(rep.count(IssueKind::TravelHitsPrint), 0, "{:?}", rep.issues);
    // `compile` refuses to write the colliding one, without --strict.
    let dir = std::env::temp_dir().join(format!("ht-guards-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("tmp");
    for (travel, ok) in [("travel_straight_to", false), ("travel_to", true)] {
        let design = dir.join(format!("{travel}.rhai"));
        std::fs::write(&design, ring_then(travel)).expect("design");
        let out_path = dir.join(format!("{travel}.gcode"));
        let out = Command::new(env!("CARGO_BIN_EXE_host-tools"))
            .arg("compile")
            .arg(&design)
            .arg("-o")
            .arg(&out_path)
            .output()
            .expect("compile");
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.success(), ok, "{travel}: {err}");
        assert_eq!(out_path.exists(), ok, "{travel}");
        if !ok {
            assert!(
                err.contains("travel-hits-print") && err.contains("nothing written"),
                "{err}"
            );
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Every travel of `g` that rises (a lift) comes after a retraction: E has gone back before Z
/// goes up (and is primed again only once the head is back down). Returns the lifts.
fn lifts_after_retraction(g: &str) -> usize {
    let t = track::track(g);
    // Every travel that rises (a lift) comes after a retraction: E has gone back before Z
    // goes up, and it is primed again only after the head is back down.
    let start = g.lines().position(|l| l == ";DESIGN_BEGIN").expect("tag") + 1;
    let mut retracted = false;
    let mut lifts = 0;
    for m in t.moves.iter().filter(|m| m.line > start) {
        let moves_xyz = (0..3).any(|k| (m.to[k] - m.from[k]).abs() > 1e-9);
        if !moves_xyz && m.de < 0.0 {
            retracted = true;
        } else if !moves_xyz && m.de > 0.0 {
            retracted = false;
        } else if m.rapid && m.to[2] > m.from[2] + 0.5 {
            lifts += 1;
            assert!(retracted, "line {}: lifts before it retracts", m.line);
        }
    }
    lifts
}

#[test]
fn a_lift_retracts_before_it_rises_and_bbox_leaves_travels_out() {
    let p = Profile::builtin("ender3").expect("ender3");
    let lattice = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/fc_speed_lattice.rhai"),
    )
    .expect("example");
    // The ring's lift over its 15 mm wall, and the lattice's 1 mm lifts between layers
    // (shorter than the retraction's 1.5 mm minimum travel: before, they rose first and
    // retracted on the way across).
    for src in [ring_then("travel_to"), lattice] {
        let out = run(&src).expect("script");
        let (g, _) = GcodeWriter::new(&p, WriteOptions::default())
            .to_string(&out.model)
            .expect("write");
        assert!(lifts_after_retraction(&g) >= 1, "{g}");
    }
    let out = run(&ring_then("travel_to")).expect("script");
    // The box of what is printed: the wall's top, not the lift 1 mm above it.
    let b = out.model.bbox();
    assert!((b.max.z - 15.0).abs() < 1e-9, "{b:?}");
    let e = run("let t = turtle(100, 100, 0.2); t.extrude_to(110, 100, 0.2); t.travel_to(120, 100, 0.2); \
                 t.extrude_to(121, 100, 0.2); let b = t.model().bbox(); if b.max[2] != 0.2 { throw b.max[2]; } t");
    assert!(e.is_ok(), "{:?}", e.err());
}
