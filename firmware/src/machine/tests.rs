use super::*;
use crate::gcode::parse_line;
use crate::motion::round_i32;
use proptest::prelude::*;

const CFG: MachineConfig = MachineConfig::ENDER3;

fn c(s: &str) -> Command {
    parse_line(s.as_bytes()).unwrap().command.unwrap()
}

fn run(m: &mut MachineState, s: &str) -> Result<Action, MachineError> {
    m.apply(&c(s), &CFG)
}

fn mv(m: &mut MachineState, s: &str) -> MoveRequest {
    match run(m, s) {
        Ok(Action::Move(r)) => r,
        other => panic!("{s}: {other:?}"),
    }
}

#[test]
fn absolute_relative_and_e_modes() {
    let mut m = MachineState::new(&CFG);
    assert_eq!(mv(&mut m, "G1 X10 E1").target, [800, 0, 0, 93]);
    run(&mut m, "G91").unwrap();
    assert!(m.is_relative() && m.is_relative_e());
    assert_eq!(mv(&mut m, "G1 X10 E1").target, [1600, 0, 0, 186]);
    // M82 after G91: E absolute, XYZ still relative.
    run(&mut m, "M82").unwrap();
    assert_eq!(mv(&mut m, "G1 X1 E3").target, [1680, 0, 0, 279]);
    // G90 sets E absolute too; M83 after it makes E relative again.
    run(&mut m, "G90").unwrap();
    run(&mut m, "M83").unwrap();
    assert_eq!(mv(&mut m, "G1 X1 E1").target, [80, 0, 0, 372]);
    // M83 then G90: G90 wins for E (last one wins, as Marlin does).
    run(&mut m, "G90").unwrap();
    assert!(!m.is_relative_e());
}

#[test]
fn g92_offsets_are_per_axis() {
    let mut m = MachineState::new(&CFG);
    mv(&mut m, "G1 X100 Y50 E5");
    run(&mut m, "G92 X0 E0").unwrap();
    assert_eq!(m.logical_mm(), [0.0, 50.0, 0.0, 0.0]);
    // X now logical 10 = machine 110; E from logical 0 to 2 feeds 2 more mm.
    assert_eq!(mv(&mut m, "G1 X10 E2").target, [8800, 4000, 0, 651]);
    // Bounds apply to machine coordinates: logical 130 = machine 230 is fine, 140 is not.
    assert!(run(&mut m, "G1 X130").is_ok());
    assert_eq!(
        run(&mut m, "G1 X140"),
        Err(MachineError::OutOfBounds(Axis::X))
    );
    // Homing clears the offset of the homed axis only.
    assert_eq!(
        run(&mut m, "G28 X"),
        Ok(Action::Home(AxisFlags([true, false, false, false])))
    );
    assert_eq!(m.logical_mm()[0], 0.0);
    assert_eq!(m.position_steps(&CFG)[0], 0);
}

