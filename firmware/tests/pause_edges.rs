//! Edge cases of pause and resume, each with its defined answer (see docs/planner.md).
mod support;

use firmware::config::MachineConfig;
use firmware::motion::{MoveRequest, PauseMode, Realtime};
use firmware::planner::BlockKind;
use firmware::printer::{Command, PausedLines, Policy, Printer, Record, Schedule, State};
use firmware::thermal::HeaterId;
use support::*;

/// Square perimeters to (60.0, 60.0) mm, 2.0 mm of filament a side, 0.2 mm layers.
fn job(layers: u32) -> Vec<Item> {
    square_layers(layers, 60.0, 2.0)
}

fn req(t_us: u64, req: Realtime) -> Req {
    Req { t_us, req }
}

const LAYER: Realtime = Realtime::Pause(PauseMode::Layer);
const NOW: Realtime = Realtime::Pause(PauseMode::Now);

fn stops(r: &Run) -> usize {
    r.records
        .iter()
        .filter(|x| matches!(x, Record::Stopped { .. }))
        .count()
}

fn cmds3() -> Vec<Command> {
    commands(&MachineConfig::ENDER3, &job(3))
}

fn base() -> Run {
    run(&mut printer(), &cmds3(), &[], 120_000_000)
}

#[test]
fn pause_while_pausing_upgrades_to_now_or_is_ignored() {
    let r = run(
        &mut printer(),
        &cmds3(),
        &[
            req(500_000, LAYER),
            req(510_000, LAYER),
            req(600_000, NOW),
            req(20_000_000, Realtime::Resume),
        ],
        120_000_000,
    );
    assert!(r.out.contains("pause already in progress"), "{}", r.out);
    assert!(r.records.iter().any(|x| matches!(x, Record::Brake { .. })));
    let stop = r.records.iter().find_map(|x| match *x {
        Record::Stopped { mid_block, .. } => Some(mid_block),
        _ => None,
    });
    assert_eq!(stop, Some(true), "the now request stopped mid-layer");
    assert_eq!(stops(&r), 1);
    assert_eq!(r.executed, base().executed);
    assert_eq!(r.end, base().end);
}

#[test]
fn pause_while_paused_and_resume_while_running() {
    let r = run(
        &mut printer(),
        &cmds3(),
        &[
            req(200_000, Realtime::Resume),
            req(500_000, NOW),
            req(10_000_000, NOW),
            req(10_000_000, LAYER),
            req(20_000_000, Realtime::Resume),
        ],
        120_000_000,
    );
    assert!(r.out.contains("not paused"), "{}", r.out);
    assert!(r.out.contains("already paused"), "{}", r.out);
    assert_eq!(stops(&r), 1);
    assert_eq!(r.executed, base().executed);
}

#[test]
fn pause_during_homing_waits_for_the_homing_move() {
    let cfg = MachineConfig::ENDER3;
    let mut cmds = vec![
        Command::Move(MoveRequest {
            target: [8000, 8000, 0, 0],
            feed_mm_s: 100.0,
            seq: 100,
        }),
        Command::Move(MoveRequest {
            target: [8000, 8000, 4000, 0],
            feed_mm_s: 5.0,
            seq: 101,
        }),
    ];
    cmds.push(Command::Home { mask: 0b111 });
    cmds.extend(commands(&cfg, &job(1)));
    // Find when the homing move runs in a run without a pause, and ask for a pause in it.
    let b = run(&mut printer(), &cmds, &[], 60_000_000);
    let i = b
        .records
        .iter()
        .position(|x| {
            matches!(
                x,
                Record::Executed {
                    kind: BlockKind::Homing,
                    ..
                }
            )
        })
        .unwrap();
    let t_of = |x: &Record| match *x {
        Record::Executed { t_us, .. } => t_us,
        _ => 0,
    };
    let end = t_of(&b.records[i]);
    let start = b.records[..i]
        .iter()
        .rev()
        .map(t_of)
        .find(|&t| t > 0)
        .unwrap();
    assert!(end > start + 200_000);
    let mut p = printer();
    let r = run(&mut p, &cmds, &[req((start + end) / 2, NOW)], 60_000_000);
    let homed_at = r.records.iter().position(|x| {
        matches!(
            x,
            Record::Executed {
                kind: BlockKind::Homing,
                ..
            }
        )
    });
    let stop_at = r
        .records
        .iter()
        .position(|x| matches!(x, Record::Stopped { .. }));
    let brake_at = r
        .records
        .iter()
        .position(|x| matches!(x, Record::Brake { .. }));
    assert!(homed_at.is_some() && stop_at.is_some(), "{:?}", r.records);
    assert!(brake_at > homed_at, "the hold waited for homing to finish");
    assert!(stop_at > homed_at);
    assert_eq!(p.status().state, State::Paused);
}

