//! A pause that meets the start code's homing (`G28`), `M400` and heater waits: nothing lost
//! or duplicated, in `layer` and `now` mode (issue 32's reproducer: a `G28`, an `M400` and a
//! few moves, a `now` pause during the homing gave `duplicated_moves: 1`).
//!
//! Two checks that do not share their bookkeeping:
//! - the sim's own figures (`lost_moves`, `duplicated_moves`), as `sim run` computes them —
//!   the comparison streamed as the runs go (that streamed comparison keyed the homing moves by
//!   whatever job line its sequence map held last when it read them, and so counted one move
//!   of the run with the pause as lost and another as duplicated);
//! - the positions: the job moves' end points of the run with the pause, in order, are the
//!   reference run's, plus at most the point where a `now` pause stopped mid-move — read from
//!   the executed records (steps), not from any job line numbering.
//!
//! Cost: 2 modes × 9 request times × 2 runs of a 15-line job on virtual time: < 1 s.

use sim::exec::PrinterFactory;
use sim::port::Lane;
use sim::run::{self, Mode, PauseWhen, Policy, Scenario};

/// The reproducer: moves before and after the homing, an M400 after it and one more later.
const JOB: &str = "G90
M83
G1 Z5 F600
G1 X30 Y30 F3000
G28
M400
G1 Z0.2 F600
G1 X10 Y10 F3000
G1 X50 Y10 E2 F1500
G1 X50 Y50 E2
G1 X10 Y50 E2
G1 X10 Y10 E2
M400
G1 X20 Y20 F3000
M84";

/// The same with the heat-up an unmodified start code has (`M190`/`M109` waits) around it.
const HEATED: &str = "M140 S60
M104 S200
G90
M83
G28
M400
M190 S60
M109 S200
G1 Z0.2 F600
G1 X10 Y10 F3000
G1 X50 Y10 E2 F1500
G1 X50 Y50 E2
G1 X10 Y50 E2
G1 X10 Y10 E2
M104 S0";

fn scenario(mode: Mode, at_s: f64, keep_records: bool, cold: bool) -> Scenario {
    let mut sc = Scenario::new(Policy::Firmware, mode);
    sc.allow_cold = cold;
    sc.keep_records = keep_records;
    sc.pause = Some(PauseWhen::AtUs((at_s * 1e6) as u64));
    sc.resume_after_us = Some(2_000_000);
    sc
}

/// End points of the job-lane records, consecutive repeats collapsed.
fn job_ends(recs: &[sim::recorder::SegRecord]) -> Vec<[i32; 4]> {
    let mut out: Vec<[i32; 4]> = Vec::new();
    for r in recs.iter().filter(|r| r.tag.lane == Lane::Job) {
        if out.last() != Some(&r.end) {
            out.push(r.end);
        }
    }
    out
}

fn check(job: &str, cold: bool, times: &[f64]) {
    let lines: Vec<String> = job.lines().map(str::to_string).collect();
    for mode in [Mode::Now, Mode::Layer] {
        for &t in times {
            let tag = format!("{mode:?} pause at {t} s");
            // As `sim run` computes its figures (streamed comparison).
            let o = run::run(&PrinterFactory, &scenario(mode, t, false, cold), &lines)
                .unwrap_or_else(|e| panic!("{tag}: {e:#}"));
            let r = &o.report;
            assert_eq!(
                (
                    r.lost_moves,
                    r.duplicated_moves,
                    r.lost_segments,
                    r.duplicated_segments
                ),
                (0, 0, 0, 0),
                "{tag}: streamed figures"
            );
            assert!(r.finished && o.reference_finished, "{tag}: not finished");
            // Records kept: the figures again, and the positions.
            let o = run::run(&PrinterFactory, &scenario(mode, t, true, cold), &lines)
                .unwrap_or_else(|e| panic!("{tag}: {e:#}"));
            let r = &o.report;
            assert_eq!(
                (r.lost_moves, r.duplicated_moves),
                (0, 0),
                "{tag}: kept figures"
            );
            let a = job_ends(&o.run.rec.records);
            let b = job_ends(&o.reference.rec.records);
            let extra: Vec<_> = a.iter().filter(|p| !b.contains(p)).collect();
            assert!(
                extra.len() <= 1 && extra.iter().all(|p| Some(**p) == r.pause_point_steps),
                "{tag}: job moves ending elsewhere than the reference's: {extra:?}"
            );
            let a_only_ref: Vec<_> = a.into_iter().filter(|p| b.contains(p)).collect();
            assert_eq!(
                a_only_ref, b,
                "{tag}: job move end points differ from the reference"
            );
        }
    }
}

/// Requests before, during and after the homing, at the M400 and in the moves after it.
#[test]
fn a_pause_across_homing_and_m400_loses_and_duplicates_nothing() {
    check(JOB, true, &[0.0, 0.5, 1.0, 2.0, 3.0, 3.5, 4.0, 5.0, 6.0]);
}

/// Requests during the heater waits of a start code (M190/M109 after G28 and M400).
#[test]
fn a_pause_during_the_heat_up_loses_and_duplicates_nothing() {
    check(HEATED, false, &[0.5, 5.0, 30.0, 60.0, 100.0, 130.0]);
}
