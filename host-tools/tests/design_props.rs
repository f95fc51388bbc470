//! Property tests of the writer on random designs: under absolute E the E of printing moves
//! never decreases and every retraction is primed back to the same value; no NaN or inf is
//! ever written; designs that stay inside the bed produce only positions inside the bed; the
//! filament written equals Σ cross-section × length ÷ filament area.

use glam::DVec3;
use host_tools::design::model::Model;
use host_tools::design::parts::Helix;
use host_tools::design::profile::Profile;
use host_tools::design::turtle::Turtle;
use host_tools::design::writer::{GcodeWriter, WriteOptions};
use host_tools::gcode::read::{default_reader, Event, GcodeReader};
use proptest::prelude::*;

#[derive(Clone, Debug)]
enum Op {
    Forward(f64, f64),
    Left(f64),
    Pen(bool),
    Speed(f64),
    Cross(f64),
}

fn op() -> impl Strategy<Value = Op> {
    prop_oneof![
        (0.0f64..20.0, 0.0f64..0.5).prop_map(|(r, dz)| Op::Forward(r, dz)),
        (-180.0f64..180.0).prop_map(Op::Left),
        any::<bool>().prop_map(Op::Pen),
        (1.0f64..150.0).prop_map(Op::Speed),
        (0.0f64..0.6).prop_map(Op::Cross),
    ]
}

/// Runs a turtle program, keeping it inside a 200 mm square (ops that would leave it are
/// turned into a left turn).
fn design(ops: &[Op]) -> Model {
    let mut t = Turtle::at(DVec3::new(117.5, 117.5, 0.2), 0.2, 20.0);
    for o in ops {
        match *o {
            Op::Forward(r, dz) => {
                let s = t.state();
                let h = s.heading_deg.to_radians();
                let p = s.pos + DVec3::new(r * h.cos(), r * h.sin(), dz);
                if p.x > 17.5 && p.x < 217.5 && p.y > 17.5 && p.y < 217.5 && p.z < 200.0 {
                    t.forward(r, dz).ok();
                } else {
                    t.left(90.0).ok();
                }
            }
            Op::Left(a) => {
                t.left(a).ok();
            }
            Op::Pen(d) => {
                if d {
                    t.pen_down()
                } else {
                    t.pen_up()
                }
            }
            Op::Speed(v) => {
                t.set_velocity(v).ok();
            }
            Op::Cross(c) => {
                t.set_cross_section(c).ok();
            }
        }
    }
    t.into_model()
}

fn written(p: &Profile, m: &Model) -> (String, f64) {
    let (g, s) = GcodeWriter::new(p, WriteOptions::default())
        .to_string(m)
        .expect("valid designs always write");
    (g, s.filament_mm)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(96))]

    #[test]
    fn absolute_e_is_monotone_and_finite(ops in proptest::collection::vec(op(), 1..120)) {
        let p = Profile::ender3();
        let m = design(&ops);
        let (g, _) = written(&p, &m);
        prop_assert!(!g.contains("NaN") && !g.contains("inf"));
        let mut last_print_e = 0.0f64;
        let mut retracted_from: Option<f64> = None;
        let mut e = 0.0f64;
        default_reader().read(g.as_bytes(), &mut |ev| {
            if let Event::Move { from, to, .. } = ev {
                e = to[3];
                let xyz = (0..3).any(|k| (to[k] - from[k]).abs() > 0.0);
                if xyz && to[3] > from[3] {
                    assert!(to[3] >= last_print_e - 1e-9, "E went back while printing");
                    last_print_e = to[3];
                } else if !xyz && to[3] < from[3] {
                    retracted_from = Some(from[3]);
                } else if !xyz && to[3] > from[3] {
                    let r = retracted_from.take();
                    assert_eq!(r, Some(to[3]), "prime must return to the retracted E");
                }
                if xyz && to[3] == from[3] {
                    // travels never carry E
                }
            }
        }).map_err(|e| TestCaseError::fail(e.to_string()))?;
        prop_assert!(e >= -10.0);
        // G0 lines never carry E
        for l in g.lines().filter(|l| l.starts_with("G0")) {
            prop_assert!(!l.contains('E'), "{}", l);
        }
    }

    #[test]
    fn positions_stay_inside_the_bed(ops in proptest::collection::vec(op(), 1..120)) {
        let p = Profile::ender3();
        let m = design(&ops);
        let (g, _) = written(&p, &m);
        let b = p.bed;
        default_reader().read(g.as_bytes(), &mut |ev| {
            if let Event::Move { to, .. } = ev {
                // The end code parks at X0 Y220 after lifting: all inside the bed too.
                assert!(to[0] >= b.x_min_mm && to[0] <= b.x_max_mm, "{to:?}");
                assert!(to[1] >= b.y_min_mm && to[1] <= b.y_max_mm, "{to:?}");
                assert!(to[2] >= 0.0 && to[2] <= b.z_max_mm, "{to:?}");
            }
        }).map_err(|e| TestCaseError::fail(e.to_string()))?;
    }

    #[test]
    fn filament_matches_volume(
        radius in 2.0f64..80.0,
        pitch in 0.1f64..1.0,
        turns in 0.5f64..20.0,
        per_turn in 3usize..200,
        cross in 0.05f64..0.5,
        relative in any::<bool>(),
    ) {
        let p = if relative { Profile::builtin("skr2").expect("p") } else { Profile::ender3() };
        let m = Helix { radius_mm: radius, pitch_mm: pitch, turns, per_turn, cross_mm2: cross,
                        ..Helix::default() }.build().expect("helix");
        let (g, filament) = written(&p, &m);
        let want = m.volume_mm3() / p.filament_area_mm2();
        prop_assert!((filament - want).abs() < 1e-6 * want.max(1.0));
        // The E written adds up to the same within the output rounding.
        let mut sum = 0.0;
        default_reader().read(g.as_bytes(), &mut |ev| {
            if let Event::Move { from, to, .. } = ev {
                let xyz = (0..3).any(|k| (to[k] - from[k]).abs() > 0.0);
                if xyz { sum += to[3] - from[3]; }
            }
        }).map_err(|e| TestCaseError::fail(e.to_string()))?;
        prop_assert!((sum - want).abs() < 0.002, "{} vs {}", sum, want);
    }
}