#[test]
fn pause_during_heater_wait_parks_and_the_wait_continues() {
    let cfg = MachineConfig::ENDER3;
    let mut p = printer();
    p.thermal_mut().set_target(HeaterId::Hotend, 200.0).unwrap();
    let mut cmds = commands(&cfg, &[Item::Move([10.0, 10.0, 0.2, 0.0], 30.0)]);
    cmds.push(Command::WaitHeater(HeaterId::Hotend));
    cmds.extend(
        commands(&cfg, &job(1))
            .into_iter()
            .skip(1)
            .map(|c| match c {
                Command::Move(mut m) => {
                    m.seq += 10;
                    Command::Move(m)
                }
                c => c,
            }),
    );
    // The wait never ends by itself (no temperature samples): a now request parks.
    let r = run(&mut p, &cmds, &[req(3_000_000, NOW)], 15_000_000);
    assert_eq!(p.status().state, State::Paused);
    assert!(r.out.contains("busy: processing"), "{}", r.out);
    let before: Vec<u32> = r.executed.iter().map(|e| e.0).collect();
    assert!(
        before.iter().all(|&s| s == 1),
        "only the move before the wait ran"
    );
    // Resume: back at the wait; M108 breaks it and the job runs to the end.
    p.request(Realtime::Resume, 16_000_000);
    let r2 = run(
        &mut p,
        &[],
        &[req(30_000_000, Realtime::BreakWait)],
        90_000_000,
    );
    assert!(
        r2.executed.iter().all(|e| e.0 > 10),
        "the job continued after the wait"
    );
    assert!(!r2.executed.is_empty());
    assert_eq!(p.status().state, State::Idle);
}

#[test]
fn layer_request_in_the_last_layer_stops_at_the_end_of_the_job() {
    let cfg = MachineConfig::ENDER3;
    let cmds = commands(&cfg, &job(1));
    let b = run(&mut printer(), &cmds, &[], 60_000_000);
    let mut p = printer();
    let r = run(&mut p, &cmds, &[req(1_000_000, LAYER)], 60_000_000);
    let stop = r.records.iter().find_map(|x| match *x {
        Record::Stopped { pos, mid_block, .. } => Some((pos, mid_block)),
        _ => None,
    });
    assert_eq!(stop, Some((b.end, false)));
    assert_eq!(p.status().state, State::Paused);
    assert_eq!(r.executed, b.executed);
}

#[test]
fn cancel_while_paused_drops_held_blocks_and_reports() {
    let mut p = printer();
    let r = run(
        &mut p,
        &cmds3(),
        &[req(1_000_000, NOW), req(8_000_000, Realtime::Cancel)],
        60_000_000,
    );
    assert!(r.out.contains("//action:cancel"), "{}", r.out);
    assert!(r.out.contains("cancelled: dropped"), "{}", r.out);
    assert_eq!(p.status().state, State::Cancelled);
    assert_eq!(p.status().queue_depth, 0);
    let b = base();
    assert!(r.executed.len() < b.executed.len());
    assert_eq!(r.executed[..], b.executed[..r.executed.len()]);
}

