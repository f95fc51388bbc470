//! One simulated print with (optionally) one pause: the policy set-up, the pause request, the
//! resume, and the reference run the pause is measured against.
//!
//! Every run is made twice on the same configuration: the run with the pause (A) and the same
//! run without it (B, the reference). Both are deterministic and identical up to the request;
//! from the request on they are stepped in lock-step and the first step that differs (in time,
//! axis or direction) is the **reaction**: the first change of motion the request caused,
//! whether a speed-up (steps come earlier) or braking (steps come later). The executed blocks of
//! A and B are then compared for lost and duplicated moves and the resume position.
//!
//! Submodules: `scenario` (what defines a run), `drive` (stepping the engines: trial run,
//! lock-step, park wait, the rest in turns).

mod drive;
mod scenario;

pub use scenario::{Mode, PauseWhen, Policy, Scenario};

use crate::engine::{Engine, Stop};
use crate::hostlink::Host;
use crate::job::{JobInfo, JobLines};
use crate::metrics::{self, PauseReport, RunFacts, RunView};
use crate::port::{Executive, FirmwareKnobs, RunState};
use crate::split;
use crate::stream::{self, Compare, LineEnds, Side};
use drive::{
    first_job_after_service, line_time, lockstep, new_engine, run_in_turns, wait_parked,
    STREAM_CHUNK_US,
};
use firmware::config::MachineConfig;

/// Builds executives: the seam to `firmware::printer::Printer` (see [`crate::exec`]).
pub trait Factory {
    /// The executive type.
    type Exec: Executive;
    /// A fresh executive for this machine and these knobs.
    fn make(&self, machine: &MachineConfig, knobs: &FirmwareKnobs) -> Self::Exec;
}

/// A moment worth telling in a timeline.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct TimelineEvent {
    /// Virtual time, s.
    pub t_s: f64,
    /// What happened.
    pub what: String,
}

/// The outcome of one run.
pub struct Outcome<E: Executive> {
    /// The measured pause (and print) figures.
    pub report: PauseReport,
    /// The run with the pause.
    pub run: Engine<E>,
    /// The reference run.
    pub reference: Engine<E>,
    /// The job as the host sent it (split for host-split).
    pub job: JobLines,
    /// Timeline of the run.
    pub timeline: Vec<TimelineEvent>,
    /// The reference run reached the end of the job.
    pub reference_finished: bool,
}

/// Make a job ready for a policy: host-split pre-splits it. Returns the lines to send and,
/// for each, the line of the original job it came from (`None`: the job is sent as it is, line
/// for line).
pub fn prepare_job(
    policy: Policy,
    job: &JobLines,
    split_mm: f64,
) -> (JobLines, Option<Vec<usize>>) {
    match policy {
        Policy::HostSplit => {
            let s = split::split_job(&job.to_vec(), split_mm);
            (JobLines::from_lines(&s.lines), Some(s.source))
        }
        _ => (job.clone(), None),
    }
}

/// The request as the host writes it on the link.
pub fn request_text(mode: Mode) -> &'static str {
    match mode {
        Mode::Layer => "M25",
        Mode::Now => "M25 S1",
    }
}

/// Run `job` under the scenario and measure the pause.
pub fn run<F: Factory>(
    f: &F,
    sc: &Scenario,
    job_lines: &[String],
) -> anyhow::Result<Outcome<F::Exec>> {
    run_job(f, sc, JobLines::from_lines(job_lines))
}

