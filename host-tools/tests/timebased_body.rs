//! `host-tools timebased` resamples the design only (issue 23): its body is the design's
//! motion between the printer's start and end code — no dive to the home corner, no replay of
//! the source's purge line or end moves, nothing below the first layer. Checked by the tests'
//! own G-code tracker (`tests/track`) against the design's own strings, not by the code under
//! test. Cost: one compile of a small design and two `host-tools` runs, ~0.3 s.

mod track;

use glam::DVec3;
use host_tools::design::model::{Model, Step};
use host_tools::design::profile::Profile;
use host_tools::design::turtle::Turtle;
use host_tools::design::writer::{GcodeWriter, WriteOptions};
use std::process::Command;

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_host-tools"))
}

/// Three layers of a 30 mm square and a 10 mm cross piece per layer (a travel between).
fn design() -> Model {
    let mut t = Turtle::at(DVec3::new(100.0, 100.0, 0.2), 0.08, 25.0);
    for k in 0..3 {
        let z = 0.2 * (k + 1) as f64;
        t.mark_layer(0.2);
        t.travel_to(DVec3::new(100.0, 100.0, z)).expect("to layer");
        for (x, y) in [
            (130.0, 100.0),
            (130.0, 130.0),
            (100.0, 130.0),
            (100.0, 100.0),
        ] {
            t.extrude_to(DVec3::new(x, y, z)).expect("side");
        }
        t.travel_to(DVec3::new(110.0, 115.0, z)).expect("travel");
        t.extrude_to(DVec3::new(120.0, 115.0, z))
            .expect("cross piece");
    }
    t.into_model()
}

/// The design's path: its strings and travels (and the implicit travels between strings that
/// do not join) as segments, in order.
fn design_path(m: &Model) -> Vec<([f64; 3], [f64; 3])> {
    let mut out = Vec::new();
    let mut at: Option<DVec3> = None;
    for s in &m.steps {
        match s {
            Step::String(st) => {
                if let Some(a) = at.filter(|a| *a != st.start) {
                    out.push((a.to_array(), st.start.to_array()));
                }
                out.push((st.start.to_array(), st.end.to_array()));
                at = Some(st.end);
            }
            Step::Travel { to, .. } => {
                if let Some(a) = at {
                    out.push((a.to_array(), to.to_array()));
                }
                at = Some(*to);
            }
            _ => {}
        }
    }
    out
}

#[test]
fn timebased_body_is_the_design_between_start_and_end_code() {
    let dir = std::env::temp_dir().join(format!("ht-tb-body-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("dir");
    let m = design();
    // The source: the vendor Ender-3 profile, with Cura's heat-up, purge line and end code.
    let p = Profile::builtin("ender3").expect("ender3");
    let (src, sum) = GcodeWriter::new(&p, WriteOptions::default())
        .to_string(&m)
        .expect("write");
    assert!(src.contains("Draw the first line"));
    let (input, output) = (dir.join("cup.gcode"), dir.join("cup.tb.gcode"));
    std::fs::write(&input, &src).expect("write source");
    for period in ["100", "37"] {
        let o = bin()
            .args(["timebased"])
            .arg(&input)
            .arg("-o")
            .arg(&output)
            .args(["--period-ms", period])
            .output()
            .expect("run");
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let tb = std::fs::read_to_string(&output).expect("read");
        let begin = tb.find(";TIMEBASED_BEGIN").expect("begin");
        let end = tb.find(";TIMEBASED_END").expect("end");
        let approach = tb.find(";TIMEBASED_APPROACH").expect("approach");
        assert!(approach < begin);
        // The printer's purge line once (its start code), never the source's again.
        assert_eq!(tb.matches("Draw the first line").count(), 1);
        assert_eq!(tb.matches("Present print").count(), 1);
        let first_layer = 0.2;
        let tr = track::track(&tb);
        let line_of = |off: usize| tb[..off].lines().count() + 1;
        let (l_approach, l_begin, l_end) = (line_of(approach), line_of(begin), line_of(end));
        // From the approach on, nothing goes below the first layer (no G1 X0 Y0 Z0 dive).
        for mv in tr
            .moves
            .iter()
            .filter(|mv| mv.line > l_approach && mv.line < l_end)
        {
            assert!(
                mv.to[2] >= first_layer - 1e-3,
                "line {} goes to z {}",
                mv.line,
                mv.to[2]
            );
        }
        // Every body sample lies on the design's path (3-decimal rounding).
        let path = design_path(&m);
        let body: Vec<_> = tr
            .moves
            .iter()
            .filter(|mv| mv.line > l_begin && mv.line < l_end)
            .collect();
        assert!(body.len() > 50);
        for mv in &body {
            let d = path
                .iter()
                .map(|(a, b)| track::seg_dist(mv.to, *a, *b))
                .fold(f64::INFINITY, f64::min);
            assert!(
                d < 2e-3,
                "period {period}: line {} at {:?} is {d} mm off the design",
                mv.line,
                mv.to
            );
        }
        // The first sample is the design's first printing point, the last its last one.
        let first_print = m
            .strings()
            .next()
            .map(|s| s.start.to_array())
            .expect("strings");
        let last_print = m
            .strings()
            .last()
            .map(|s| s.end.to_array())
            .expect("strings");
        let close = |a: [f64; 3], b: [f64; 3]| (0..3).all(|k| (a[k] - b[k]).abs() < 2e-3);
        assert!(close(body[0].to, first_print), "{:?}", body[0]);
        assert!(
            close(body[body.len() - 1].to, last_print),
            "{:?}",
            body.last()
        );
        // All the design's filament (net of its retractions), none of the purge's.
        let fed: f64 = body.iter().map(|mv| mv.de).sum();
        assert!(
            (fed - sum.filament_mm).abs() < 1e-3,
            "period {period}: {fed} vs {}",
            sum.filament_mm
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}