#[test]
fn inches_feed_and_overrides() {
    let mut m = MachineState::new(&CFG);
    run(&mut m, "G20").unwrap();
    let r = mv(&mut m, "G1 X1 F60");
    assert_eq!(r.target[0], 2032); // 25.4 mm × 80
    assert!((r.feed_mm_s - 25.4).abs() < 1e-4);
    run(&mut m, "G21").unwrap();
    assert_eq!(run(&mut m, "G1 F1200"), Ok(Action::None));
    assert_eq!(m.feed_mm_s(), 20.0);
    run(&mut m, "M220 S150").unwrap();
    assert_eq!(mv(&mut m, "G1 X30").feed_mm_s, 30.0);
    run(&mut m, "M221 S50").unwrap();
    assert_eq!(mv(&mut m, "G1 X31 E10").target[3], 465); // 5 mm fed
    assert_eq!(m.logical_mm()[3], 10.0);
    assert_eq!(
        run(&mut m, "M220 S0"),
        Err(MachineError::OverrideOutOfRange)
    );
    assert_eq!(run(&mut m, "G1 X1 F0"), Err(MachineError::BadFeed));
    assert_eq!(run(&mut m, "G1 X1 F-5"), Err(MachineError::BadFeed));
    // Issue 31: `G1 X13 F0.0001` was an 83-day move.
    assert_eq!(run(&mut m, "G1 X13 F0.0001"), Err(MachineError::FeedTooLow));
    assert_eq!(run(&mut m, "G1 X13 F5.99"), Err(MachineError::FeedTooLow));
    // 6 mm/min with the 150 % override above.
    assert!((mv(&mut m, "G1 X13 F6").feed_mm_s - 0.15).abs() < 1e-6);
    run(&mut m, "G20").unwrap();
    // 0.2 in/min = 5.08 mm/min.
    assert_eq!(run(&mut m, "G1 F0.2"), Err(MachineError::FeedTooLow));
    assert_eq!(run(&mut m, "G1 F0.3"), Ok(Action::None));
    run(&mut m, "G21").unwrap();
    assert!(MachineError::FeedTooLow
        .message()
        .contains(&format!("{MIN_FEED_MM_MIN} mm/min")));
    assert_eq!(run(&mut m, "M220"), Ok(Action::Executive));
}

#[test]
fn errors_leave_state_unchanged() {
    let mut m = MachineState::new(&CFG);
    mv(&mut m, "G1 X10 Y10 Z1 E1 F600");
    for bad in [
        "G1 X-1",
        "G1 Y236",
        "G1 Z251 E5 F100",
        "G1 X5 F0",
        "G1 X5 F0.0001",
        "G2 X20 Y10",
        "G2 X20 Y10 I5 R5",
        "G2 X10 Y10 R5",
        "G2 X30 Y10 I1",
        "G2 X10 Y10 I-20",
        "M221 S1000",
        "G4 P-1",
    ] {
        let before = m;
        assert!(run(&mut m, bad).is_err(), "{bad}");
        assert_eq!(m, before, "{bad}");
    }
}

#[test]
fn no_drift_over_many_relative_moves() {
    let mut m = MachineState::new(&CFG);
    run(&mut m, "G91").unwrap();
    let mut last = None;
    for _ in 0..2000 {
        if let Ok(Action::Move(r)) = run(&mut m, "G1 X0.1 E0.0123") {
            last = Some(r);
        }
    }
    let r = last.unwrap();
    // 200 mm × 80 and 24.6 mm × 93, rounded once.
    assert_eq!(r.target[0], 16000);
    assert_eq!(r.target[3], 2288);
}

#[test]
fn seq_strictly_increases_and_errors_do_not_consume() {
    let mut m = MachineState::new(&CFG);
    let a = mv(&mut m, "G1 X1");
    assert!(run(&mut m, "G1 X-5").is_err());
    let b = mv(&mut m, "G1 X2");
    assert_eq!(b.seq, a.seq + 1);
    let Ok(Action::Arc(arc)) = run(&mut m, "G2 X4 Y0 I1 J0") else {
        panic!()
    };
    let seqs: heapless::Vec<u32, 4096> = arc.map(|r| r.seq).collect();
    assert_eq!(seqs.first(), Some(&(b.seq + 1)));
    assert!(seqs.windows(2).all(|w| w[1] == w[0] + 1));
    let c = mv(&mut m, "G1 X10");
    assert_eq!(Some(&(c.seq - 1)), seqs.last());
}

