//! Print-time cost of segmentation and of stopping at layer marks, on the slicer fixtures
//! (heater waits removed). A report, not a check of speed: run with
//! `cargo test -p firmware --release --test segmentation_cost -- --ignored --nocapture`.
mod support;

use firmware::config::MachineConfig;
use firmware::printer::{Policy, Printer};
use support::*;

fn print_time_s(path: &str, seg_mm: f32, policy: Policy) -> Option<(f64, usize)> {
    let text = std::fs::read_to_string(path).ok()?;
    let lines: Vec<&str> = text
        .lines()
        .filter(|l| !l.trim().is_empty() && !l.starts_with("M109") && !l.starts_with("M190"))
        .collect();
    let mut cfg = MachineConfig::ENDER3;
    cfg.pause.segment_len_mm = seg_mm;
    let mut p = Printer::with_policy(cfg, policy);
    let r = run_gcode(&mut p, &lines, &[], 4_000_000_000);
    let t = r.trace.last().map_or(0, |x| x.0) as f64 / 1e9;
    Some((t, r.executed.len()))
}

#[test]
#[ignore]
fn segmentation_cost_report() {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../tests/fixtures/slicer/");
    for f in ["prusaslicer.gcode", "cura.gcode", "slic3r.gcode"] {
        let path = format!("{dir}{f}");
        let no_marks = Policy {
            stop_at_marks: false,
            ..Policy::FIRMWARE
        };
        let unseg = Policy {
            segment: false,
            ..no_marks
        };
        let rows = [
            ("unsegmented, no stop at marks", 0.2, unseg),
            ("0.2 mm, no stop at marks", 0.2, no_marks),
            ("0.2 mm (default)", 0.2, Policy::FIRMWARE),
            ("0.1 mm", 0.1, Policy::FIRMWARE),
            ("0.5 mm", 0.5, Policy::FIRMWARE),
        ];
        for (name, seg, pol) in rows {
            if let Some((t, blocks)) = print_time_s(&path, seg, pol) {
                println!("{f:18} {name:32} print {t:9.2} s  blocks {blocks:7}");
            }
        }
    }
}
