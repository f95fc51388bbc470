//! Driving the engines of a run: a trial run to time a job line, lock-step of A and B up to
//! the first change of motion, waiting for the park, and A and B in turns to the end.

use super::{Factory, Policy, Scenario};
use crate::engine::{Engine, Stop};
use crate::hostlink::{Host, Origin};
use crate::job::JobLines;
use crate::port::{Executive, State};
use crate::stream::{self, Compare, LineEnds, Side};

pub(super) fn new_engine<F: Factory>(f: &F, sc: &Scenario, job: JobLines) -> Engine<F::Exec> {
    let fw = f.make(&sc.machine, &sc.knobs());
    let host = Host::new(sc.link.clone(), job);
    Engine::new(fw, host)
}

/// Time at `fraction` of the execution of the sent lines `lines` (the pieces of one original
/// line), from a trial run.
pub(super) fn line_time<F: Factory>(
    f: &F,
    sc: &Scenario,
    job: &JobLines,
    lines: std::ops::RangeInclusive<usize>,
    fraction: f64,
) -> Option<u64> {
    let mut e = new_engine(f, sc, job.clone());
    let mut t0 = None;
    loop {
        match e.advance(sc.max_time_us, true) {
            Stop::Step(ev) => {
                let here = matches!(
                    e.origin_of_seq(ev.seq),
                    Some(Origin::Job(l)) if lines.contains(&l)
                );
                match (t0, here) {
                    (None, true) => t0 = Some(ev.t_us),
                    (Some(t), false) => {
                        let d = ev.t_us.saturating_sub(t) as f64;
                        return Some(t + (d * fraction.clamp(0.0, 1.0)) as u64);
                    }
                    _ => {}
                }
            }
            _ => return t0,
        }
    }
}

/// Virtual time A runs before B catches up and their records are compared, µs.
pub(super) const STREAM_CHUNK_US: u64 = 2_000_000;

/// Index of A's first job record after its first service record (printing again after the
/// pause), if any.
pub(super) fn first_job_after_service<E: Executive>(a: &Engine<E>) -> Option<usize> {
    let recs = &a.rec.records;
    let s = recs.iter().position(|r| stream::key_of(a, r).is_none())?;
    (s..recs.len()).find(|&i| stream::key_of(a, &recs[i]).is_some())
}

/// Run A and B to the end in turns (B catching up with A's number of executed blocks after
/// each chunk of A), comparing their records as they complete. Returns whether each finished.
/// `a_stays`: A is not run further (a pause that is never resumed).
pub(super) fn run_in_turns<E: Executive>(
    a: &mut Engine<E>,
    b: &mut Engine<E>,
    max_us: u64,
    a_stays: bool,
    cmp: &mut Compare,
    ends: &mut LineEnds,
) -> (bool, bool) {
    // None while running; Some(finished) once it finished, stalled or ran out of time.
    let mut a_end: Option<bool> = a_stays.then_some(false);
    let mut b_end: Option<bool> = None;
    let step = |e: &mut Engine<E>| -> Option<bool> {
        let deadline = (e.now_us + STREAM_CHUNK_US).min(max_us);
        match e.advance(deadline, false) {
            Stop::Finished => Some(true),
            Stop::Stalled => Some(false),
            _ if e.now_us >= max_us => Some(false),
            _ => None,
        }
    };
    loop {
        if a_end.is_none() {
            a_end = step(a);
            stream::feed(a, Side::A, a_end.is_some(), cmp, ends);
        }
        while b_end.is_none() && (a_end.is_some() || cmp.fed_b <= cmp.fed_a) {
            b_end = step(b);
            stream::feed(b, Side::B, b_end.is_some(), cmp, ends);
        }
        if let (Some(x), Some(y)) = (a_end, b_end) {
            return (x, y);
        }
    }
}

/// Step A and B together from the request on; the time of the first step that differs.
pub(super) fn lockstep<E: Executive>(
    a: &mut Engine<E>,
    b: &mut Engine<E>,
    _t_req: u64,
    max_us: u64,
) -> Option<u64> {
    loop {
        match b.advance(max_us, true) {
            Stop::Step(eb) => match a.advance(eb.t_us, true) {
                Stop::Step(ea) => {
                    if !crate::port::same_motion(&ea, &eb) {
                        return Some(ea.t_us.min(eb.t_us));
                    }
                }
                // A did not step when B did: A has braked or stopped.
                _ => return Some(eb.t_us),
            },
            _ => {
                // The reference has no more steps: any further step of A differs.
                return match a.advance(max_us, true) {
                    Stop::Step(ea) => Some(ea.t_us),
                    _ => None,
                };
            }
        }
    }
}

/// Advance until the printer is parked; the time of the last parking step.
pub(super) fn wait_parked<E: Executive>(a: &mut Engine<E>, sc: &Scenario) -> Option<u64> {
    let slice = 20_000;
    loop {
        let st = a.fw.status().state;
        let idle_motion = a.fw.next_step_us(a.now_us).is_none();
        let parked = match sc.policy {
            Policy::Fifo | Policy::Firmware => st == State::Paused && idle_motion,
            Policy::HostSplit => {
                a.host.holding()
                    && a.host.inserts_done()
                    && idle_motion
                    && a.host.tx.is_idle()
                    && a.fw.status().queue_depth == 0
            }
        };
        if parked {
            return Some(a.rec.last_step_us);
        }
        if a.now_us >= sc.max_time_us {
            return None;
        }
        if matches!(
            a.advance(a.now_us + slice, false),
            Stop::Finished | Stop::Stalled
        ) {
            return None;
        }
    }
}
