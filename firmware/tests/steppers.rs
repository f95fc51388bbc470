//! M17/M18/M84 reach the board as stepper requests, in job order: a disable only once the
//! moves before it have been stepped.

use firmware::config::MachineConfig;
use firmware::printer::{Printer, StepperRequest};

fn send(p: &mut Printer, line: &str, now_us: u64) {
    let mut l = String::from(line);
    l.push('\n');
    assert_eq!(p.receive(l.as_bytes(), now_us), l.len());
    p.poll(now_us);
}

/// One 1 ms main-loop tick: poll, then take the step events due by its end.
fn tick(p: &mut Printer, now_us: u64) -> u64 {
    p.poll(now_us);
    while let Some(t) = p.next_step_ns() {
        if t > (now_us + 1000) * 1000 {
            break;
        }
        p.next_step();
    }
    now_us + 1000
}

/// Poll and step until nothing moves; returns the time reached, µs.
fn drain(p: &mut Printer, mut now_us: u64) -> u64 {
    for _ in 0..100_000 {
        now_us = tick(p, now_us);
        if p.next_step_ns().is_none() && p.status().queue_depth == 0 {
            p.poll(now_us);
            break;
        }
    }
    now_us
}

#[test]
fn enable_disable_and_timeout() {
    let mut p = Printer::new(MachineConfig::ENDER3);
    send(&mut p, "M17", 0);
    assert_eq!(
        p.take_stepper_request(),
        Some(StepperRequest::Enable { mask: 0b1111 })
    );
    send(&mut p, "M18 X E", 1000);
    assert_eq!(
        p.take_stepper_request(),
        Some(StepperRequest::Disable { mask: 0b1001 })
    );
    send(&mut p, "M84 S30", 2000);
    assert_eq!(
        p.take_stepper_request(),
        Some(StepperRequest::IdleTimeout { s: 30.0 })
    );
    send(&mut p, "M84", 3000);
    assert_eq!(
        p.take_stepper_request(),
        Some(StepperRequest::Disable { mask: 0b1111 })
    );
    assert_eq!(p.take_stepper_request(), None);
}

#[test]
fn bad_timeout_is_refused_not_a_request() {
    let mut p = Printer::new(MachineConfig::ENDER3);
    send(&mut p, "M84 S-5", 0);
    assert_eq!(p.take_stepper_request(), None);
    let mut out = String::new();
    p.write_output(&mut out).unwrap();
    // A refusal, as an `echo:` warning: `Error:` would end an OctoPrint print.
    assert!(out.contains("echo:refused: M84 S"), "{out}");
    assert!(!out.contains("Error"), "{out}");
}

#[test]
fn disable_waits_for_the_moves_before_it() {
    let mut p = Printer::new(MachineConfig::ENDER3);
    send(&mut p, "G28", 0);
    let t = drain(&mut p, 1000);
    send(&mut p, "G1 X50 F3000", t);
    send(&mut p, "M84", t);
    // Moving: the disable is held back.
    assert_eq!(p.take_stepper_request(), None);
    assert!(p.next_step_ns().is_some());
    let t = drain(&mut p, t + 1000);
    assert_eq!(
        p.take_stepper_request(),
        Some(StepperRequest::Disable { mask: 0b1111 })
    );
    assert!(t > 0);
}

#[test]
fn steppers_off_lose_the_position_until_homed_and_the_pause_does_not_park_there() {
    use firmware::motion::{PauseMode, Realtime};
    use firmware::printer::State;
    let mut p = Printer::new(MachineConfig::ENDER3);
    send(&mut p, "G1 X50 Y50 Z1 F6000", 0);
    let t = drain(&mut p, 0);
    assert_eq!(p.status().position_lost, 0);
    send(&mut p, "M18 X Y", t);
    let t = drain(&mut p, t);
    assert_eq!(p.status().position_lost, 0b011);
    let mut out = String::new();
    let _ = p.write_output(&mut out);
    assert!(out.contains("X Y position lost until G28"), "{out}");
    // A long move, paused now: retract and lift, but no park to bed coordinates.
    send(&mut p, "G1 X150 E5 F1200", t);
    let t = drain_until(&mut p, t, 500_000);
    p.request(Realtime::Pause(PauseMode::Now), t);
    let t = drain(&mut p, t);
    assert_eq!(p.status().state, State::Paused);
    let held = p.status().paused_at.expect("paused");
    let here = p.status().position;
    assert_eq!(here[..2], held[..2], "parked although X/Y were lost");
    assert!(here[2] > held[2], "lifted");
    out.clear();
    let _ = p.write_output(&mut out);
    assert!(out.contains("not parking"), "{out}");
    // Homing X and Y makes them trusted again.
    p.request(Realtime::Cancel, t);
    let t = drain(&mut p, t);
    // Lines right after a cancel are the rest of the job for a host that does not number its
    // lines (docs/frontend.md, "Cancel"): a new command comes after a pause of 2 s.
    let t = drain_until(&mut p, t, 2_100_000);
    send(&mut p, "G28 X Y", t);
    let _ = drain(&mut p, t);
    assert_eq!(p.status().position_lost, 0);
}

/// Poll and step for `us` microseconds from `now_us`; returns the time reached.
fn drain_until(p: &mut Printer, mut now_us: u64, us: u64) -> u64 {
    let end = now_us + us;
    while now_us < end {
        now_us = tick(p, now_us);
    }
    now_us
}
