//! Every pause completes: a feed hold whose brake ends at (or runs up to) the last queued
//! point reaches Paused, announces `//action:paused`, and an M400 behind it gets its `ok`
//! (issue 14 item 7). Swept over request times and both policies.
mod support;

use firmware::config::MachineConfig;
use firmware::motion::{PauseMode, Realtime};
use firmware::printer::{Policy, Printer, State};
use support::*;

/// `lines` then M400, paused at `t_us`, resumed 5 s later.
fn job(lines: &[&str], policy: Policy, mode: PauseMode, t_us: u64) -> Run {
    let mut p = Printer::with_policy(MachineConfig::ENDER3, policy);
    let mut all = lines.to_vec();
    all.push("M400");
    run_gcode(
        &mut p,
        &all,
        &[(t_us, pause_line(mode)), (t_us + 5_000_000, "M602\n")],
        30_000_000,
    )
}

fn pause_line(mode: PauseMode) -> &'static str {
    match mode {
        PauseMode::Layer => "M601\n",
        PauseMode::Now => "M601 S1\n",
    }
}

#[test]
fn a_feed_hold_at_the_end_of_the_queued_motion_reaches_paused() {
    for policy in [Policy::FIRMWARE, Policy::FIFO] {
        for mode in [PauseMode::Now, PauseMode::Layer] {
            // `G1 X100 F7800` (130 mm/s: long ramps) takes about 1.03 s: requests through
            // the cruise, the deceleration and its very end.
            for t_ms in (100..=1040).step_by(20) {
                let r = job(&["G1 X100 F7800"], policy, mode, t_ms * 1000);
                let paused = r.out.matches("//action:paused").count();
                let resumed = r.out.matches("//action:resumed").count();
                let msg = format!("{policy:?} {mode:?} at {t_ms} ms:\n{}", r.out);
                // The request may come after the move ended (then "nothing to pause");
                // otherwise it must complete.
                if r.out.contains("nothing to pause") {
                    assert_eq!(paused, 0, "{msg}");
                } else {
                    assert_eq!(paused, 1, "never paused: {msg}");
                    assert_eq!(resumed, 1, "{msg}");
                }
                assert!(
                    !r.out.contains(
                        "busy: processing\nbusy: processing\nbusy: processing\nbusy: processing"
                    ),
                    "M400 waited for ever: {msg}"
                );
                let oks = r.out.lines().filter(|l| l.starts_with("ok")).count();
                // G1, M400, the pause and the resume lines.
                assert_eq!(oks, 4, "{msg}");
                let x = r.end[0];
                assert_eq!(
                    x,
                    (100.0 * MachineConfig::ENDER3.axes[0].steps_per_mm) as i32
                );
            }
        }
    }
}

/// Two moves that join at speed: a feed hold in the first one (firmware: brakes through into
/// the second; fifo: stops at the tail) must still reach Paused, and the job ends where it
/// would without the pause.
#[test]
fn a_pause_over_moves_joined_at_speed_completes_in_both_policies() {
    for policy in [Policy::FIRMWARE, Policy::FIFO] {
        for mode in [PauseMode::Now, PauseMode::Layer] {
            for t_ms in (100..=1400).step_by(50) {
                let r = job(
                    &["G1 X100 F7800", "G1 X150 Y20 F7800"],
                    policy,
                    mode,
                    t_ms * 1000,
                );
                let msg = format!("{policy:?} {mode:?} at {t_ms} ms:\n{}", r.out);
                if !r.out.contains("nothing to pause") {
                    assert_eq!(r.out.matches("//action:paused").count(), 1, "{msg}");
                    assert_eq!(r.out.matches("//action:resumed").count(), 1, "{msg}");
                }
                let oks = r.out.lines().filter(|l| l.starts_with("ok")).count();
                assert_eq!(oks, 5, "{msg}");
                let spm = MachineConfig::ENDER3.axes[0].steps_per_mm;
                assert_eq!(r.end[0], (150.0 * spm) as i32, "{msg}");
                let _ = (Realtime::Resume, State::Idle);
            }
        }
    }
}
