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
//! What defines a run is [`crate::scenario`] (re-exported here); the submodule `drive` steps
//! the engines (trial run, lock-step, park wait, the rest in turns).

mod drive;

pub use crate::scenario::{Mode, PauseWhen, Policy, Scenario};

use crate::engine::{Engine, Stop};
use crate::hostlink::{Host, Refusals};
use crate::job::{HostState, JobInfo, JobLines};
use crate::metrics::{self, PauseReport, RunFacts, RunView};
use crate::port::{Executive, FirmwareKnobs, State};
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
    /// Job lines the printer refused in the run (`echo:refused:`), by their index in the file.
    pub refused: Refusals,
    /// Job lines the printer did not know (`echo:Unknown command:`): macros the sim cannot run.
    pub unknown: Refusals,
    /// Lines longer than [`crate::job::MAX_LINE_BYTES`], sent cut there.
    pub cut_lines: u64,
}

/// Make a job ready for a policy: host-split pre-splits it. Returns the lines to send and,
/// for each, the line of the original job it came from (`None`: the job is sent as it is, line
/// for line).
/// Host-split holds its split job in memory (a model of the paper's host for lab-sized jobs):
/// a longer file is refused rather than read whole.
pub const HOST_SPLIT_MAX_LINES: usize = 2_000_000;