#[test]
fn arcs_follow_the_circle_and_end_exactly() {
    let mut m = MachineState::new(&CFG);
    mv(&mut m, "G1 X100 Y100 Z1 E0");
    // Quarter circle counter-clockwise around (100, 110) to (110, 110), E 1 mm.
    let Ok(Action::Arc(arc)) = run(&mut m, "G3 X110 Y110 J10 E1") else {
        panic!()
    };
    let n = arc.segments();
    assert!(n > 10, "{n}");
    let mut last = None;
    for r in arc {
        let x = f64::from(r.target[0]) / 80.0 - 100.0;
        let y = f64::from(r.target[1]) / 80.0 - 110.0;
        let rad = libm::hypot(x, y);
        // On the circle within chord tolerance + a step of rounding.
        assert!((rad - 10.0).abs() < ARC_CHORD_TOLERANCE_MM + 0.02, "{rad}");
        // Counter-clockwise from (100,100) to (110,110) about (100,110): x ≥ 0 side.
        assert!(x >= -0.02);
        last = Some(r);
    }
    assert_eq!(last.unwrap().target, [8800, 8800, 400, 93]);
    assert_eq!(m.position_steps(&CFG), [8800, 8800, 400, 93]);
    // Clockwise with R: the short way round from (110,110) to (100,120), centre (100,110)? No:
    // clockwise short arc has the centre right of the chord: (110,120).
    let Ok(Action::Arc(arc)) = run(&mut m, "G2 X100 Y120 R10") else {
        panic!()
    };
    for r in arc {
        let x = f64::from(r.target[0]) / 80.0 - 110.0;
        let y = f64::from(r.target[1]) / 80.0 - 120.0;
        assert!((libm::hypot(x, y) - 10.0).abs() < 0.03);
    }
    // Full circle with I only.
    let Ok(Action::Arc(arc)) = run(&mut m, "G2 I5") else {
        panic!()
    };
    assert!(arc.segments() > 50, "{}", arc.segments());
    assert_eq!(arc.last().unwrap().target, m.position_steps(&CFG));
}

#[test]
fn arc_bulging_out_of_the_volume_is_refused() {
    let mut m = MachineState::new(&CFG);
    mv(&mut m, "G1 X5 Y100");
    let before = m;
    // Half circle to the left of x = 5 with radius 10: reaches x = -5.
    assert_eq!(
        run(&mut m, "G2 X5 Y120 I0 J10"),
        Err(MachineError::ArcOutOfBounds(Axis::X))
    );
    assert_eq!(m, before);
    // The other way round (through x = 15) stays inside.
    assert!(matches!(
        run(&mut m, "G3 X5 Y120 I0 J10"),
        Ok(Action::Arc(_))
    ));
}

/// Regression (issue 16, found by `state_stays_consistent` on a fresh seed): the end point is
/// inside, no axis extreme of the circle is within the sweep, but the radius changes along the
/// arc (the end is 0.94 mm off the circle of radius 5081 mm) and the chord points dip below
/// Y = 0. Every point the arc would run through is checked, not just the extremes.
#[test]
fn arc_points_between_inside_ends_are_checked() {
    let mut m = MachineState::new(&CFG);
    run(&mut m, "G20").unwrap();
    let before = m;
    assert_eq!(
        run(&mut m, "G3 X3 J200 I4"),
        Err(MachineError::ArcOutOfBounds(Axis::Y))
    );
    assert_eq!(m, before);
    // The same arc in the other direction goes the long way round: out of the volume as well.
    assert!(run(&mut m, "G2 X3 J200 I4").is_err());
    assert_eq!(m, before);
}

/// Every segment end of an accepted arc lies in the build volume (to half a step).
fn assert_arc_inside(arc: ArcMoves) {
    for r in arc {
        for axis in [Axis::X, Axis::Y, Axis::Z] {
            let a = CFG.axis(axis);
            let mm = f64::from(r.target[axis.index()]) / f64::from(a.steps_per_mm);
            let slack = BOUNDS_TOLERANCE_MM + 0.5 / f64::from(a.steps_per_mm);
            assert!(mm >= f64::from(a.min_mm) - slack, "{axis:?} {mm}");
            assert!(mm <= f64::from(a.max_mm) + slack, "{axis:?} {mm}");
        }
    }
}

#[test]
fn arcs_touching_the_edge_are_taken() {
    let mut m = MachineState::new(&CFG);
    mv(&mut m, "G1 X10 Y0");
    // Half circle from (10, 0) to (30, 0) through (20, 10): the ends on the edge, inside.
    let Ok(Action::Arc(a)) = run(&mut m, "G2 X30 Y0 I10 J0") else {
        panic!()
    };
    assert_arc_inside(a);
}

