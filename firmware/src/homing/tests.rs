use super::*;
use crate::motion::AXES;

const CFG: MachineConfig = MachineConfig::ENDER3;

/// An axis whose true position (steps) the printer does not know, with a minimum switch pressed
/// at and below `switch_step` (`None`: a switch that never triggers).
struct World {
    phys: [i64; AXES],
    switch_step: [Option<i64>; 3],
}

impl Endstops for World {
    fn triggered(&mut self, axis: Axis) -> bool {
        let i = axis.index();
        i < 3 && self.switch_step[i].is_some_and(|s| self.phys[i] <= s)
    }
}

/// Runs homing to the end, one step at a time, checking the switch after every step of an
/// approach. Returns the moves made, the outcome, and the true position of each axis at the
/// moment it was declared homed.
fn run(
    w: &mut World,
    mask: u8,
    abort_after_steps: Option<u64>,
) -> (Vec<HomingMove>, Next, [Option<i64>; 3]) {
    let mut h = Homing::new(mask, &HomingConfig::ENDER3, &CFG);
    let mut moves = Vec::new();
    let mut homed_at = [None; 3];
    let mut steps_run = 0u64;
    loop {
        match h.next_step() {
            Next::Move(m) => {
                moves.push(m);
                let i = m.axis.index();
                let spm = f64::from(CFG.axis(m.axis).steps_per_mm);
                let n = (f64::from(m.distance_mm) * spm).round() as i64;
                let dir = n.signum();
                let mut end = MoveEnd::Completed { switch: false };
                let mut triggered = m.stop_at_switch && w.triggered(m.axis);
                for _ in 0..n.abs() {
                    if triggered {
                        break;
                    }
                    w.phys[i] += dir;
                    steps_run += 1;
                    if abort_after_steps.is_some_and(|a| steps_run >= a) {
                        h.abort();
                        break;
                    }
                    triggered = m.stop_at_switch && w.triggered(m.axis);
                }
                if !h.is_moving() {
                    continue;
                }
                if triggered {
                    end = MoveEnd::Triggered;
                } else if let MoveEnd::Completed { switch } = &mut end {
                    *switch = w.triggered(m.axis);
                }
                h.finished(end);
            }
            Next::Homed(axis) => homed_at[axis.index()] = Some(w.phys[axis.index()]),
            other => return (moves, other, homed_at),
        }
    }
}

fn world(switch: [Option<i64>; 3]) -> World {
    World {
        phys: [5000, 7000, 400, 0],
        switch_step: switch,
    }
}

#[test]
fn homes_exactly_to_the_step_with_z_raised_first_and_bumps() {
    let mut w = world([Some(-37), Some(12), Some(-3)]);
    let (moves, end, homed_at) = run(&mut w, 0, None);
    assert_eq!(end, Next::Done);
    // Exactly at the switch, to the step, on every axis.
    assert_eq!(homed_at, [Some(-37), Some(12), Some(-3)]);
    let mv = |axis, distance_mm, feed_mm_s, stop_at_switch| HomingMove {
        axis,
        distance_mm,
        feed_mm_s,
        stop_at_switch,
    };
    assert_eq!(
        moves,
        [
            mv(Axis::Z, 4.0, 4.0, false),
            mv(Axis::X, -352.5, 20.0, true),
            mv(Axis::X, 5.0, 20.0, false),
            mv(Axis::X, -10.0, 10.0, true),
            mv(Axis::Y, -352.5, 20.0, true),
            mv(Axis::Y, 5.0, 20.0, false),
            mv(Axis::Y, -10.0, 10.0, true),
            mv(Axis::Z, -375.0, 4.0, true),
            mv(Axis::Z, 2.0, 4.0, false),
            mv(Axis::Z, -4.0, 1.0, true),
        ]
    );
}

/// After a slicer's end code the printer believes X is at its minimum; G28 X still runs the
/// full sequence (the switch is elsewhere: the belief was wrong).
#[test]
fn an_axis_believed_home_is_homed_all_the_same() {
    let mut w = world([Some(-800), None, None]);
    let (moves, end, homed_at) = run(&mut w, 0b001, None);
    assert_eq!(end, Next::Done);
    assert_eq!(homed_at[0], Some(-800));
    // Z raised, then X: fast, bump, slow.
    assert_eq!(moves.len(), 4);
    // Z alone: no raise.
    let mut w = world([None, None, Some(0)]);
    let (moves, end, _) = run(&mut w, 0b100, None);
    assert_eq!(end, Next::Done);
    assert_eq!(moves[0].distance_mm, -375.0);
}

