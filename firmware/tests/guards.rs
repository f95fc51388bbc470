//! Machine safety at the executive (issue 16): cold and over-long extrusion, per-axis speed
//! limits (E included), arcs and the pause park inside the build volume. Refusals are `echo:`
//! lines (no `Error:`: OctoPrint ends a print on one) and change nothing.
mod support;

use firmware::config::MachineConfig;
use firmware::printer::{Printer, State};
use firmware::thermal::HeaterId;
use proptest::prelude::*;
use support::*;

const CFG: MachineConfig = MachineConfig::ENDER3;

/// A printer with the protection as configured (the support printer allows cold extrusion).
fn guarded() -> Printer {
    Printer::new(CFG)
}

/// Send `lines` one after another (each after the previous `ok`), polling every millisecond
/// and feeding the hotend temperature `hotend_c(t_us)` every tick; stop when everything ran
/// or at `limit_us`.
fn drive(p: &mut Printer, lines: &[&str], hotend_c: impl Fn(u64) -> f32, limit_us: u64) -> Run {
    let mut r = Run::default();
    let mut now = 0u64;
    let mut next = 0;
    let mut waiting = false;
    while now <= limit_us {
        p.thermal_sample(HeaterId::Hotend, hotend_c(now), now);
        p.thermal_sample(HeaterId::Bed, 25.0, now);
        if !waiting && next < lines.len() {
            let l = format!("{}\n", lines[next]);
            assert_eq!(
                p.receive(l.as_bytes(), now),
                l.len(),
                "one line per ok is always taken"
            );
            next += 1;
            waiting = true;
        }
        p.poll(now);
        while let Some(t) = p.next_step_ns() {
            if t > (now + 1000) * 1000 {
                break;
            }
            if p.next_step().is_none() {
                break;
            }
            r.trace.push((t, p.status().position));
        }
        let mut s = String::new();
        let _ = p.write_output(&mut s);
        if s.lines().any(|l| l.starts_with("ok")) {
            waiting = false;
        }
        r.out.push_str(&s);
        now += 1000;
        if next >= lines.len() && !waiting && p.status().state == State::Idle {
            break;
        }
    }
    r.end = p.status().position;
    r.end_us = now;
    r
}

#[test]
fn cold_extrusion_is_refused_until_m302_p1() {
    let mut p = guarded();
    let r = drive(
        &mut p,
        &["G1 E50", "G1 X10 E1", "M114"],
        |_| 25.0,
        2_000_000,
    );
    assert_eq!(
        r.out
            .matches("echo:refused: cold extrusion prevented")
            .count(),
        2,
        "{}",
        r.out
    );
    assert!(!r.out.contains("Error"), "{}", r.out);
    // Judged when the moves reach the planner, as Marlin: the E part is dropped, the rest
    // runs (X to 10 mm), and the next move feeds only its own filament (Marlin's
    // `position.e = target.e`): the logical E is where the lines put it, the E motor has not
    // moved.
    assert!(r.trace.iter().all(|(_, pos)| pos[3] == 0), "E moved cold");
    assert_eq!(r.end, [800, 0, 0, 0]);
    assert!(r.out.contains("X:10.00 Y:0.00 Z:0.00 E:1.00"), "{}", r.out);
    // Travel without E is fine cold; M302 P1 allows E: E1 → E5 feeds 4 mm.
    let r = drive(
        &mut p,
        &["G1 X10", "M302 P1", "G1 E5", "M302"],
        |_| 25.0,
        20_000_000,
    );
    assert!(!r.out.contains("prevented"), "{}", r.out);
    assert_eq!(r.end, [800, 0, 0, 372]);
    assert!(
        r.out
            .contains("echo:Cold extrudes are enabled (min temp 170C)"),
        "{}",
        r.out
    );
    // M302 S0 P0: protection on again with a minimum of 0 °C: 25 °C is warm enough.
    let r = drive(&mut p, &["M302 P0 S0", "G1 E6"], |_| 25.0, 20_000_000);
    assert!(!r.out.contains("prevented"), "{}", r.out);
    assert_eq!(r.end[3], 465);
}

/// M104 then an extruding move at once: the move is taken (the hotend heats) and waits in the
/// queue until the hotend reaches 170 °C; a travel move before it is not held.
#[test]
fn extrusion_taken_while_heating_waits_for_the_minimum() {
    let mut p = guarded();
    // 25 °C, rising 50 °C/s from t = 0.5 s: 170 °C at 3.4 s.
    let temp = |t: u64| 25.0 + (t.saturating_sub(500_000) as f32 * 1e-6 * 50.0).min(180.0);
    let r = drive(
        &mut p,
        &["M104 S200", "G1 X5 F600", "G1 E2 F600"],
        temp,
        10_000_000,
    );
    assert!(!r.out.contains("prevented"), "{}", r.out);
    let first_e = r
        .trace
        .iter()
        .find(|(_, pos)| pos[3] != 0)
        .map(|(t, _)| *t)
        .expect("E moved");
    let first_x = r.trace.first().map(|(t, _)| *t).expect("X moved");
    assert!(first_x < 1_000_000_000, "travel ran at once: {first_x}");
    assert!(
        first_e >= 3_400_000_000,
        "E moved at {first_e} ns, before 170 °C"
    );
    assert_eq!(r.end, [400, 0, 0, 186]);
    // The host hears from the printer while it waits, as during M109.
    assert!(r.out.contains("busy: processing"), "{}", r.out);
}

