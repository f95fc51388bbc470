//! G28 through the planner with endstops (issue 16 item 4), driven like the board: the test
//! knows where each axis really is (the printer does not), and after every step event reports
//! each minimum switch, pressed at and below a known true position.
mod support;

/// The board's G28 (step interrupt running events 2 ms ahead, endstop watch, homed axes): the
/// same source the emulated-core test runs (`scripts/qemu-test.sh`).
#[path = "../qemu/src/board_homing.rs"]
mod board_homing;

#[test]
fn g28_with_the_board_step_queue_running_ahead() {
    assert_eq!(board_homing::run(), Ok(3));
}

use firmware::config::MachineConfig;
use firmware::homing::HomingConfig;
use firmware::motion::Axis;
use firmware::printer::{Printer, State};
use support::Run;

const CFG: MachineConfig = MachineConfig::ENDER3;
const AXES3: [Axis; 3] = [Axis::X, Axis::Y, Axis::Z];

/// Where the axes really are (true steps, moved by the step events; the printer's belief is
/// only its own count); each switch pressed at and below `switch` (true steps; `None`: never).
struct World {
    real: [i32; 3],
    switch: [Option<i32>; 3],
}

impl World {
    fn report(&self, p: &mut Printer) {
        for (i, axis) in AXES3.into_iter().enumerate() {
            p.set_endstop(axis, self.switch[i].is_some_and(|s| self.real[i] <= s));
        }
    }

    fn step(&mut self, axis_mask: u8, dir_mask: u8) {
        for i in 0..3 {
            if axis_mask & (1 << i) != 0 {
                self.real[i] += if dir_mask & (1 << i) != 0 { 1 } else { -1 };
            }
        }
    }
}

fn printer() -> Printer {
    let mut p = Printer::new(CFG);
    p.enable_endstops(HomingConfig::ENDER3);
    p.extrusion_guard_mut().allow_cold = true;
    p
}

/// Stream `lines` (each after the previous `ok`), send `sends` at their times, poll every
/// millisecond, report the switches after every step. The trace holds true positions.
fn drive(
    p: &mut Printer,
    w: &mut World,
    lines: &[&str],
    sends: &[(u64, &str)],
    limit_us: u64,
) -> Run {
    let mut r = Run::default();
    let (mut now, mut next, mut next_send, mut waiting) = (0u64, 0usize, 0usize, false);
    w.report(p);
    while now <= limit_us {
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
        while next_send < sends.len() && sends[next_send].0 <= now {
            let b = sends[next_send].1.as_bytes();
            assert_eq!(p.receive(b, now), b.len());
            next_send += 1;
        }
        p.poll(now);
        while let Some(t) = p.next_step_ns() {
            if t > (now + 1000) * 1000 {
                break;
            }
            let Some(ev) = p.next_step() else { break };
            w.step(ev.axis_mask, ev.dir_mask);
            w.report(p);
            r.trace
                .push((t, [w.real[0], w.real[1], w.real[2], p.status().position[3]]));
        }
        let mut s = String::new();
        let _ = p.write_output(&mut s);
        if s.lines().any(|l| l.starts_with("ok")) {
            waiting = false;
        }
        r.out.push_str(&s);
        now += 1000;
        let st = p.status().state;
        if next >= lines.len()
            && next_send >= sends.len()
            && !waiting
            && matches!(st, State::Idle | State::Halted)
            && p.next_step_ns().is_none()
        {
            break;
        }
    }
    r.end = p.status().position;
    r.end_us = now;
    r
}

/// The true positions one axis passes through from `start`, without repeats.
fn path(r: &Run, axis: usize, start: i32) -> Vec<i32> {
    let mut v: Vec<i32> = vec![start];
    for (_, p) in &r.trace {
        if v.last() != Some(&p[axis]) {
            v.push(p[axis]);
        }
    }
    v
}

/// Turning points of a path (where it changes direction), with its ends.
fn turns(v: &[i32]) -> Vec<i32> {
    let mut out = vec![v[0]];
    for w in v.windows(3) {
        if (w[1] - w[0]).signum() != (w[2] - w[1]).signum() {
            out.push(w[1]);
        }
    }
    out.push(v[v.len() - 1]);
    out
}