#[test]
fn a_switch_that_never_triggers_fails_after_one_and_a_half_travels() {
    let mut w = world([None, Some(0), Some(0)]);
    let start = w.phys[0];
    let (moves, end, _) = run(&mut w, 0b011, None);
    assert_eq!(
        end,
        Next::Failed(HomingError::SwitchNotHit {
            axis: Axis::X,
            searched_mm: 352.5
        })
    );
    assert_eq!(w.phys[0], start - 352 * 80 - 40);
    // Y was not tried.
    assert!(moves.iter().all(|m| m.axis != Axis::Y));
    assert_eq!(
        end_text(end),
        "Homing Failed: X endstop not hit within 352 mm"
    );
}

fn end_text(n: Next) -> String {
    match n {
        Next::Failed(e) => format!("{e}"),
        other => format!("{other:?}"),
    }
}

#[test]
fn a_stuck_switch_fails_after_the_bump() {
    struct Stuck;
    impl Endstops for Stuck {
        fn triggered(&mut self, _: Axis) -> bool {
            true
        }
    }
    let mut h = Homing::new(0b001, &HomingConfig::ENDER3, &CFG);
    let _raise = h.next_step();
    h.finished(MoveEnd::Completed { switch: false });
    assert!(matches!(h.next_step(), Next::Move(m) if m.stop_at_switch));
    h.finished(MoveEnd::Triggered);
    assert!(matches!(h.next_step(), Next::Move(m) if m.distance_mm == 5.0));
    h.finished(MoveEnd::Completed {
        switch: Stuck.triggered(Axis::X),
    });
    assert_eq!(
        h.next_step(),
        Next::Failed(HomingError::SwitchStuck { axis: Axis::X })
    );
}

/// M112 (or kill, quick stop) during the long Z approach: homing stops at once and reports.
#[test]
fn abort_stops_at_once() {
    let mut w = world([Some(0), Some(0), None]);
    let (moves, end, _) = run(&mut w, 0b100, Some(1000));
    assert_eq!(end, Next::Failed(HomingError::Aborted));
    assert_eq!(moves.len(), 1);
    assert_eq!(w.phys[2], 400 - 1000);
    // Later calls keep reporting the failure, no new move.
    let mut h = Homing::new(0, &HomingConfig::ENDER3, &CFG);
    h.abort();
    assert_eq!(h.next_step(), Next::Failed(HomingError::Aborted));
    assert_eq!(h.next_step(), Next::Failed(HomingError::Aborted));
}

/// A next() without finished() returns the running move again (the executive may ask twice).
#[test]
fn next_is_idempotent_while_a_move_runs() {
    let mut h = Homing::new(0b010, &HomingConfig::ENDER3, &CFG);
    let a = h.next_step();
    assert_eq!(h.next_step(), a);
    assert!(h.is_moving());
}

struct Pin(Option<bool>);

impl embedded_hal::digital::ErrorType for Pin {
    type Error = core::convert::Infallible;
}

impl InputPin for Pin {
    fn is_high(&mut self) -> Result<bool, Self::Error> {
        Ok(self.0 == Some(true))
    }
    fn is_low(&mut self) -> Result<bool, Self::Error> {
        Ok(self.0 == Some(false))
    }
}

#[test]
fn pins_and_the_m119_report() {
    let mut e = PinEndstops {
        x: Pin(Some(true)),
        y: Pin(Some(false)),
        z: Pin(Some(false)),
        pressed_high: 0b111,
    };
    assert_eq!(
        m119_lines(&mut e),
        [
            "Reporting endstop status",
            "x_min: TRIGGERED",
            "y_min: open",
            "z_min: open"
        ]
    );
    e.pressed_high = 0;
    assert_eq!(
        m119_lines(&mut e)[1..],
        ["x_min: open", "y_min: TRIGGERED", "z_min: TRIGGERED"]
    );
    assert!(!e.triggered(Axis::E));
}
