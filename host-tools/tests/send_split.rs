//! The host-side fallback: move splitting and the pause/resume sequences.

use host_tools::job::gcode::parse;
use host_tools::job::modal::{Modal, E, X, Y, Z};
use host_tools::job::sender::fallback::{
    pause_sequence, resume_sequence, rewrite_move, sped_up_feed_mm_min, split_move, HostPause,
};
use proptest::prelude::*;
use std::f64::consts::{PI, TAU};

fn modal_after(lines: &[&str]) -> Modal {
    let mut m = Modal::default();
    for l in lines {
        if let Some(c) = parse(l).expect("parse") {
            m.apply(&c);
        }
    }
    m
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    /// Pieces are never longer than the limit, end exactly at the target, and extrude exactly
    /// what the original move extrudes (absolute or relative E, absolute or relative XYZ).
    #[test]
    fn split_pieces_are_short_and_add_up(
        x0 in 0.0f64..200.0, y0 in 0.0f64..200.0,
        dx in -50.0f64..50.0, dy in -50.0f64..50.0, de in 0.0f64..5.0,
        e0 in 0.0f64..1000.0,
        rel_e in any::<bool>(), rel_xyz in any::<bool>(),
        max in prop_oneof![Just(0.1), Just(0.2)],
    ) {
        let setup = [
            format!("G92 X{x0:.3} Y{y0:.3} Z0.2 E{e0:.4}"),
            if rel_xyz { "G91".into() } else { "G90".into() },
            if rel_e { "M83".into() } else { "M82".into() },
        ];
        let refs: Vec<&str> = setup.iter().map(String::as_str).collect();
        let before = modal_after(&refs);
        let mv = if rel_xyz {
            format!("G1 X{dx:.3} Y{dy:.3} E{:.5} F1800", if rel_e { de } else { before.pos_mm[E] + de })
        } else {
            format!(
                "G1 X{:.3} Y{:.3} E{:.5} F1800",
                before.pos_mm[X] + dx,
                before.pos_mm[Y] + dy,
                if rel_e { de } else { before.pos_mm[E] + de }
            )
        };
        let cmd = parse(&mv).expect("parse").expect("command");
        let mut target = before.clone();
        target.apply(&cmd);
        match split_move(&cmd, &before, max) {
            None => {
                let len = (dx * dx + dy * dy).sqrt();
                prop_assert!(len <= max + 1e-3, "unsplit move of {len} mm");
            }
            Some(pieces) => {
                let mut m = before.clone();
                for p in &pieces {
                    let c = parse(p).expect("piece parses").expect("command");
                    let step = m.apply(&c).expect("a move");
                    prop_assert!(step.xyz_len_mm() <= max + 2e-4, "{p}: {}", step.xyz_len_mm());
                }
                for ax in [X, Y, Z] {
                    prop_assert!((m.pos_mm[ax] - target.pos_mm[ax]).abs() < 1e-4);
                }
                prop_assert!((m.pos_mm[E] - target.pos_mm[E]).abs() < 2e-4,
                    "E {} vs {}", m.pos_mm[E], target.pos_mm[E]);
                prop_assert!(pieces[0].contains("F1800"));
            }
        }
    }
}

#[test]
fn pause_and_resume_sequences_follow_the_paper() {
    let m = modal_after(&["G90", "M82", "G92 E0", "G1 X50 Y60 Z1.2 E12.5 F1200"]);
    let p = HostPause {
        lift_mm: 0.0,
        park_xy_mm: (200.0, 200.0),
        ..HostPause::default()
    };
    assert_eq!(
        pause_sequence(&m, &p),
        ["M83", "G1 E-2 F1500", "M82", "G90", "G0 X200 Y200 F3600"]
    );
    let r = resume_sequence(&m, &p);
    assert_eq!(
        r,
        [
            "G90",
            "G0 X50 Y60 F3600",
            "G0 Z1.2 F600",
            "M83",
            "G1 E2 F1500",
            "G90",
            "M82",
            "G92 E12.5",
            "G1 F1200"
        ]
    );
    // Relative-E jobs get M83 back.
    let m = modal_after(&["G90", "M83", "G1 X5 Y5 Z0.4 E1 F900"]);
    let r = resume_sequence(&m, &p);
    assert!(r.contains(&"M83".to_string()) && r.last() == Some(&"G1 F900".to_string()));
    assert_eq!(r[r.len() - 3], "M83");
    // With a lift, the park goes up first and the return comes down after XY.
    let p = HostPause { lift_mm: 1.0, ..p };
    let s = pause_sequence(&m, &p);
    assert_eq!(s[4], "G0 Z1.4 F600");
}

