//! Pause and resume through the Printer on virtual time: layer and now modes, edge cases.
mod support;

use firmware::config::MachineConfig;
use firmware::motion::{PauseMode, Realtime};
use firmware::printer::Record;
use support::*;

/// Square perimeters to (40.0, 40.0) mm, 1.2 mm of filament a side, 0.2 mm layers.
fn job(layers: u32) -> Vec<Item> {
    square_layers(layers, 40.0, 1.2)
}

fn stopped(r: &Run) -> Option<(firmware::motion::StepPos, Option<u32>, bool, u64)> {
    r.records.iter().find_map(|x| match *x {
        Record::Stopped {
            pos,
            layer,
            mid_block,
            t_us,
        } => Some((pos, layer, mid_block, t_us)),
        _ => None,
    })
}

#[test]
fn layer_pause_stops_at_boundary_and_resumes_exactly() {
    let cfg = MachineConfig::ENDER3;
    let cmds = commands(&cfg, &job(3));
    let base = run(&mut printer(), &cmds, &[], 60_000_000);
    let mut p = printer();
    let reqs = [
        Req {
            t_us: 1_000_000,
            req: Realtime::Pause(PauseMode::Layer),
        },
        Req {
            t_us: 20_000_000,
            req: Realtime::Resume,
        },
    ];
    let r = run(&mut p, &cmds, &reqs, 60_000_000);
    assert_eq!(r.executed, base.executed, "same segments, once, in order");
    assert_eq!(r.end, base.end);
    let (pos, layer, mid, _) = stopped(&r).expect("stopped");
    assert!(!mid);
    assert_eq!(layer, Some(1));
    // The stop is at the end of layer 0: the last block of layer 0 ends at pos.
    let first_l1 = cmds
        .iter()
        .position(|c| matches!(c, firmware::printer::Command::Layer(m) if m.layer == 1))
        .unwrap();
    let last_seq_l0 = cmds[..first_l1]
        .iter()
        .filter(|c| matches!(c, firmware::printer::Command::Move(_)))
        .count() as u32;
    let idx = r
        .executed
        .iter()
        .rposition(|&(s, _)| s == last_seq_l0)
        .unwrap();
    assert_eq!(r.job_pos[idx], pos);
    assert!(r.out.contains("//action:paused"), "{}", r.out);
    assert!(r.out.contains("//action:resumed"), "{}", r.out);
    // Speed-up made layer 0 finish sooner than without the pause.
    assert!(r
        .records
        .iter()
        .any(|x| matches!(x, Record::SpeedUp { .. })));
}

#[test]
fn now_pause_brakes_within_braking_distance() {
    let cfg = MachineConfig::ENDER3;
    let cmds = commands(&cfg, &[Item::Move([200.0, 0.0, 0.0, 0.0], 100.0)]);
    let base = run(&mut printer(), &cmds, &[], 60_000_000);
    let reqs = [
        Req {
            t_us: 1_000_000,
            req: Realtime::Pause(PauseMode::Now),
        },
        Req {
            t_us: 10_000_000,
            req: Realtime::Resume,
        },
    ];
    let mut p = printer();
    let r = run(&mut p, &cmds, &reqs, 60_000_000);
    assert_eq!(r.executed, base.executed);
    assert_eq!(r.end, base.end);
    let (pos, _, mid, t_stop) = stopped(&r).expect("stopped");
    assert!(mid);
    let (v, a) = r.brake().unwrap();
    // Position at request time.
    let at_req = r
        .trace
        .iter()
        .take_while(|(t, _)| *t <= 1_000_000_000)
        .last()
        .unwrap()
        .1;
    let travel_mm = (pos[0] - at_req[0]) as f32 / 80.0;
    let bound = v * v / (2.0 * a) + 1.0 / 80.0;
    assert!(travel_mm <= bound, "travel {travel_mm} > {bound}");
    assert!(t_stop < 1_300_000, "stopped at {t_stop}");
}