#[test]
fn firmware_retract_and_dwell() {
    let mut m = MachineState::new(&CFG);
    let r = mv(&mut m, "G10");
    assert_eq!(r.target[3], -186);
    assert_eq!(run(&mut m, "G10"), Ok(Action::None));
    assert_eq!(m.logical_mm()[3], 0.0);
    assert_eq!(mv(&mut m, "G11").target[3], 0);
    assert_eq!(run(&mut m, "G4 S1.5"), Ok(Action::Dwell { ms: 1500 }));
    assert_eq!(run(&mut m, "G4 P20"), Ok(Action::Dwell { ms: 20 }));
    assert_eq!(run(&mut m, "M104 S200"), Ok(Action::Executive));
}

#[test]
fn set_position_steps_keeps_offsets() {
    let mut m = MachineState::new(&CFG);
    mv(&mut m, "G1 X50 E10");
    run(&mut m, "G92 X0 E0").unwrap();
    m.set_position_steps(&[4800, 0, 0, 1023], &CFG);
    assert_eq!(m.position_steps(&CFG), [4800, 0, 0, 1023]);
    let l = m.logical_mm();
    assert!((l[0] - 10.0).abs() < 1e-9);
    assert!((l[3] - 1.0).abs() < 1e-9);
}

/// The points of an arc in mm (X Y Z E), and its centre's unwrapped angle at each, turns
/// counted (positive counter-clockwise), from the start point.
fn arc_path(arc: ArcMoves, start: [f64; 4], centre: [f64; 2]) -> Vec<([f64; 4], f64)> {
    let spm = [80.0, 80.0, 400.0, 93.0];
    let angle = |p: &[f64; 4]| libm::atan2(p[1] - centre[1], p[0] - centre[0]);
    let (mut prev, mut turned) = (angle(&start), 0.0);
    arc.map(|r| {
        let p: [f64; 4] = core::array::from_fn(|k| f64::from(r.target[k]) / spm[k]);
        let a = angle(&p);
        // Steps between segment ends are far below half a turn: unwrap by the short way.
        let mut d = a - prev;
        while d > core::f64::consts::PI {
            d -= core::f64::consts::TAU;
        }
        while d < -core::f64::consts::PI {
            d += core::f64::consts::TAU;
        }
        turned += d;
        prev = a;
        (p, turned)
    })
    .collect()
}

/// `G3 … P1` with end = start (BambuStudio's spiral Z lift, `G3 Z.88 I-.86 J.861 P1`): Marlin's
/// `plan_arc` makes the full circle 360° and `P1` adds one more, so two turns; Z rises
/// linearly with the angle. Hand-derived for r = 10 mm: the chord tolerance allows
/// 2·acos(1 − 0.005/10) = 0.0632482 rad per segment, 4π / 0.0632482 = 198.68 → 199 segments
/// (the 0.1 mm minimum would allow 1256); the chords sum to 199·2·10·sin(4π/398) = 125.643 mm.
#[test]
fn arc_p_full_circle_makes_p_plus_one_turns() {
    let mut m = MachineState::new(&CFG);
    mv(&mut m, "G1 X110 Y100 Z1 E0");
    let Ok(Action::Arc(arc)) = run(&mut m, "G3 Z1.2 I-10 P1") else {
        panic!()
    };
    assert_eq!(arc.segments(), 199);
    let pts = arc_path(arc, [110.0, 100.0, 1.0, 0.0], [100.0, 100.0]);
    assert_eq!(pts.len(), 199);
    let (end, turned) = pts[198];
    assert_eq!(end, [110.0, 100.0, 1.2, 0.0]);
    assert!(
        (turned / core::f64::consts::TAU - 2.0).abs() < 1e-3,
        "{turned}"
    );
    let mut len = 0.0;
    let mut prev = [110.0, 100.0];
    for (p, turned) in &pts {
        len += libm::hypot(p[0] - prev[0], p[1] - prev[1]);
        prev = [p[0], p[1]];
        // Z linear in the angle (to the step, 1/400 mm).
        let z = 1.0 + 0.2 * turned / (2.0 * core::f64::consts::TAU);
        assert!((p[2] - z).abs() <= 0.5 / 400.0 + 1e-9, "{p:?} {z}");
    }
    // Step rounding (1/80 mm) moves each vertex; the sum stays within a few hundredths.
    assert!((len - 125.643).abs() < 0.05, "{len}");
    assert_eq!(m.position_steps(&CFG), [8800, 8000, 480, 0]);
}