#[test]
fn over_long_extrusion_is_refused_even_with_m302() {
    let mut p = guarded();
    let r = drive(
        &mut p,
        &[
            "M302 P1",
            "G1 X1 E91335",
            "G92 E9999999",
            "G1 X5 E0",
            "M114",
        ],
        |_| 25.0,
        2_000_000,
    );
    assert_eq!(
        r.out
            .matches("echo:refused: too long extrusion prevented")
            .count(),
        2,
        "{}",
        r.out
    );
    assert!(r.trace.is_empty());
    assert!(
        r.out.contains("X:0.00 Y:0.00 Z:0.00 E:9999999.00"),
        "{}",
        r.out
    );
}

/// Issue 16: the chord points of `G3 X3 J200 I4` under G20 leave the machine although the end
/// point is inside: refused with an `echo:`, nothing queued, the position unchanged.
#[test]
fn arc_leaving_the_volume_is_refused_with_echo() {
    let mut p = printer();
    let r = run_gcode(&mut p, &["G20", "G3 X3 J200 I4", "M114"], &[], 5_000_000);
    assert!(
        r.out
            .contains("echo:refused: arc leaves the build volume (Y)"),
        "{}",
        r.out
    );
    assert!(!r.out.contains("Error"), "{}", r.out);
    assert!(r.trace.is_empty());
    assert!(r.out.contains("X:0.00 Y:0.00 Z:0.00"), "{}", r.out);
}

#[test]
fn m760_values_outside_the_machine_are_refused() {
    let mut p = printer();
    let r = run_gcode(
        &mut p,
        &["M760 X1000", "M760 Y100 Z300", "M760 F60000", "M760"],
        &[],
        1_000_000,
    );
    assert!(
        r.out
            .contains("echo:refused: M760 X1000.00 outside 0.00..235.00"),
        "{}",
        r.out
    );
    assert!(
        r.out.contains("echo:refused: M760 Z300.00 outside"),
        "{}",
        r.out
    );
    assert!(
        r.out.contains("echo:refused: M760 F60000.00 outside"),
        "{}",
        r.out
    );
    assert!(!r.out.contains("Error"), "{}", r.out);
    // All or nothing: Y100 came with a bad Z and was not taken either.
    assert!(
        r.out.contains("M760 R2.00 Z5.00 X235.0 Y235.0 F3600"),
        "{}",
        r.out
    );
}

/// The park position from the configuration is moved inside the travel whatever it says.
#[test]
fn park_stays_inside_the_travel() {
    let mut p = printer();
    p.config_mut().pause.park_x_mm = 1000.0;
    p.config_mut().pause.park_y_mm = -50.0;
    let r = run_gcode(
        &mut p,
        &["G1 X50 Y50 F6000", "G1 X60 F600"],
        &[(600_000, "M25\n")],
        30_000_000,
    );
    assert!(r.out.contains("//action:paused"), "{}", r.out);
    let (min, max) = r
        .trace
        .iter()
        .fold(([i32::MAX; 4], [i32::MIN; 4]), |(lo, hi), (_, p)| {
            (
                core::array::from_fn(|i| lo[i].min(p[i])),
                core::array::from_fn(|i| hi[i].max(p[i])),
            )
        });
    assert_eq!(r.end[..2], [235 * 80, 0]);
    assert!(max[0] <= 235 * 80 && min[1] >= 0, "{min:?} {max:?}");
}

/// Highest speed of each axis over the run, mm/s, from the step trace, over every window of
/// `WINDOW` consecutive steps of that axis, discounting `SLACK` steps: the step quantisation
/// (Bresenham puts a minor axis's steps on major-axis steps, and a segment's floor-rounded
/// share of a move can hold one step more than its exact share) shifts a window by at most
/// that many steps, whatever the speed.
fn axis_speeds(r: &Run) -> [f64; 4] {
    const WINDOW: usize = 32;
    const SLACK: f64 = 1.0;
    let mut out = [0.0f64; 4];
    for (ax, o) in out.iter_mut().enumerate() {
        let mut times = Vec::new();
        let mut last = None;
        for &(t, pos) in &r.trace {
            if last.is_some_and(|l: i32| l != pos[ax]) {
                times.push(t);
            }
            last = Some(pos[ax]);
        }
        let spm = f64::from(CFG.axes[ax].steps_per_mm);
        for w in times.windows(WINDOW + 1) {
            let dt_s = (w[WINDOW] - w[0]) as f64 * 1e-9;
            *o = o.max((WINDOW as f64 - SLACK) / spm / dt_s.max(1e-12));
        }
    }
    out
}