/// Splits `line` (after `setup`) with [`rewrite_move`] and replays the pieces: the modal state
/// after every piece, and the expected end state.
fn replay(
    setup: &[String],
    line: &str,
    max: f64,
    feed: Option<f64>,
) -> (Vec<Modal>, Modal, Vec<String>) {
    let refs: Vec<&str> = setup.iter().map(String::as_str).collect();
    let before = modal_after(&refs);
    let cmd = parse(line).expect("parse").expect("command");
    let mut target = before.clone();
    target.apply(&cmd).expect("a move");
    let pieces = rewrite_move(&cmd, &before, max, feed).expect("rewritten");
    let mut m = before.clone();
    let mut states = vec![m.clone()];
    for p in &pieces {
        let c = parse(p).expect("piece parses").expect("command");
        assert!(c.is('G', 1), "{p}");
        m.apply(&c).expect("a move");
        states.push(m.clone());
    }
    (states, target, pieces)
}

proptest! {
    // 128 cases by default; `PROPTEST_CASES=5000` for a longer hunt.
    #![proptest_config(ProptestConfig::with_cases(
        std::env::var("PROPTEST_CASES").ok().and_then(|v| v.parse().ok()).unwrap_or(128)
    ))]

    /// G2/G3 arcs (I/J and R forms, CW and CCW, helical Z, E, absolute or relative modes) become
    /// straight pieces of at most the limit (and at least half of it), every vertex on the
    /// circle, turning the commanded way, Z and E proportional to the path, ending exactly at
    /// the target.
    #[test]
    fn arcs_become_short_chords_on_the_circle(
        cx in 60.0f64..160.0, cy in 60.0f64..160.0, r in 0.5f64..25.0,
        a0 in 0.0f64..TAU, sweep in 0.05f64..(TAU - 0.05),
        cw in any::<bool>(), radius_form in any::<bool>(),
        dz in prop_oneof![Just(0.0), 0.0f64..2.0], de in 0.0f64..5.0, e0 in 0.0f64..500.0,
        rel_e in any::<bool>(), rel_xyz in any::<bool>(),
        max in prop_oneof![Just(0.1), Just(0.2)],
    ) {
        // Near a half circle the R form is ill-conditioned (the centre moves by mm for µm of
        // text rounding, on any firmware): the I/J form covers those sweeps.
        prop_assume!(!radius_form || (sweep - PI).abs() > 0.1);
        let (x0, y0) = (cx + r * a0.cos(), cy + r * a0.sin());
        let a1 = if cw { a0 - sweep } else { a0 + sweep };
        let (x1, y1) = (cx + r * a1.cos(), cy + r * a1.sin());
        let z0 = 0.4;
        let setup = vec![
            format!("G92 X{x0:.5} Y{y0:.5} Z{z0} E{e0:.5}"),
            if rel_xyz { "G91".into() } else { "G90".into() },
            if rel_e { "M83".into() } else { "M82".into() },
        ];
        let (ex, ey, ez) = if rel_xyz { (x1 - x0, y1 - y0, dz) } else { (x1, y1, z0 + dz) };
        let ee = if rel_e { de } else { e0 + de };
        let centre = if radius_form {
            // R > 0: the short arc; R < 0: the long one.
            format!("R{:.5}", if sweep <= PI { r } else { -r })
        } else {
            format!("I{:.5} J{:.5}", cx - x0, cy - y0)
        };
        let zw = if dz > 0.0 { format!(" Z{ez:.5}") } else { String::new() };
        let line = format!(
            "G{} X{ex:.5} Y{ey:.5}{zw} E{ee:.5} {centre} F1200",
            if cw { 2 } else { 3 }
        );
        let (states, target, pieces) = replay(&setup, &line, max, None);
        prop_assert!(pieces[0].ends_with("F1200"), "{}", pieces[0]);
        let end = states.last().expect("states");
        for ax in [X, Y, Z] {
            prop_assert!((end.pos_mm[ax] - target.pos_mm[ax]).abs() < 1e-4, "axis {ax}");
        }
        prop_assert!((end.pos_mm[E] - target.pos_mm[E]).abs() < 2e-4);
        let start = &states[0];
        let arc_len = r * sweep;
        let mut path = 0.0;
        let mut lens = Vec::new();
        for w in states.windows(2) {
            let d: f64 = (0..3).map(|k| (w[1].pos_mm[k] - w[0].pos_mm[k]).powi(2)).sum::<f64>().sqrt();
            lens.push(d);
            path += d;
            let p = &w[1].pos_mm;
            // On the circle (chords within the firmware's 5 µm tolerance, 5-decimal text).
            let rr = ((p[X] - cx).powi(2) + (p[Y] - cy).powi(2)).sqrt();
            prop_assert!((rr - r).abs() < 0.0065, "radius {rr} vs {r}");
            // Turning the commanded way.
            let q = &w[0].pos_mm;
            let cross = (q[X] - cx) * (p[Y] - cy) - (q[Y] - cy) * (p[X] - cx);
            prop_assert!(if cw { cross < 1e-9 } else { cross > -1e-9 }, "wrong way: {cross}");
        }
        for (i, w) in states.windows(2).enumerate() {
            let done: f64 = lens[..=i].iter().sum::<f64>() / path;
            let p = &w[1].pos_mm;
            prop_assert!(((p[Z] - start.pos_mm[Z]) - dz * done).abs() < 1e-3, "Z off the helix");
            prop_assert!(((p[E] - start.pos_mm[E]) - de * done).abs() < 1e-3, "E not proportional");
        }
        let helix_len = (arc_len * arc_len + dz * dz).sqrt();
        prop_assert!((path - helix_len).abs() < 0.01 * helix_len + 1e-3, "path {path} vs arc {helix_len}");
        for l in &lens {
            prop_assert!(*l <= max + 2e-4, "piece of {l} mm");
            if helix_len > max {
                prop_assert!(*l >= max / 2.0 - 2e-3, "piece of {l} mm");
            }
        }
    }
}