/// `G2 … P2` on a quarter arc: clockwise from (100, 100) about (110, 100) to (110, 110) is
/// −π/2; two circles more make −(π/2 + 4π) = −4.5π, 2.25 turns. E is shared out by angle
/// (Marlin's per-circle share 360° / total): E at any point = 3 mm × turned / −4.5π.
/// Segments: 4.5π / 0.0632482 = 223.5 → 224.
#[test]
fn arc_p_adds_whole_turns_to_a_partial_arc() {
    let mut m = MachineState::new(&CFG);
    mv(&mut m, "G1 X100 Y100 Z1 E0");
    let Ok(Action::Arc(arc)) = run(&mut m, "G2 X110 Y110 I10 J0 E3 P2") else {
        panic!()
    };
    assert_eq!(arc.segments(), 224);
    let pts = arc_path(arc, [100.0, 100.0, 1.0, 0.0], [110.0, 100.0]);
    let (end, turned) = pts[pts.len() - 1];
    assert_eq!(end, [110.0, 110.0, 1.0, 3.0]);
    assert!(
        (turned + 4.5 * core::f64::consts::PI).abs() < 1e-3,
        "{turned}"
    );
    for (p, turned) in &pts {
        assert!((libm::hypot(p[0] - 110.0, p[1] - 100.0) - 10.0).abs() < 0.02);
        let e = 3.0 * turned / (-4.5 * core::f64::consts::PI);
        assert!((p[3] - e).abs() <= 0.5 / 93.0 + 1e-9, "{p:?} {e}");
    }
    // P0 is the plain arc.
    mv(&mut m, "G1 X100 Y100");
    let Ok(Action::Arc(plain)) = run(&mut m, "G2 X110 Y110 I10 J0 P0") else {
        panic!()
    };
    let pts = arc_path(plain, [100.0, 100.0, 1.0, 3.0], [110.0, 100.0]);
    assert!((pts[pts.len() - 1].1 + core::f64::consts::FRAC_PI_2).abs() < 1e-3);
}

/// The bound: P at most 100 (Marlin's `WITHIN(circles_to_do, 0, 100)`); a larger, negative or
/// fractional P is a parse error (the line changes nothing). P100 of a 100 mm circle (63 m of
/// path) is still at most ARC_MAX_SEGMENTS segments, so the bounds check and the iteration
/// cost what any arc costs; it ends exactly and winds 101 times.
#[test]
fn arc_p_is_bounded() {
    use crate::gcode::ParseErrorKind;
    for (line, kind) in [
        ("G2 I5 P101", ParseErrorKind::OutOfRange),
        ("G2 I5 P255", ParseErrorKind::OutOfRange),
        ("G2 I5 P4294967296", ParseErrorKind::OutOfRange),
        ("G2 I5 P-1", ParseErrorKind::Negative),
        ("G2 I5 P1.5", ParseErrorKind::NotWhole),
    ] {
        assert_eq!(
            parse_line(line.as_bytes()).map(|_| ()).unwrap_err().kind,
            kind,
            "{line}"
        );
    }
    let mut m = MachineState::new(&CFG);
    mv(&mut m, "G1 X17 Y117 Z1");
    let Ok(Action::Arc(arc)) = run(&mut m, "G2 I100 P100") else {
        panic!()
    };
    assert_eq!(arc.segments(), ARC_MAX_SEGMENTS);
    let pts = arc_path(arc, [17.0, 117.0, 1.0, 0.0], [117.0, 117.0]);
    let (end, turned) = pts[pts.len() - 1];
    assert_eq!(end, [17.0, 117.0, 1.0, 0.0]);
    assert!(
        (turned / core::f64::consts::TAU + 101.0).abs() < 1e-3,
        "{turned}"
    );
}

