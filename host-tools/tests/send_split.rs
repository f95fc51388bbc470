//! The host-side fallback: move splitting and the pause/resume sequences.

use host_tools::job::gcode::parse;
use host_tools::job::modal::{Modal, E, X, Y, Z};
use host_tools::sender::fallback::{pause_sequence, resume_sequence, split_move, HostPause};
use proptest::prelude::*;

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