/// Make a job ready for a policy: host-split pre-splits it (in memory, up to
/// [`HOST_SPLIT_MAX_LINES`] lines). Returns the lines to send and, for each, the line of the
/// original job it came from (`None`: the job is sent as it is, line for line).
pub fn prepare_job(
    policy: Policy,
    job: &JobLines,
    split_mm: f64,
) -> anyhow::Result<(JobLines, Option<Vec<usize>>)> {
    match policy {
        Policy::HostSplit => {
            if job.len() > HOST_SPLIT_MAX_LINES {
                anyhow::bail!(
                    "host-split keeps its split job in memory: at most {HOST_SPLIT_MAX_LINES} lines, this job has {}",
                    job.len()
                );
            }
            let s = split::split_job(&job.to_vec()?, split_mm);
            Ok((JobLines::from_lines(&s.lines), Some(s.source)))
        }
        _ => Ok((job.clone(), None)),
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

/// [`run`] of a job already in a [`JobLines`] (`sim run`: the file streamed, shared by both
/// runs). The phases, in order: the request's moment ([`Run::request_time`]), A and B up to
/// it ([`Run::until_request`]), the request and the lock-step to the reaction
/// ([`Run::request`]), the park and the resume ([`Run::park_and_resume`]), the rest of the job
/// ([`Run::run_to_the_end`]), the figures ([`Run::report`]).
pub fn run_job<F: Factory>(
    f: &F,
    sc: &Scenario,
    job_lines: JobLines,
) -> anyhow::Result<Outcome<F::Exec>> {
    let wall = std::time::Instant::now();
    let (job, source) = prepare_job(sc.policy, &job_lines, sc.split_mm)?;
    drop(job_lines);
    let mut r = Run::new(f, sc, job, source)?;
    let t_req = r.request_time(f)?;
    r.until_request(t_req);
    if let Some(t) = t_req {
        r.request(t)?;
    }
    if sc.pause.is_some() {
        r.park_and_resume();
    }
    let view = r.run_to_the_end()?;
    r.facts.wall_s = wall.elapsed().as_secs_f64();
    Ok(r.report(f, view))
}

/// One run in progress: A (with the pause), B (the reference), what is compared and noted.
struct Run<'s, E: Executive> {
    sc: &'s Scenario,
    /// The job as sent (split for host-split), and each sent line's line in the file.
    job: JobLines,
    source: Option<Vec<usize>>,
    /// The host's view of the job (read only around a pause).
    info: JobInfo,
    a: Engine<E>,
    b: Engine<E>,
    /// A and B compared as they run (without kept records).
    streaming: bool,
    cmp: Compare,
    ends: LineEnds,
    facts: RunFacts,
    timeline: Vec<TimelineEvent>,
    /// Host-split: the host state its pause sequence was written from.
    host_pause_state: Option<HostState>,
}

impl<'s, E: Executive> Run<'s, E> {
    fn new<F: Factory<Exec = E>>(
        f: &F,
        sc: &'s Scenario,
        job: JobLines,
        source: Option<Vec<usize>>,
    ) -> anyhow::Result<Self> {
        // The host's view of the job is only read around a pause.
        let info = if sc.pause.is_some() && sc.policy == Policy::HostSplit {
            // Host-split writes its pause and resume sequences from the host state at each line.
            JobInfo::parse_job(&job)?
        } else if sc.pause.is_some() {
            JobInfo::parse_layers(&job)?
        } else {
            JobInfo::default()
        };
        let mut a = new_engine(f, sc, job.clone());
        a.rec.keep_records = sc.keep_records || sc.pause.is_some();
        // With a pause and no caller asking for the records, compare A and B as they run.
        let streaming = sc.pause.is_some() && !sc.keep_records;
        a.rec.stream = streaming;
        // Without a pause the reference is the run itself and is never stepped.
        let b_job = if sc.pause.is_some() {
            job.clone()
        } else {
            JobLines::default()
        };
        let mut b = new_engine(f, sc, b_job);
        b.rec.stream = streaming;
        Ok(Self {
            sc,
            job,
            source,
            info,
            a,
            b,
            streaming,
            cmp: Compare::default(),
            ends: LineEnds::default(),
            facts: RunFacts::default(),
            timeline: Vec::new(),
            host_pause_state: None,
        })
    }

    fn note(&mut self, t_us: u64, what: String) {
        self.timeline.push(TimelineEvent {
            t_s: t_us as f64 * 1e-6,
            what,
        });
    }

    /// When the request is made (`None`: no request during the run; a pause at a layer is
    /// scheduled here, before the job starts).
    fn request_time<F: Factory<Exec = E>>(&mut self, f: &F) -> anyhow::Result<Option<u64>> {
        let sc = self.sc;
        match sc.pause {
            None => Ok(None),
            Some(PauseWhen::AtUs(t)) => Ok(Some(t)),
            Some(PauseWhen::DuringLine { line, fraction }) => {
                let (first, last) = match &self.source {
                    Some(source) => (
                        source.iter().position(|&s| s == line),
                        source.iter().rposition(|&s| s == line),
                    ),
                    None => {
                        let here = (line < self.job.len()).then_some(line);
                        (here, here)
                    }
                };
                let range = first
                    .zip(last)
                    .map(|(a, b)| a..=b)
                    .unwrap_or(usize::MAX..=usize::MAX);
                let t = line_time(f, sc, &self.job, range, fraction).ok_or_else(|| {
                    anyhow::anyhow!("job line {line} never executes: no moment to pause in")
                })?;
                Ok(Some(t))
            }
            Some(PauseWhen::AtLayer(n)) => {
                let layer_start = || {
                    self.info
                        .layer_starts
                        .iter()
                        .find(|(l, _)| *l == n)
                        .map(|(_, i)| *i)
                        .ok_or_else(|| anyhow::anyhow!("the job has no layer {n}"))
                };
                match sc.policy {
                    Policy::Firmware => self.a.host.insert_lines([format!("M761 L{n}")]),
                    Policy::Fifo => {
                        let at = layer_start()?;
                        // A conventional slicer's "pause at layer": M601 in the stream before it.
                        self.a.host.insert_before(at, vec!["M601".into()], false);
                    }
                    Policy::HostSplit => {
                        let at = layer_start()?;
                        let st = self.info.state_before(at);
                        self.host_pause_state = Some(st);
                        self.a
                            .host
                            .insert_and_hold_before(at, split::pause_sequence(&st, &sc.machine));
                    }
                }
                self.note(0, format!("pause scheduled for the start of layer {n}"));
                Ok(None)
            }
        }
    }

    /// Up to the request (or, for a scheduled pause, until the pause begins): A and B in
    /// turns, their records compared and let go as they complete (when streaming).
    fn until_request(&mut self, t_req: Option<u64>) {
        if !self.streaming {
            return;
        }
        let until = t_req.unwrap_or(self.sc.max_time_us);
        let (a, b) = (&mut self.a, &mut self.b);
        loop {
            let next = (a.now_us + STREAM_CHUNK_US).min(until);
            let stop = a.advance(next, false);
            if stop == Stop::Finished && t_req.is_some() {
                break;
            }
            b.advance(next, false);
            let pausing = matches!(a.fw.status().state, State::Pausing | State::Paused);
            if pausing || matches!(stop, Stop::Finished | Stop::Stalled) || next >= until {
                break;
            }
            stream::feed(a, Side::A, false, &mut self.cmp, &mut self.ends);
            stream::feed(b, Side::B, false, &mut self.cmp, &mut self.ends);
            if let Some(fl) = stream::window_floor(a) {
                self.ends.raise_floor(fl);
            }
        }
    }

    /// The request at `t` as the policy's host makes it, then A and B in lock-step until the
    /// motion differs (the reaction).
    fn request(&mut self, t: u64) -> anyhow::Result<()> {
        let sc = self.sc;
        let stop = self.a.advance(t, false);
        if let Some(why) = &self.a.host.aborted {
            anyhow::bail!("host link: {why}");
        }
        if stop == Stop::Finished {
            anyhow::bail!(
                "the job finished at {:.3} s, before the pause request at {:.3} s",
                self.a.now_us as f64 * 1e-6,
                t as f64 * 1e-6
            );
        }
        self.b.advance(t, false);
        self.facts.t_req_us = Some(t);
        self.facts.pos_at_req = self.a.rec.pos;
        self.facts.records_before_req = self.a.rec.records.len();
        self.note(
            t,
            format!(
                "pause requested ({} mode, {})",
                sc.mode.name(),
                sc.policy.name()
            ),
        );
        match sc.policy {
            // Conventional firmware has one pause (at the tail): always the plain M25.
            Policy::Fifo => self.a.host.send_realtime(request_text(Mode::Layer), t),
            Policy::Firmware => self.a.host.send_realtime(request_text(sc.mode), t),
            Policy::HostSplit => {
                // The host's view: the layer of the last line it sent.
                let last_sent = self.a.host.cursor().saturating_sub(1);
                let at = match sc.mode {
                    Mode::Now => self.a.host.cursor(),
                    Mode::Layer => self
                        .info
                        .next_layer_start(last_sent)
                        .unwrap_or(self.job.len()),
                };
                let st = self.info.state_before(at);
                self.host_pause_state = Some(st);
                self.a
                    .host
                    .insert_and_hold_before(at, split::pause_sequence(&st, &sc.machine));
            }
        }
        self.facts.reaction_us = lockstep(&mut self.a, &mut self.b, t, sc.max_time_us);
        Ok(())
    }

    /// Wait for the park, then resume as the policy's host does.
    fn park_and_resume(&mut self) {
        let sc = self.sc;
        let Some(tp) = wait_parked(&mut self.a, sc) else {
            return;
        };
        self.facts.t_parked_us = Some(tp);
        self.note(tp, "parked (paused)".into());
        let Some(after) = sc.resume_after_us else {
            return;
        };
        let tr = tp + after;
        // However long the pause: the host resumes at `tr` (not a stall).
        self.a.wait_until(tr);
        self.facts.t_resume_us = Some(tr);
        self.note(tr, "resume requested".into());
        match sc.policy {
            Policy::Fifo | Policy::Firmware => self.a.host.send_realtime("M24", tr),
            Policy::HostSplit => {
                let st = self.host_pause_state.unwrap_or_else(|| {
                    // Scheduled host-side pause: the state where the host stopped.
                    self.info.state_before(self.a.host.cursor())
                });
                self.a
                    .host
                    .insert_lines(split::resume_sequence(&st, &sc.machine));
                self.a.host.release();
            }
        }
    }

    /// The rest of the job, A and B to their ends; what the figures read of the records.
    fn run_to_the_end(&mut self) -> anyhow::Result<RunView> {
        let sc = self.sc;
        let mut view = RunView::default();
        // A pause that is never resumed: A stays parked (nothing more to run), B runs on.
        let a_stays =
            sc.pause.is_some() && sc.resume_after_us.is_none() && self.facts.t_parked_us.is_some();
        let (a_done, b_done) = if self.streaming {
            // Keep A's records from the request until it prints again after the resume (the
            // window the pause figures read), then run A and B to the end in turns.
            loop {
                let resumed = first_job_after_service(&self.a).is_some();
                if resumed || a_stays || self.a.now_us >= sc.max_time_us {
                    break;
                }
                let stop = self.a.advance(self.a.now_us + STREAM_CHUNK_US, false);
                if matches!(stop, Stop::Finished | Stop::Stalled) {
                    break;
                }
            }
            view.records = self.a.rec.records.clone();
            view.keys = view
                .records
                .iter()
                .map(|r| stream::key_of(&self.a, r))
                .collect();
            let job_lines = view.keys.iter().flatten().map(|k| k.0);
            if let Some(top) = job_lines.filter(|&l| l != stream::HOMING_LINE).max() {
                self.ends.set_ceil(top);
            }
            run_in_turns(
                &mut self.a,
                &mut self.b,
                sc.max_time_us,
                a_stays,
                &mut self.cmp,
                &mut self.ends,
            )
        } else {
            let a_done = !a_stays && self.a.run_to_end(sc.max_time_us);
            // Without a pause the reference is the run itself: do not simulate it twice.
            let b_done = if sc.pause.is_some() {
                self.b.run_to_end(sc.max_time_us)
            } else {
                a_done
            };
            (a_done, b_done)
        };
        if let Some(why) = &self.a.host.aborted {
            anyhow::bail!("host link: {why}");
        }
        if !self.streaming {
            // Everything kept: compare the whole records.
            view.records = self.a.rec.records.clone();
            view.keys = view
                .records
                .iter()
                .map(|r| stream::key_of(&self.a, r))
                .collect();
            if sc.pause.is_some() {
                stream::feed(&mut self.a, Side::A, true, &mut self.cmp, &mut self.ends);
                stream::feed(&mut self.b, Side::B, true, &mut self.cmp, &mut self.ends);
            } else {
                // The run against itself.
                let recs = self.a.rec.records.clone();
                for r in &recs {
                    let k = stream::key_of(&self.a, r);
                    self.cmp.push(Side::A, k);
                    self.cmp.push(Side::B, k);
                    self.ends.note(k, r);
                }
            }
        }
        view.b_line_ends = std::mem::take(&mut self.ends);
        view.comparison = std::mem::take(&mut self.cmp).finish();
        self.facts.finished = a_done;
        self.facts.reference_finished = b_done;
        Ok(view)
    }

    /// The figures, the segmentation cost (one more run) and the timeline.
    fn report<F: Factory<Exec = E>>(mut self, f: &F, view: RunView) -> Outcome<E> {
        let sc = self.sc;
        let mut report = if sc.pause.is_some() {
            metrics::compute(sc, &self.info, &self.a, &self.b, &self.facts, &view)
        } else {
            metrics::compute(sc, &self.info, &self.a, &self.a, &self.facts, &view)
        };
        // A refused job line is a lost move (issue 27): read from the answers the host got.
        report.refused_job_lines = usize::try_from(self.a.host.refused.count).unwrap_or(usize::MAX);
        report.lost_moves = report.lost_moves.saturating_add(report.refused_job_lines);
        if sc.measure_segmentation_cost && sc.policy == Policy::Firmware {
            let mut knobs = sc.knobs();
            knobs.segment_len_mm = None;
            let fw = f.make(&sc.machine, &knobs);
            let mut c = Engine::new(fw, Host::new(sc.link.clone(), self.job.clone()));
            c.rec.keep_records = false;
            c.run_to_end(sc.max_time_us);
            let t_plain = c.rec.last_step_us as f64 * 1e-6;
            report.segmentation_cost_s = Some(report.print_time_unpaused_s - t_plain);
        }
        if let Some((r, t)) = report.reaction_s.zip(self.facts.t_req_us) {
            self.note(
                t + (r * 1e6) as u64,
                "first change of motion (reaction)".into(),
            );
        }
        if let Some((s, t)) = report.stop_s.zip(self.facts.t_req_us) {
            let at = match (report.stopped_at_layer_boundary, report.stop_layer) {
                (true, Some(l)) => format!(" (end of layer {l})"),
                (false, Some(l)) => format!(" (inside layer {l})"),
                _ => String::new(),
            };
            self.note(
                t + (s * 1e6) as u64,
                format!("head stopped at the pause point{at}"),
            );
        }
        if let Some(t) = report.resumed_s {
            self.note(
                (t * 1e6) as u64,
                "printing again (first job step after resume)".into(),
            );
        }
        let last = self.a.rec.last_step_us;
        self.note(
            last,
            if self.facts.finished {
                "job finished"
            } else {
                "last step (the job did not finish)"
            }
            .into(),
        );
        self.timeline.sort_by(|x, y| x.t_s.total_cmp(&y.t_s));
        // Refused lines by their line in the file (host-split sends pieces of them).
        let mut refused = self.a.host.refused.clone();
        let mut unknown = self.a.host.unknown.clone();
        if let Some(source) = &self.source {
            for r in refused.first.iter_mut().chain(unknown.first.iter_mut()) {
                r.index = source.get(r.index).copied().unwrap_or(r.index);
            }
        }
        Outcome {
            report,
            reference_finished: self.facts.reference_finished,
            refused,
            unknown,
            cut_lines: self.a.host.cut_lines,
            run: self.a,
            reference: self.b,
            job: self.job,
            timeline: self.timeline,
        }
    }
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

/// Why a pause did not do what the layers of the job say it must (`None` when it did), judged
/// by the independent reference ([`layerref`], in [`crate::metrics`]), for this firmware's
/// policy (the conventional ones are measured, not judged):
/// - a pause scheduled for layer `n` (`M761 L<n>`) must happen, and stop at the boundary before
///   the layer the reference numbers `n` (a job without such a layer fails too);
/// - a `layer` pause requested at a time must happen, stop at a layer boundary, and at the
///   first one still reachable when it was asked for.
///
/// `sim run` reports the reason and exits non-zero.
pub fn layer_verdict<E: Executive>(sc: &Scenario, o: &Outcome<E>) -> Option<String> {
    if sc.policy != Policy::Firmware {
        return None;
    }
    let r = &o.report;
    let stopped = || match (r.stopped_at_layer_boundary, r.stop_layer) {
        (true, Some(l)) => format!("at the end of layer {l}"),
        (true, None) => "before the first layer".to_string(),
        (false, Some(l)) => format!("inside layer {l}"),
        (false, None) => "off a layer boundary".to_string(),
    };
    match sc.pause {
        Some(PauseWhen::AtLayer(n)) => {
            if r.parked_s.is_none() {
                Some(format!("the pause scheduled for layer {n} never happened"))
            } else if !r.first_boundary_after_request {
                Some(format!(
                    "the pause scheduled for layer {n} stopped {} (the reference's layer {n} \
                     starts after the end of layer {})",
                    stopped(),
                    n.saturating_sub(1)
                ))
            } else {
                None
            }
        }
        Some(_) if sc.mode == Mode::Layer => {
            if r.parked_s.is_none() {
                Some("the layer pause never happened".to_string())
            } else if !r.stopped_at_layer_boundary {
                Some(format!("the layer pause stopped {}", stopped()))
            } else if r.first_reachable_boundary == Some(false) {
                Some(format!(
                    "the layer pause stopped {}, not at the first boundary still reachable at \
                     the request (the end of layer {})",
                    stopped(),
                    r.request_layer.map_or("—".to_string(), |l| l.to_string())
                ))
            } else {
                None
            }
        }
        _ => None,
    }
}