/// [`run`] of a job already in a [`JobLines`] (`sim run`: one buffer for the file, shared by
/// both runs).
pub fn run_job<F: Factory>(
    f: &F,
    sc: &Scenario,
    job_lines: JobLines,
) -> anyhow::Result<Outcome<F::Exec>> {
    let wall = std::time::Instant::now();
    let (job, source) = prepare_job(sc.policy, &job_lines, sc.split_mm);
    drop(job_lines);
    // The host's view of the job (layers, states) is only read around a pause.
    let info = if sc.pause.is_some() && sc.policy == Policy::HostSplit {
        // Host-split writes its pause and resume sequences from the host state at each line.
        JobInfo::parse_job(&job)
    } else if sc.pause.is_some() {
        JobInfo::parse_layers(&job)
    } else {
        JobInfo::default()
    };
    let mut a = new_engine(f, sc, job.clone());
    a.rec.keep_records = sc.keep_records || sc.pause.is_some();
    // With a pause and no caller asking for the records, compare A and B as they run.
    let streaming = sc.pause.is_some() && !sc.keep_records;
    a.rec.stream = streaming;
    // Without a pause the reference is the run itself and is never stepped.
    let mut b = new_engine(
        f,
        sc,
        if sc.pause.is_some() {
            job.clone()
        } else {
            JobLines::default()
        },
    );
    b.rec.stream = streaming;
    let mut cmp = Compare::default();
    let mut ends = LineEnds::default();
    let mut timeline = Vec::new();
    let mut note = |t_us: u64, what: String| {
        timeline.push(TimelineEvent {
            t_s: t_us as f64 * 1e-6,
            what,
        })
    };

    let mut host_pause_state = None;
    // When is the request made?
    let t_req: Option<u64> = match sc.pause {
        None => None,
        Some(PauseWhen::AtUs(t)) => Some(t),
        Some(PauseWhen::DuringLine { line, fraction }) => {
            let (first, last) = match &source {
                Some(source) => (
                    source.iter().position(|&s| s == line),
                    source.iter().rposition(|&s| s == line),
                ),
                None => {
                    let here = (line < job.len()).then_some(line);
                    (here, here)
                }
            };
            let range = first
                .zip(last)
                .map(|(a, b)| a..=b)
                .unwrap_or(usize::MAX..=usize::MAX);
            Some(line_time(f, sc, &job, range, fraction).ok_or_else(|| {
                anyhow::anyhow!("job line {line} never executes: no moment to pause in")
            })?)
        }
        Some(PauseWhen::AtLayer(n)) => {
            match sc.policy {
                Policy::Firmware => a.host.insert_lines([format!("M761 L{n}")]),
                Policy::Fifo => {
                    let at = info
                        .layer_starts
                        .iter()
                        .find(|(l, _)| *l == n)
                        .map(|(_, i)| *i)
                        .ok_or_else(|| anyhow::anyhow!("the job has no layer {n}"))?;
                    // A conventional slicer's "pause at layer": M601 in the stream before it.
                    a.host.insert_before(at, vec!["M601".into()], false);
                }
                Policy::HostSplit => {
                    let at = info
                        .layer_starts
                        .iter()
                        .find(|(l, _)| *l == n)
                        .map(|(_, i)| *i)
                        .ok_or_else(|| anyhow::anyhow!("the job has no layer {n}"))?;
                    let st = info.state_before(at);
                    host_pause_state = Some(st);
                    a.host
                        .insert_and_hold_before(at, split::pause_sequence(&st, &sc.machine));
                }
            }
            note(0, format!("pause scheduled for the start of layer {n}"));
            None
        }
    };

    let mut facts = RunFacts::default();
    if streaming {
        // Up to the request (or, for a scheduled pause, until the pause begins): A and B in
        // turns, their records compared and let go as they complete.
        let until = t_req.unwrap_or(sc.max_time_us);
        loop {
            let next = (a.now_us + STREAM_CHUNK_US).min(until);
            let stop = a.advance(next, false);
            if stop == Stop::Finished && t_req.is_some() {
                break;
            }
            b.advance(next, false);
            let pausing = matches!(a.fw.status().state, RunState::Pausing | RunState::Paused);
            if pausing || matches!(stop, Stop::Finished | Stop::Stalled) || next >= until {
                break;
            }
            stream::feed(&mut a, Side::A, false, &mut cmp, &mut ends);
            stream::feed(&mut b, Side::B, false, &mut cmp, &mut ends);
            if let Some(fl) = stream::window_floor(&a) {
                ends.raise_floor(fl);
            }
        }
    }
    if let Some(t) = t_req {
        let stop = a.advance(t, false);
        if let Some(why) = &a.host.aborted {
            anyhow::bail!("host link: {why}");
        }
        if stop == Stop::Finished {
            anyhow::bail!(
                "the job finished at {:.3} s, before the pause request at {:.3} s",
                a.now_us as f64 * 1e-6,
                t as f64 * 1e-6
            );
        }
        b.advance(t, false);
        facts.t_req_us = Some(t);
        facts.pos_at_req = a.rec.pos;
        facts.records_before_req = a.rec.records.len();
        note(
            t,
            format!(
                "pause requested ({} mode, {})",
                sc.mode.name(),
                sc.policy.name()
            ),
        );
        match sc.policy {
            // Conventional firmware has one pause (at the tail): always the plain M25.
            Policy::Fifo => a.host.send_realtime(request_text(Mode::Layer), t),
            Policy::Firmware => a.host.send_realtime(request_text(sc.mode), t),
            Policy::HostSplit => {
                // The host's view: the layer of the last line it sent.
                let last_sent = a.host.cursor().saturating_sub(1);
                let at = match sc.mode {
                    Mode::Now => a.host.cursor(),
                    Mode::Layer => info.next_layer_start(last_sent).unwrap_or(job.len()),
                };
                let st = info.state_before(at);
                host_pause_state = Some(st);
                a.host
                    .insert_and_hold_before(at, split::pause_sequence(&st, &sc.machine));
            }
        }
        // Lock-step until the motion differs.
        facts.reaction_us = lockstep(&mut a, &mut b, t, sc.max_time_us);
    } else if let Some(PauseWhen::AtLayer(_)) = sc.pause {
        facts.t_req_us = None;
    }

    // Wait for the park, then resume.
    if sc.pause.is_some() {
        let parked = wait_parked(&mut a, sc);
        if let Some(tp) = parked {
            facts.t_parked_us = Some(tp);
            note(tp, "parked (paused)".into());
            if let Some(after) = sc.resume_after_us {
                let tr = tp + after;
                a.advance(tr, false);
                facts.t_resume_us = Some(tr);
                note(tr, "resume requested".into());
                match sc.policy {
                    Policy::Fifo | Policy::Firmware => a.host.send_realtime("M24", tr),
                    Policy::HostSplit => {
                        let st = host_pause_state.unwrap_or_else(|| {
                            // Scheduled host-side pause: the state where the host stopped.
                            info.state_before(a.host.cursor())
                        });
                        a.host
                            .insert_lines(split::resume_sequence(&st, &sc.machine));
                        a.host.release();
                    }
                }
            }
        }
    }
    let mut view = RunView::default();
    let (a_done, b_done) = if streaming {
        // Keep A's records from the request until it prints again after the resume (the
        // window the pause figures read), then run A and B to the end in turns.
        loop {
            let resumed = first_job_after_service(&a).is_some();
            if resumed || a.now_us >= sc.max_time_us {
                break;
            }
            let stop = a.advance(a.now_us + STREAM_CHUNK_US, false);
            if matches!(stop, Stop::Finished | Stop::Stalled) {
                break;
            }
        }
        view.records = a.rec.records.clone();
        view.keys = view.records.iter().map(|r| stream::key_of(&a, r)).collect();
        if let Some(top) = view.keys.iter().flatten().map(|k| k.0).max() {
            ends.set_ceil(top);
        }
        run_in_turns(&mut a, &mut b, sc.max_time_us, &mut cmp, &mut ends)
    } else {
        let a_done = a.run_to_end(sc.max_time_us);
        // Without a pause the reference is the run itself: do not simulate it twice.
        let b_done = if sc.pause.is_some() {
            b.run_to_end(sc.max_time_us)
        } else {
            a_done
        };
        (a_done, b_done)
    };
    if let Some(why) = &a.host.aborted {
        anyhow::bail!("host link: {why}");
    }
    if !streaming {
        // Everything kept: compare the whole records.
        view.records = a.rec.records.clone();
        view.keys = view.records.iter().map(|r| stream::key_of(&a, r)).collect();
        if sc.pause.is_some() {
            stream::feed(&mut a, Side::A, true, &mut cmp, &mut ends);
            stream::feed(&mut b, Side::B, true, &mut cmp, &mut ends);
        } else {
            // The run against itself.
            let recs = a.rec.records.clone();
            for r in &recs {
                let k = stream::key_of(&a, r);
                cmp.push(Side::A, k);
                cmp.push(Side::B, k);
                ends.note(k, r);
            }
        }
    }
    view.b_line_ends = ends;
    view.comparison = cmp.finish();
    facts.finished = a_done;
    facts.reference_finished = b_done;
    facts.wall_s = wall.elapsed().as_secs_f64();

    let mut report = if sc.pause.is_some() {
        metrics::compute(sc, &info, &a, &b, &facts, &view)
    } else {
        metrics::compute(sc, &info, &a, &a, &facts, &view)
    };
    if sc.measure_segmentation_cost && sc.policy == Policy::Firmware {
        let mut knobs = sc.knobs();
        knobs.segment_len_mm = None;
        let fw = f.make(&sc.machine, &knobs);
        let mut c = Engine::new(fw, Host::new(sc.link.clone(), job.clone()));
        c.rec.keep_records = false;
        c.run_to_end(sc.max_time_us);
        let t_plain = c.rec.last_step_us as f64 * 1e-6;
        report.segmentation_cost_s = Some(report.print_time_unpaused_s - t_plain);
    }
    if let Some((r, t)) = report.reaction_s.zip(facts.t_req_us) {
        note(
            t + (r * 1e6) as u64,
            "first change of motion (reaction)".into(),
        );
    }
    if let Some(ts) = report.stop_s.zip(facts.t_req_us) {
        note(
            ts.1 + (ts.0 * 1e6) as u64,
            format!(
                "head stopped at the pause point{}",
                match (report.stopped_at_layer_boundary, report.stop_layer) {
                    (true, Some(l)) => format!(" (end of layer {l})"),
                    (false, Some(l)) => format!(" (inside layer {l})"),
                    _ => String::new(),
                }
            ),
        );
    }
    if let Some(t) = report.resumed_s {
        note(
            (t * 1e6) as u64,
            "printing again (first job step after resume)".into(),
        );
    }
    note(
        a.rec.last_step_us,
        if a_done {
            "job finished"
        } else {
            "last step (the job did not finish)"
        }
        .into(),
    );
    timeline.sort_by(|x, y| x.t_s.total_cmp(&y.t_s));
    Ok(Outcome {
        report,
        run: a,
        reference: b,
        job,
        timeline,
        reference_finished: b_done,
    })
}