#[test]
fn emergency_stop_at_any_point_halts() {
    for t in [0u64, 300_000, 1_000_000, 5_000_000] {
        let mut p = printer();
        let r = run(
            &mut p,
            &cmds3(),
            &[req(t, NOW), req(t + 10_000, Realtime::EmergencyStop)],
            30_000_000,
        );
        assert_eq!(p.status().state, State::Halted);
        assert!(p.next_step_ns().is_none());
        assert!(
            r.out.contains("Error:Printer halted. kill() called!"),
            "{}",
            r.out
        );
        p.request(Realtime::Resume, 40_000_000);
        assert_eq!(p.status().state, State::Halted);
    }
}

#[test]
fn requests_during_the_pause_sequence_are_deferred() {
    // Resume while parking: the resume runs once parked.
    let mut p = printer();
    let r = run(
        &mut p,
        &cmds3(),
        &[req(1_000_000, NOW), req(1_250_000, Realtime::Resume)],
        120_000_000,
    );
    assert!(r.out.contains("resume deferred"), "{}", r.out);
    assert_eq!(r.executed, base().executed);
    assert_eq!(r.end, base().end);
    assert_eq!(p.status().state, State::Idle);
    // Pause while returning: a second pause follows the resume.
    let mut p = printer();
    let r = run(
        &mut p,
        &cmds3(),
        &[
            req(1_000_000, NOW),
            req(8_000_000, Realtime::Resume),
            req(8_100_000, NOW),
            req(20_000_000, Realtime::Resume),
        ],
        120_000_000,
    );
    assert!(r.out.contains("pause deferred"), "{}", r.out);
    assert_eq!(stops(&r), 2);
    assert_eq!(r.executed, base().executed);
    assert_eq!(r.end, base().end);
}

#[test]
fn scheduled_pause_stops_before_the_layer() {
    let cfg = MachineConfig::ENDER3;
    let mut cmds = vec![Command::SchedulePause(Schedule::Layer(2))];
    cmds.extend(commands(&cfg, &job(3)));
    let mut p = printer();
    let r = run(&mut p, &cmds, &[], 120_000_000);
    let stop = r.records.iter().find_map(|x| match *x {
        Record::Stopped {
            layer, mid_block, ..
        } => Some((layer, mid_block)),
        _ => None,
    });
    assert_eq!(stop, Some((Some(2), false)));
    assert_eq!(p.status().state, State::Paused);
    // Nothing of layer 2 ran: 2 layers × 5 moves.
    let seqs: std::collections::BTreeSet<u32> = r.executed.iter().map(|e| e.0).collect();
    assert_eq!(seqs.len(), 10);
}

#[test]
fn manual_moves_while_paused_do_not_disturb_the_job() {
    let mut p = Printer::with_policy(
        MachineConfig::ENDER3,
        Policy {
            paused_lines: PausedLines::Manual,
            ..Policy::FIRMWARE
        },
    );
    // No heater model: the job extrudes cold (as M302 P1; the guard judges at the planner).
    p.extrusion_guard_mut().allow_cold = true;
    let _ = run(&mut p, &cmds3(), &[req(1_000_000, NOW)], 8_000_000);
    assert_eq!(p.status().state, State::Paused);
    let held = p.status().paused_at.unwrap();
    // A jog and a purge while paused.
    let park = p.status().position;
    let jog = [park[0] - 800, park[1], park[2] + 400, park[3] + 930];
    p.push_command(
        Command::Move(MoveRequest {
            target: jog,
            feed_mm_s: 20.0,
            seq: 9999,
        }),
        8_000_000,
    )
    .unwrap();
    let j = run(&mut p, &[], &[], 12_000_000);
    assert_eq!(j.end, jog);
    assert_eq!(p.status().state, State::Paused);
    p.request(Realtime::Resume, 12_000_000);
    let r = run(&mut p, &[], &[], 120_000_000);
    let b = base();
    // The first position after the resume sequence is the held one; the job finishes the same.
    assert_eq!(r.end, b.end);
    assert!(r.trace.iter().any(|&(_, pos)| pos == held));
}