#[test]
fn arc_forms_agree_and_full_circles_work() {
    let setup = vec![
        "G90".to_string(),
        "M82".into(),
        "G92 X100 Y110 Z0.2 E0".into(),
    ];
    // A quarter circle about (100, 100), clockwise, with I/J and with R.
    let (a, _, pa) = replay(&setup, "G2 X110 Y100 I0 J-10 E1", 0.2, None);
    let (b, _, pb) = replay(&setup, "G2 X110 Y100 R10 E1", 0.2, None);
    assert_eq!(pa, pb);
    assert_eq!(a.len(), b.len());
    // 15.7 mm of arc in pieces of at most 0.2 mm: at least 79.
    assert!(pa.len() >= 79, "{}", pa.len());
    assert_eq!(pa.last().map(String::as_str), Some("G1 X110 Y100 E1"));
    // The long way round with R < 0 (G3, counter-clockwise through the left side).
    let (c, _, _) = replay(&setup, "G3 X110 Y100 R-10 E3", 0.2, None);
    let lowest_x = c.iter().map(|m| m.pos_mm[X]).fold(f64::MAX, f64::min);
    assert!((lowest_x - 90.0).abs() < 0.01, "{lowest_x}");
    // A full circle with I/J (end = start).
    let (d, _, pd) = replay(&setup, "G3 X100 Y110 I0 J-10 E2", 0.2, None);
    assert!(pd.len() >= 315, "{}", pd.len());
    let highest_y = d.iter().map(|m| m.pos_mm[Y]).fold(f64::MIN, f64::max);
    let lowest_y = d.iter().map(|m| m.pos_mm[Y]).fold(f64::MAX, f64::min);
    assert!((highest_y - 110.0).abs() < 1e-3 && (lowest_y - 90.0).abs() < 0.01);
    // An arc the firmware refuses (end not on the circle) is sent unchanged.
    let m = modal_after(&["G90", "G92 X100 Y110"]);
    let bad = parse("G2 X150 Y100 I0 J-10")
        .expect("parse")
        .expect("command");
    assert_eq!(rewrite_move(&bad, &m, 0.2, None), None);
}

