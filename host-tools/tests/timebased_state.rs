//! `host-tools timebased` keeps the design (issue 33): its state changes — fan, temperatures,
//! pauses, raw lines — come through in order, and everything it prints, what it prints
//! before its first `mark_layer` included. Checked independently of the code under test:
//! designs compiled with `host-tools compile`, resampled with `host-tools timebased`, both
//! files read with the tests' own line reader (`tests/track` and the word split below, not
//! the firmware's parser): the same sequence of state lines in the source and the output,
//! and the same net extrusion in the source's design (between its design tags) and in the
//! output's samples, and the same layers (numbers and heights) in `stats` of both. Before the fix the output had no M106/M601 at all and lost the floor
//! ring's filament. Cost: three compiles and three resamplings of small designs, ~1 s.

mod track;

use std::path::Path;
use std::process::Command;

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_host-tools"))
}

fn run(args: &[&str]) -> String {
    let out = bin().args(args).output().expect("run host-tools");
    assert!(
        out.status.success(),
        "host-tools {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// The lines that set machine state, as written (comments and spaces trimmed): everything
/// but motion, dwells, homing, position and mode settings, progress (`M73`) and comments.
fn state_lines(text: &str) -> Vec<String> {
    text.lines()
        .map(|l| l.split(';').next().unwrap_or("").trim())
        .filter(|l| !l.is_empty())
        .filter(|l| {
            let cmd = l.split_whitespace().next().unwrap_or("");
            ![
                "G0", "G1", "G2", "G3", "G4", "G28", "G29", "G80", "G90", "G91", "G92", "M82",
                "M83", "M73",
            ]
            .contains(&cmd)
        })
        .map(str::to_string)
        .collect()
}

/// Net filament (E) pushed between the lines `from` and `to` (exclusive), read with the
/// tests' tracker over the whole file.
fn net_e_between(text: &str, from: &str, to: &str) -> f64 {
    let lines: Vec<&str> = text.lines().collect();
    let a = lines.iter().position(|l| l.trim() == from).expect(from) + 1;
    let b = lines.iter().position(|l| l.trim() == to).expect(to) + 1;
    track::track(text)
        .moves
        .iter()
        .filter(|m| m.line > a && m.line < b)
        .map(|m| m.de)
        .sum()
}

fn check(design: &Path, printer: &str, expect_state: &[&str]) {
    let dir = std::env::temp_dir().join(format!(
        "ht-tbstate-{}-{}",
        std::process::id(),
        design.file_stem().and_then(|s| s.to_str()).unwrap_or("d")
    ));
    std::fs::create_dir_all(&dir).expect("tmp");
    let (src, tb) = (dir.join("src.gcode"), dir.join("tb.gcode"));
    let s = |p: &Path| p.to_str().expect("utf-8 path").to_string();
    run(&[
        "compile",
        &s(design),
        "-o",
        &s(&src),
        "--printer",
        printer,
        "--no-check",
    ]);
    run(&["timebased", &s(&src), "-o", &s(&tb), "--printer", printer]);
    let (source, output) = (
        std::fs::read_to_string(&src).expect("source"),
        std::fs::read_to_string(&tb).expect("output"),
    );
    let (a, b) = (state_lines(&source), state_lines(&output));
    assert_eq!(
        a,
        b,
        "{}: state lines of the source and the time-based file",
        design.display()
    );
    for want in expect_state {
        assert!(
            a.iter().any(|l| l == want),
            "{}: {want} in {a:?}",
            design.display()
        );
    }
    let e_src = net_e_between(&source, ";DESIGN_BEGIN", ";DESIGN_END");
    let e_out = net_e_between(&output, ";TIMEBASED_BEGIN", ";TIMEBASED_END");
    assert!(e_src > 1.0, "{}: {e_src}", design.display());
    assert!(
        (e_src - e_out).abs() < 0.01 + 1e-5 * e_src,
        "{}: {e_src} mm of filament in the design, {e_out} mm in the time-based file",
        design.display()
    );
    // One notion of a layer: the same numbers and heights in `stats` of both files.
    let layers = |f: &Path| -> Vec<(u64, f64)> {
        let out = bin()
            .args(["stats", &s(f), "--json", "--printer", printer])
            .output()
            .expect("stats");
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
        v["layer_times"]
            .as_array()
            .expect("layer_times")
            .iter()
            .map(|l| {
                (
                    l["layer"].as_u64().unwrap_or(0),
                    l["z_mm"].as_f64().unwrap_or(-1.0),
                )
            })
            .collect()
    };
    // A time-based layer's first extruding piece may start in the rise onto it (a sample
    // chord out of the layer change): at most a layer height (0.2 mm here) lower, never
    // higher — never a travel's lift.
    let (la, lb) = (layers(&src), layers(&tb));
    assert_eq!(la.len(), lb.len(), "{}: {la:?} vs {lb:?}", design.display());
    for (a, b) in la.iter().zip(&lb) {
        assert!(
            a.0 == b.0 && b.1 <= a.1 + 1e-3 && b.1 >= a.1 - 0.2 - 1e-3,
            "{}: {la:?} vs {lb:?}",
            design.display()
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// A lamp shade in FullControl's manner: a floor ring printed before the first `mark_layer`,
/// then rings with the fan raised three times, a pause before a layer, a raw line and a
/// temperature change.
const LAMP: &str = r#"
let t = init(#{ nozzle_temp: 210, bed_temp: 55, fan_percent: 0, print_speed: 30,
               extrusion_width: 0.45, extrusion_height: 0.2,
               start: point(BED_X + 15, BED_Y, 0.2) });
// The floor: two rings at the first layer's height, before any layer mark.
t.extrude_path(circle_xy(point(BED_X, BED_Y, 0.2), 15, 0, 64));
t.travel_to(point(BED_X + 14.5, BED_Y, 0.2));
t.extrude_path(circle_xy(point(BED_X, BED_Y, 0.2), 14.5, 0, 64));
for l in 1..16 {
    let z = 0.2 * (l + 1);
    if l == 9 { t.pause(); }
    t.mark_layer(0.2);
    if l == 2 { t.fan(30); }
    if l == 5 { t.fan(60); t.gcode("M117 halfway"); }
    if l == 12 { t.fan(100); t.hotend(205); }
    t.travel_to(point(BED_X + 15, BED_Y, z));
    t.extrude_path(circle_xy(point(BED_X, BED_Y, z), 15, 0, 64));
}
t
"#;

#[test]
fn lamp_keeps_fan_pause_raw_lines_and_floor() {
    let dir = std::env::temp_dir().join(format!("ht-tbstate-lamp-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("tmp");
    let design = dir.join("lamp.rhai");
    std::fs::write(&design, LAMP).expect("design");
    for printer in ["ender3", "mk3s"] {
        check(
            &design,
            printer,
            &[
                "M106 S77",
                "M106 S153",
                "M106 S255",
                "M601",
                "M117 halfway",
                "M104 S205",
            ],
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn examples_keep_their_state_and_prime_line() {
    let ex = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples");
    // The cup: the profile's fan comes on at the second layer (the issue's "fan off all
    // print"); the speed lattice: its own prime line before the first layer, fan changes.
    check(&ex.join("cup.rhai"), "ender3", &["M106 S255"]);
    check(
        &ex.join("fc_speed_lattice.rhai"),
        "mk3s",
        &["M106 S128", "M106 S255"],
    );
}