#[test]
fn g28_homes_every_axis_exactly_at_its_switch() {
    // The printer believes it is at 0; X is really 100 mm out, Y 50 mm, Z 10 mm; the switches
    // sit at odd true positions.
    let mut w = World {
        real: [8000, 4000, 4000],
        switch: [Some(-37), Some(11), Some(-3)],
    };
    let mut p = printer();
    let r = drive(&mut p, &mut w, &["G28", "M114"], &[], 120_000_000);
    assert!(!r.out.contains("Error"), "{}", r.out);
    // Homed: believed 0 on X Y Z, really at each switch, to the step.
    assert_eq!(r.end[..3], [0, 0, 0]);
    assert_eq!(w.real, [-37, 11, -3]);
    assert!(r.out.contains("X:0.00 Y:0.00 Z:0.00"), "{}", r.out);
    // Z rose 4 mm before X or Y moved.
    let z = turns(&path(&r, 2, 4000));
    assert_eq!(z[..2], [4000, 4000 + 4 * 400]);
    let first_xy = r
        .trace
        .iter()
        .position(|(_, q)| q[0] != 8000 || q[1] != 4000);
    let z_top = r.trace.iter().position(|(_, q)| q[2] == 4000 + 1600);
    assert!(z_top < first_xy, "{z_top:?} {first_xy:?}");
    // X: fast approach to the switch, back off 5 mm, slow approach to the switch again.
    assert_eq!(turns(&path(&r, 0, 8000)), [8000, -37, -37 + 400, -37]);
    assert_eq!(turns(&path(&r, 1, 4000)), [4000, 11, 11 + 400, 11]);
    // Z: down to the switch, back 2 mm, down again.
    assert_eq!(z[2..], [-3, -3 + 800, -3]);
    // The slow approach runs at half the feed (X: 10 mm/s): 5 mm took at least 0.5 s.
    let slow: Vec<u64> = r
        .trace
        .iter()
        .filter(|(_, q)| q[0] < -37 + 400 && q[1] == 4000 && q[0] > -37)
        .map(|(t, _)| *t)
        .collect();
    let span_s = (slow[slow.len() - 1] - slow[0]) as f64 * 1e-9;
    assert!(span_s > 0.9, "{span_s}"); // both passes through the last 5 mm, ≥ 0.25 + 0.5 s
}

/// After a slicer's end code the printer believes X is at 0 (e.g. `G1 X0`); the next G28 must
/// still home X, here really 3 mm away from its switch.
#[test]
fn g28_after_the_end_code_does_not_skip_x() {
    let mut w = World {
        real: [240, 0, 0],
        switch: [Some(0), Some(0), Some(0)],
    };
    let mut p = printer();
    let r = drive(&mut p, &mut w, &["G28 X"], &[], 30_000_000);
    assert!(!r.out.contains("Error"), "{}", r.out);
    assert_eq!(w.real[0], 0);
    assert_eq!(p.status().position[0], 0);
}

#[test]
fn a_switch_that_never_triggers_fails_with_a_clear_error() {
    let mut w = World {
        real: [0, 0, 0],
        switch: [None, Some(0), Some(0)],
    };
    let mut p = printer();
    let r = drive(&mut p, &mut w, &["G28 X", "G1 X10"], &[], 60_000_000);
    assert!(
        r.out
            .contains("Error:Homing Failed: X endstop not hit within 352 mm"),
        "{}",
        r.out
    );
    assert_eq!(p.status().state, State::Halted);
    // It searched 1.5 × the travel, then stopped: nothing after it ran.
    assert_eq!(path(&r, 0, 0).last(), Some(&(-352 * 80 - 40)));
}

/// M112 during the (long) Z approach stops the motion at once; M410 (quick stop) ends homing
/// too, and the printer takes moves again.
#[test]
fn m112_and_quick_stop_end_homing_at_once() {
    let mut w = World {
        real: [0, 0, 80_000],
        switch: [Some(0), Some(0), Some(0)],
    };
    let mut p = printer();
    let r = drive(
        &mut p,
        &mut w,
        &["G28 Z"],
        &[(3_000_000, "M112\n")],
        30_000_000,
    );
    assert_eq!(p.status().state, State::Halted);
    let last_t = r.trace.last().map(|(t, _)| *t).expect("moved");
    assert!(last_t <= 3_001_000_000, "stepped until {last_t} ns");
    assert!(w.real[2] > 60_000, "still far from the switch");

    let mut p = printer();
    let r = drive(
        &mut p,
        &mut w,
        &["G28 Z", "G1 Z150"],
        &[(3_000_000, "M410\n")],
        60_000_000,
    );
    assert!(r.out.contains("echo:homing aborted"), "{}", r.out);
    assert_ne!(p.status().state, State::Halted);
    // The G1 after it ran (believed position 150 mm).
    assert_eq!(p.status().position[2], 150 * 400);
}

#[test]
fn m119_reports_the_switches_as_marlin() {
    let mut w = World {
        real: [0, 100, 0],
        switch: [Some(0), Some(0), Some(0)],
    };
    let mut p = printer();
    let r = drive(&mut p, &mut w, &["M119"], &[], 1_000_000);
    // Exactly Marlin's lines (`Endstops::report_states()`: SERIAL_ECHOLNPGM, no `echo:`).
    let lines: Vec<&str> = r.out.lines().collect();
    let at = lines
        .iter()
        .position(|l| *l == "Reporting endstop status")
        .unwrap_or_else(|| panic!("{}", r.out));
    assert_eq!(
        lines[at..at + 4],
        [
            "Reporting endstop status",
            "x_min: TRIGGERED",
            "y_min: open",
            "z_min: TRIGGERED"
        ],
        "{}",
        r.out
    );
}