fn mv(line: &str, setup: &[&str]) -> host_tools::job::modal::Move {
    let mut m = modal_after(setup);
    m.apply(&parse(line).expect("parse").expect("command"))
        .expect("a move")
}

/// The speed-up after a layer pause request: ×3 by default, the factor and the flow bound
/// configurable, the firmware's formula (π·(d/2)²·e_per_mm·v ≤ max flow), never slower than the
/// job.
#[test]
fn speed_up_multiplies_the_feed_within_the_flow_limit() {
    let p = HostPause::default();
    assert_eq!(p.speedup_factor, 3.0);
    assert_eq!(p.max_volumetric_mm3_s, 12.0);
    assert_eq!(p.filament_diameter_mm, 1.75);
    let setup = ["G90", "M82", "G92 X10 Y10 Z0.2 E0", "G1 F1800"];
    let area = PI * 0.875 * 0.875;
    // Travel: ×3.
    let f = sped_up_feed_mm_min(&mv("G0 X20", &setup), &p).expect("feed");
    assert!((f - 5400.0).abs() < 1.0, "{f}");
    // Thin extrusion (0.05 mm of filament per mm): 90 mm/s needs 10.8 mm³/s < 12: ×3.
    let f = sped_up_feed_mm_min(&mv("G1 X20 E0.5", &setup), &p).expect("feed");
    assert!((f - 5400.0).abs() < 1.0, "{f}");
    // Thick extrusion (0.1 mm/mm): bounded by 12 mm³/s.
    let f = sped_up_feed_mm_min(&mv("G1 X20 E1", &setup), &p).expect("feed");
    let bound = 12.0 / (area * 0.1) * 60.0;
    assert!((f - bound).abs() < 0.005 * bound, "{f} vs {bound}");
    assert!(f < 5400.0 && f > 1800.0);
    // The flow bound is a flag: at 0.06 mm/mm, 12 mm³/s allows 83 mm/s, 6 mm³/s half that.
    let f12 = sped_up_feed_mm_min(&mv("G1 X20 E0.6", &setup), &p).expect("feed");
    let half = HostPause {
        max_volumetric_mm3_s: 6.0,
        ..p.clone()
    };
    let f6 = sped_up_feed_mm_min(&mv("G1 X20 E0.6", &setup), &half).expect("feed");
    let bound6 = 6.0 / (area * 0.06) * 60.0;
    assert!((f6 - bound6).abs() < 0.005 * bound6, "{f6} vs {bound6}");
    assert!((f12 - 2.0 * bound6).abs() < 0.01 * bound6, "{f12}");
    // So is the factor.
    let x2 = HostPause {
        speedup_factor: 2.0,
        ..p.clone()
    };
    let f = sped_up_feed_mm_min(&mv("G0 X20", &setup), &x2).expect("feed");
    assert!((f - 3600.0).abs() < 1.0, "{f}");
    // Never slower than the job: a move already faster than the bound keeps its feed...
    let f = sped_up_feed_mm_min(&mv("G1 X20 E1 F6000", &setup), &p).expect("feed");
    assert_eq!(f, 6000.0);
    // ... and a retract (no XYZ travel) is left alone; factor 1 turns the speed-up off.
    let f = sped_up_feed_mm_min(&mv("G1 E-2 F2400", &setup), &p).expect("feed");
    assert_eq!(f, 2400.0);
    let off = HostPause {
        speedup_factor: 1.0,
        ..p.clone()
    };
    assert_eq!(
        sped_up_feed_mm_min(&mv("G0 X20", &setup), &off),
        Some(1800.0)
    );
    // With a feed, even a short move is rewritten with it.
    let (_, _, pieces) = replay(
        &setup.iter().map(|s| s.to_string()).collect::<Vec<_>>(),
        "G1 X10.1 E0.01",
        0.2,
        Some(5400.0),
    );
    assert_eq!(pieces, ["G1 X10.1 E0.01 F5400"]);
}