fn assert_within_limits(r: &Run, what: &str) {
    let v = axis_speeds(r);
    for (ax, v) in v.iter().enumerate() {
        let limit = f64::from(CFG.axes[ax].max_feed_mm_s);
        assert!(
            *v <= limit * 1.001,
            "{what}: axis {ax} at {v} mm/s, limit {limit}"
        );
    }
    for &(_, pos) in &r.trace {
        for (ax, (a, s)) in CFG.axes.iter().zip(pos).take(3).enumerate() {
            let lo = (a.min_mm * a.steps_per_mm).round() as i32;
            let hi = (a.max_mm * a.steps_per_mm).round() as i32;
            assert!((lo..=hi).contains(&s), "{what}: axis {ax} at step {s}");
        }
    }
}

/// The cases run E within its limit once allowed by length (the step generator used to
/// lift any cruise speed below 1e-3 mm/s to 1e-3, which ran E at 1e-3 × 80 000 = 80 mm/s on
/// `G1 Z0.0025 E200`), and a diagonal over the whole volume keeps every axis within its limit.
#[test]
fn extreme_ratios_keep_every_axis_within_its_limit() {
    for prog in [
        &["G1 Z0.0025 E200"][..],
        &["G1 X0.0125 E200 F60000"][..],
        &["G1 X0.0125 Y0.0125 Z0.0025 E-200"][..],
        &["G1 X235 Y235 Z250 E0.0108 F60000"][..],
        &["G92 E-150", "G1 X5 E0 F60000"][..],
    ] {
        let mut p = printer();
        let r = run_gcode(&mut p, prog, &[], 200_000_000);
        assert!(!r.out.contains("prevented"), "{}", r.out);
        assert!(!r.trace.is_empty());
        assert_within_limits(&r, &format!("{prog:?}"));
    }
}

fn num(lo: i32, hi: i32) -> impl Strategy<Value = String> {
    (lo * 100..=hi * 100).prop_map(|v| format!("{:.2}", f64::from(v) / 100.0))
}

fn line() -> impl Strategy<Value = String> {
    prop_oneof![
        4 => (num(-5, 240), num(-5, 240), num(0, 20), num(-60, 60), 60u32..30_000).prop_map(
            |(x, y, z, e, f)| format!("G1 X{x} Y{y} Z{z} E{e} F{f}")
        ),
        2 => (num(-5, 5), num(-5, 5), num(-250, 250), 60u32..30_000)
            .prop_map(|(x, z, e, f)| format!("G1 X{x} Z{z} E{e} F{f}")),
        1 => (num(0, 235), num(0, 235), num(-50, 50), num(-50, 50), any::<bool>()).prop_map(
            |(x, y, i, j, cw)| format!("G{} X{x} Y{y} I{i} J{j} F6000", if cw { 2 } else { 3 })
        ),
        1 => prop_oneof![
            Just("G91".to_string()),
            Just("G90".to_string()),
            Just("M83".to_string()),
            Just("M82".to_string()),
            Just("G20".to_string()),
            Just("G21".to_string()),
            Just("G10".to_string()),
            Just("G11".to_string()),
        ],
        1 => num(-100_000, 100_000).prop_map(|e| format!("G92 E{e}")),
        1 => (10u32..999).prop_map(|s| format!("M220 S{s}")),
        1 => (10u32..999).prop_map(|s| format!("M221 S{s}")),
        1 => (num(-10, 1100), num(-10, 1100), num(0, 300), 1u32..100_000)
            .prop_map(|(x, y, z, f)| format!("M760 X{x} Y{y} Z{z} F{f}")),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, .. ProptestConfig::default() })]

    /// Random programs (moves, arcs, modes, E resets, overrides, M760, a pause and resume):
    /// no axis ever runs beyond its speed limit, X Y Z never leave the travel.
    #[test]
    fn random_programs_respect_speed_limits_and_travel(
        lines in proptest::collection::vec(line(), 1..12),
        pause_at_ms in proptest::option::of(0u64..3000),
    ) {
        let mut p = printer();
        let lines: Vec<&str> = lines.iter().map(String::as_str).collect();
        let sends: Vec<(u64, &str)> = match pause_at_ms {
            Some(t) => vec![(t * 1000, "M25\n"), (t * 1000 + 2_000_000, "M24\n")],
            None => vec![],
        };
        let r = run_gcode(&mut p, &lines, &sends, 600_000_000);
        assert_within_limits(&r, &format!("{lines:?}"));
    }
}