#[test]
fn scheduled_pause_met_by_a_pause_in_progress_is_not_repeated() {
    // The schedule asks for layer 1; the user's layer request (before layer 1 is queued)
    // stops at the same boundary. After the resume the job must not pause again at layer 2.
    let cfg = MachineConfig::ENDER3;
    let mut cmds = vec![Command::SchedulePause(Schedule::Layer(1))];
    cmds.extend(commands(&cfg, &job(3)));
    let mut p = printer();
    let r = run(
        &mut p,
        &cmds,
        &[req(500_000, LAYER), req(20_000_000, Realtime::Resume)],
        120_000_000,
    );
    let layers: Vec<Option<u32>> = r.stops().iter().map(|s| s.layer).collect();
    assert_eq!(layers, vec![Some(1)], "{}", r.out);
    assert!(r.out.contains("scheduled pause met"), "{}", r.out);
    assert_eq!(p.scheduled_pause(), None);
    assert_eq!(r.executed, base().executed);
}

#[test]
fn schedule_due_during_a_pause_stops_at_its_layer_after_the_resume() {
    // Short layers (8 mm, 40 segments, under the 64-block ring): the user's layer pause stops
    // before layer 1 and layer 2's mark enters the ring behind that barrier, so the schedule
    // (layer 2) comes due while the pause is in progress. After the resume the job must stop
    // before layer 2, not a layer later.
    let cfg = MachineConfig::ENDER3;
    let mut items = Vec::new();
    let mut e = 0.0;
    for l in 0..5u32 {
        items.push(Item::Layer(l));
        let z = 0.2 * (l + 1) as f32;
        for (x, y) in [(12.0, 10.0), (12.0, 12.0), (10.0, 12.0), (10.0, 10.0)] {
            e += 0.1;
            items.push(Item::Move([x, y, z, e], 5.0));
        }
    }
    let mut cmds = vec![Command::SchedulePause(Schedule::Layer(2))];
    cmds.extend(commands(&cfg, &items));
    let base = run(&mut printer(), &cmds, &[], 120_000_000);
    let mut p = printer();
    let r = run(
        &mut p,
        &cmds,
        &[req(300_000, LAYER), req(20_000_000, Realtime::Resume)],
        120_000_000,
    );
    let layers: Vec<Option<u32>> = r.stops().iter().map(|s| s.layer).collect();
    assert_eq!(layers, vec![Some(1), Some(2)], "{}", r.out);
    assert_eq!(p.status().state, State::Paused);
    // Up to the scheduled stop the run matches the unpaused one (which stopped there too).
    assert_eq!(r.executed, base.executed);
}

/// Issue 24's `executive` find (`finds/executive/marks-without-motion-f14bcec1`): more layer
/// markers in a row than the planner keeps marks (16), with no motion between them (empty
/// layers, a file of only markers). The 17th waited for room only a block behind it could
/// make, and every later line (the host's M400 too) waited for ever. Consecutive marks with no
/// block between them stand at one place: the newer replaces the older. The M400 is answered,
/// the move after them runs, and the printer reports the last marker's layer.
#[test]
fn layer_markers_without_motion_between_never_wedge_the_queue() {
    let mut p = Printer::new(MachineConfig::ENDER3);
    let mut lines: Vec<String> = vec!["G28".into(), "G1 X10 Y10 Z0.2 F3000".into()];
    for n in 1..=50 {
        lines.push(format!(";LAYER:{n}"));
    }
    lines.push("M400".into());
    lines.push("G1 X50 Y50 F3000".into());
    lines.push("M400".into());
    lines.push("M114".into());
    let refs: Vec<&str> = lines.iter().map(String::as_str).collect();
    let r = run_gcode(&mut p, &refs, &[], 60_000_000);
    let oks = r.out.lines().filter(|l| l.starts_with("ok")).count();
    assert_eq!(oks, lines.len(), "{}", r.out);
    assert!(r.out.contains("X:50.00 Y:50.00"), "{}", r.out);
    assert_eq!(p.status().layer, Some(50), "{}", r.out);
}