/// Why a run that should have reached the end of its job did not (`None` when it did; with a
/// pause and no resume, why the pause never completed, if it did not). A job that does not finish
/// is a failure of the firmware (a pause that never completes, a wait that never ends), so
/// `sim run` reports it and exits non-zero instead of printing "job finished".
pub fn unfinished<E: Executive>(sc: &Scenario, o: &Outcome<E>) -> Option<String> {
    let why = |e: &Engine<E>, what: &str| {
        let st = e.fw.status();
        let last = e.host.received.last().map_or(String::new(), |r| {
            format!("; last printer line {:?}", r.text)
        });
        format!(
            "{what}: printer {:?} at {:.3} s (virtual), {} of {} lines sent, {} moves queued{last}",
            st.state,
            e.now_us as f64 * 1e-6,
            e.host.cursor(),
            e.host.job().len(),
            st.queue_depth,
        )
    };
    if sc.pause.is_some() && sc.resume_after_us.is_none() {
        // Staying paused is the plan: the pause must have completed (parked).
        return o
            .report
            .parked_s
            .is_none()
            .then(|| why(&o.run, "the pause never completed"));
    }
    if !o.report.finished {
        return Some(why(&o.run, "the job did not finish"));
    }
    if sc.pause.is_some() && !o.reference_finished {
        return Some(why(
            &o.reference,
            "the job did not finish (reference run without the pause)",
        ));
    }
    None
}