fn line() -> impl Strategy<Value = String> {
    prop_oneof![
        "G[0-3]( [XYZEIJR]-?[0-9]{1,3}(\\.[0-9]{1,3})?){0,5}( P[0-9]{1,3})?( F[0-9]{1,4})?",
        Just("G90".to_string()),
        Just("G91".to_string()),
        Just("M82".to_string()),
        Just("M83".to_string()),
        Just("G20".to_string()),
        Just("G21".to_string()),
        Just("G10".to_string()),
        Just("G11".to_string()),
        "G28( X)?( Y)?( Z)?",
        "G92( [XYZE]-?[0-9]{1,3})",
        "M22[01] S[0-9]{1,4}",
        "G4 [PS]-?[0-9]{1,3}",
    ]
}

proptest! {
    #[test]
    fn round_i32_matches_libm(x in -3.0e9f64..3.0e9, f in prop_oneof![Just(0.5), Just(-0.5), Just(0.0), -1.0f64..1.0]) {
        let v = libm::round(x.trunc() + f);
        let want = if v >= f64::from(i32::MIN) && v <= f64::from(i32::MAX) { Some(v as i32) } else { None };
        prop_assert_eq!(round_i32(x.trunc() + f), want);
        let v = libm::round(x);
        let want = if v >= f64::from(i32::MIN) && v <= f64::from(i32::MAX) { Some(v as i32) } else { None };
        prop_assert_eq!(round_i32(x), want);
    }

    /// Random command sequences: no panic; an error changes nothing; a success keeps the
    /// commanded position in the build volume and the step position consistent with it.
    #[test]
    fn state_stays_consistent(lines in proptest::collection::vec(line(), 1..60)) {
        let mut m = MachineState::new(&CFG);
        let mut last_seq = 0;
        for l in &lines {
            let Ok(parsed) = parse_line(l.as_bytes()) else { continue };
            let Some(cmd) = parsed.command else { continue };
            let before = m;
            match m.apply(&cmd, &CFG) {
                Err(_) => prop_assert_eq!(m, before),
                Ok(Action::Move(r)) => {
                    prop_assert!(r.seq > last_seq);
                    last_seq = r.seq;
                    prop_assert_eq!(r.target, m.position_steps(&CFG));
                }
                Ok(Action::Arc(arc)) => {
                    let mut end = None;
                    for r in arc {
                        prop_assert!(r.seq > last_seq);
                        last_seq = r.seq;
                        for axis in [Axis::X, Axis::Y, Axis::Z] {
                            let a = CFG.axis(axis);
                            let mm = f64::from(r.target[axis.index()]) / f64::from(a.steps_per_mm);
                            // The commanded point in the volume, rounded to the nearest step.
                            let slack = BOUNDS_TOLERANCE_MM + 0.5 / f64::from(a.steps_per_mm);
                            prop_assert!(mm >= f64::from(a.min_mm) - slack, "{:?} {}", axis, mm);
                            prop_assert!(mm <= f64::from(a.max_mm) + slack, "{:?} {}", axis, mm);
                        }
                        end = Some(r.target);
                    }
                    prop_assert_eq!(end, Some(m.position_steps(&CFG)));
                }
                Ok(_) => {}
            }
            let pos = m.machine_mm();
            for axis in [Axis::X, Axis::Y, Axis::Z] {
                prop_assert!(pos[axis.index()] >= f64::from(CFG.axis(axis).min_mm) - BOUNDS_TOLERANCE_MM);
                prop_assert!(pos[axis.index()] <= f64::from(CFG.axis(axis).max_mm) + BOUNDS_TOLERANCE_MM);
            }
        }
    }
}
