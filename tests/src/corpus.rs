//! The layer corpus' grid: layer pauses at fixed-seed random request times and `M761 L<n>`
//! schedules on a job, each judged by the independent reference ([`crate::judge`], built on
//! `layerref`) and by the sim's own verdict (`sim::run::layer_verdict`).

use crate::judge::{judge_request, judge_schedule, Job, Outcome};
use sim::exec::PrinterFactory;
use sim::run::{self, PauseWhen};

/// A small fixed-seed generator (xorshift64*): request times and schedules.
pub struct Rng(pub u64);
impl Rng {
    /// The next number in [0, 1).
    pub fn unit(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Printing window (first extruding XY move, end) of a run without a pause: requests fall
/// after the start code's homing and heat-up (a request during the heat-up stops only after
/// it, beyond the minute each run is simulated for after its request).
pub fn window(job: &Job) -> (f64, f64) {
    let o = run::run(&PrinterFactory, &job.scenario(), &job.lines).expect("reference run");
    // Without a pause the run is its own reference (`o.reference` is never stepped).
    let first_xy = o
        .run
        .rec
        .records
        .iter()
        .find(|r| (r.start[0] != r.end[0] || r.start[1] != r.end[1]) && r.end[3] > r.start[3])
        .map_or(0, |r| r.t_start_us);
    (first_xy as f64 * 1e-6, o.report.print_time_unpaused_s)
}

/// Judge `job` (named `name` in failures) with `requests` `layer` pauses at random times in
/// its printing window and `schedules` `M761 L<n>` for random layers n ≥ 2: each by the
/// independent reference (`crate::judge`) and by the sim's own verdict. Returns (right,
/// total, failures).
pub fn check_job(
    name: &str,
    job: &Job,
    requests: usize,
    schedules: usize,
    rng: &mut Rng,
) -> (usize, usize, Vec<String>) {
    let comments = job.comments;
    let mut failures = Vec::new();
    let mut right = 0;
    let (t0, t1) = window(job);
    for _ in 0..requests {
        let at = t0 + (t1 - t0) * rng.unit() * 0.97;
        let t_req = (at * 1e6) as u64;
        let mut sc = job.scenario();
        sc.pause = Some(PauseWhen::AtUs(t_req));
        sc.resume_after_us = Some(200_000);
        // The verdict needs the stop and the first move after the resume (stopping, parking,
        // returning: `Job::after_request_us`), the rest of the job is not simulated (nothing
        // lost or duplicated is the property tests' business).
        sc.max_time_us = t_req + job.after_request_us;
        let tag = format!("{name} {comments:?} request at {at:.3} s");
        let ok = judged(job, &sc, &tag, &mut failures, |o| {
            judge_request(o, t_req, job)
        });
        right += usize::from(ok);
    }
    let numbered: Vec<u32> = job
        .model
        .layers()
        .iter()
        .map(|l| l.number)
        .filter(|&n| n > 0)
        .collect();
    for _ in 0..schedules {
        let Some(&n) = numbered.get(1 + (rng.unit() * (numbered.len() - 1) as f64) as usize) else {
            continue;
        };
        let mut sc = job.scenario();
        sc.pause = Some(PauseWhen::AtLayer(n));
        sc.resume_after_us = Some(200_000);
        let tag = format!("{name} {comments:?} M761 L{n}");
        let ok = judged(job, &sc, &tag, &mut failures, |o| judge_schedule(o, n, job));
        right += usize::from(ok);
    }
    (right, requests + schedules, failures)
}

/// One run of `job` under `sc`, judged by `judge` (the independent reference) and by the sim's
/// own verdict; what fails goes to `failures`, named `tag`. Whether both held.
fn judged(
    job: &Job,
    sc: &run::Scenario,
    tag: &str,
    failures: &mut Vec<String>,
    judge: impl FnOnce(&Outcome) -> Result<(), String>,
) -> bool {
    let o = match run::run(&PrinterFactory, sc, &job.lines) {
        Ok(o) => o,
        Err(e) => {
            failures.push(format!("{tag}: run failed: {e:#}"));
            return false;
        }
    };
    let mut ok = true;
    if let Err(e) = judge(&o) {
        failures.push(format!("{tag}: {e}"));
        ok = false;
    }
    if let Some(why) = run::layer_verdict(sc, &o) {
        failures.push(format!(
            "{tag}: the sim's verdict: {why} ({} lines refused, first {:?})",
            o.refused.count,
            o.refused.first.first().map(|r| &r.reply)
        ));
        ok = false;
    }
    ok
}
