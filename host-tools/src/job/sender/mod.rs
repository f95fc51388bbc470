//! The sender: streams a [`Job`] to a printer over any `Read + Write` byte stream (a serial port,
//! a pseudo-terminal, or an in-memory fake printer in tests) with line numbers, XOR checksums and
//! `ok` flow control; handles `Resend:`, `busy:`, `echo:`, `Error:`, temperature reports and
//! `//action:` notifications; detects our layer-aware pause from M115; pauses at a layer
//! boundary (the firmware's pause, or the host-side [`fallback`] on stock firmware) so the rest
//! of the job can be edited with [`crate::job::ops`] before resuming.
//!
//! [`Session`] is a state machine driven by [`Session::poll`] with the current time, so tests run
//! it against a scripted printer without threads or a clock. Its work is split by job: `types`
//! (what it reports and accepts), `stream` (what to write next), `receive` (the printer's
//! replies), `resend` (recovery from a lossy link) and `requests` (pause, resume, cancel).

pub mod fallback;
pub mod protocol;
pub mod tui;

mod receive;
mod requests;
mod resend;
mod stream;
mod types;

use std::collections::VecDeque;
use std::io::{Read, Write};
use std::time::Duration;

use crate::job::modal::Modal;
use crate::job::{Job, Section};
use protocol::frame;

pub use types::{Capabilities, Event, Options, PauseMethod, Progress, Request, State};

/// How long to wait for `//action:resumed` after `M24` before streaming anyway.
pub const RESUME_WAIT: Duration = Duration::from_secs(60);

/// Give up when the printer has not acknowledged the M115 query after this long (it may be busy
/// with a long command of an earlier session, answering `busy:`).
pub const IDENTIFY_TIMEOUT: Duration = Duration::from_secs(900);

/// Give up when a line has been resent this many times for want of an `ok` (see
/// [`Options::ok_timeout`]).
pub const MAX_NUDGES: u32 = 3;

/// A `Resend:` for one of the last `ACK_DOUBT` lines taken as acknowledged is trusted (the
/// `ok`s were wrong: doubled, or a refusal whose `Error:`/`Resend:` was lost); one further back
/// means the printer's line counter went back (reset, M110 from elsewhere) and is set again.
/// So a counter reset within the first `ACK_DOUBT` lines of a session re-runs those lines (the
/// M115 query and the start of the start code).
pub const ACK_DOUBT: u32 = 3;

/// A request for a line outside the unacknowledged ones sets the printer's line counter (M110)
/// only when it comes this many times in a row (a garbled number rarely repeats).
pub const RESYNC_AFTER: u32 = 3;

/// Give up when the printer asks for the same line this many times in a row.
pub const MAX_RESENDS: u32 = 10;

/// Longest framed line (`N<n> <line>*<cs>`) sent to our firmware (`firmware::link::LINE_CAP`).
pub const LINE_CAP_FIRMWARE: usize = firmware::link::LINE_CAP;

/// Longest framed line sent to stock firmware (Marlin's `MAX_CMD_SIZE` is 96 bytes).
pub const LINE_CAP_STOCK: usize = 96;

/// How many sent lines are kept for `Resend:` requests.
pub const HISTORY_LINES: usize = 1024;

/// Capability names (in the M115 `Cap:` report) that announce our layer-aware pause. The first is
/// the spelling of `firmware::link`; the others are accepted for compatibility.
pub const LAYER_PAUSE_CAPS: &[&str] = &["LAYER_PAUSE", "PAUSE_AT_LAYER"];

#[derive(Clone, Debug, PartialEq)]
enum Pending {
    /// Stop before layer index `gate`, then park. `early` says the firmware was already told.
    AtLayer { gate: usize },
    /// Stop now.
    Now,
}

#[derive(Clone, Debug, PartialEq)]
enum Sync {
    /// The harmless command that delivers the layer mark at the gate (firmware pause): once it
    /// is acknowledged the mark is queued, and a realtime `M25` stops exactly there.
    Trigger,
    /// M400 sent before the host pause sequence (pause now, host-side).
    HostDrain,
    /// M400 sent after the host pause sequence: paused when acknowledged.
    HostParked,
    /// M400 after a host prompt line: paused when acknowledged.
    Prompt(String),
    /// M400 after the last job line: done when acknowledged.
    Finish,
}

/// A host-generated line waiting to be sent.
#[derive(Clone, Debug, PartialEq)]
struct Out {
    line: String,
    sync: Option<Sync>,
    /// Update the modal state with this line when it is sent (false for the pieces of a job
    /// move, whose original command was tracked when it was taken).
    tracked: bool,
}

impl Out {
    fn plain(line: impl Into<String>) -> Out {
        Out {
            line: line.into(),
            sync: None,
            tracked: true,
        }
    }

    fn piece(line: String) -> Out {
        Out {
            line,
            sync: None,
            tracked: false,
        }
    }
}

/// A print session over a byte stream `P`.
pub struct Session<P: Read + Write> {
    port: P,
    opts: Options,
    job: Job,
    sec: Section,
    idx: usize,
    state: State,
    method: Option<PauseMethod>,
    caps: Capabilities,
    rx: Vec<u8>,
    next_no: u32,
    history: VecDeque<(u32, String)>,
    outstanding: usize,
    resend_from: Option<u32>,
    queue: VecDeque<Out>,
    modal: Modal,
    pending: Option<Pending>,
    sync: Option<(u32, Sync)>,
    paused_modal: Option<Modal>,
    paused_by_firmware: bool,
    last_rx: Duration,
    last_probe: Option<Duration>,
    started: Option<Duration>,
    last_temp_req: Duration,
    events: Vec<Event>,
    progress: Progress,
    pause_requested_at: Option<Duration>,
    log_rx: bool,
    rx_log: Vec<String>,
    rt_oks: usize,
    last_resend: (u32, u32),
    /// Highest line number the printer is known to have accepted (its `ok` came without a
    /// `Resend:` for it).
    acked: u32,
    /// Number of the last numbered line written (new or resent).
    last_written: u32,
    /// A `Resend:` arrived since `last_written` was written: its `ok` does not accept it.
    rejected: bool,
    /// When the M115 query was sent (identification timeout).
    identify_sent_at: Option<Duration>,
    /// When connecting started (connection timeout).
    connecting_since: Option<Duration>,
    /// The resend a line error asked for; the `Resend:` that follows it is not counted twice.
    error_resend: Option<u32>,
    /// A resend request outside the unacknowledged lines and how often it came in a row: the
    /// printer's counter is set (M110) only at the [`RESYNC_AFTER`]th.
    suspect: Option<(u32, u32)>,
    /// Time of the current poll.
    now: Duration,
    /// Last sign that the printer is handling our lines: an `ok`, `busy:` or `Resend:`, or the
    /// write of a numbered line.
    last_ack: Duration,
    /// Resends for want of an `ok` since the last `ok`.
    nudges: u32,
    resume_requested_at: Option<Duration>,
    pause_now: bool,
    scheduled: bool,
}

impl<P: Read + Write> Session<P> {
    /// A session that will stream `job` over `port`.
    pub fn new(port: P, job: Job, opts: Options) -> Self {
        let mut s = Session {
            port,
            opts,
            job,
            sec: Section::Start,
            idx: 0,
            state: State::Connecting,
            method: None,
            caps: Capabilities::default(),
            rx: Vec::new(),
            next_no: 1,
            history: VecDeque::new(),
            outstanding: 0,
            resend_from: None,
            queue: VecDeque::new(),
            modal: Modal::default(),
            pending: None,
            sync: None,
            paused_modal: None,
            paused_by_firmware: false,
            last_rx: Duration::ZERO,
            last_probe: None,
            started: None,
            last_temp_req: Duration::ZERO,
            events: Vec::new(),
            progress: Progress::default(),
            pause_requested_at: None,
            log_rx: false,
            rx_log: Vec::new(),
            rt_oks: 0,
            last_resend: (0, 0),
            acked: 0,
            last_written: 0,
            rejected: false,
            identify_sent_at: None,
            connecting_since: None,
            error_resend: None,
            suspect: None,
            now: Duration::ZERO,
            last_ack: Duration::ZERO,
            nudges: 0,
            resume_requested_at: None,
            pause_now: false,
            scheduled: false,
        };
        s.refresh_estimates();
        s
    }

    /// Keep every line received (for debugging and tests); see [`Session::take_rx_log`].
    pub fn set_rx_log(&mut self, on: bool) {
        self.log_rx = on;
    }

    /// Lines received since the last call (when enabled with [`Session::set_rx_log`]).
    pub fn take_rx_log(&mut self) -> Vec<String> {
        std::mem::take(&mut self.rx_log)
    }

    /// The job (read-only).
    pub fn job(&self) -> &Job {
        &self.job
    }

    /// The first layer whose lines the host has not started to send.
    pub fn first_unsent_layer(&self) -> usize {
        match self.sec {
            Section::Start => 0,
            Section::Layer(i) if self.idx == 0 => i,
            Section::Layer(i) => i + 1,
            Section::End => self.job.layers.len(),
        }
    }

    /// Edits the rest of the job while paused: `f` gets the job and the boundary (the first layer
    /// the host has not started to send); layers before it and the start code must not change.
    /// Fails when not paused.
    pub fn edit_job<T>(
        &mut self,
        f: impl FnOnce(&mut Job, usize) -> Result<T, crate::job::JobError>,
    ) -> Result<T, crate::job::JobError> {
        let boundary = match &self.state {
            State::Paused {
                boundary: Some(b), ..
            } => *b,
            _ => {
                return Err(crate::job::JobError::Op(
                    "the job can only be edited while paused".into(),
                ))
            }
        };
        let mut edited = self.job.clone();
        let r = f(&mut edited, boundary)?;
        if edited.layers.get(..boundary) != self.job.layers.get(..boundary)
            || edited.start != self.job.start
        {
            return Err(crate::job::JobError::Op(
                "the edit changed layers that are already sent".into(),
            ));
        }
        self.job = edited;
        // A cursor at the boundary (start of a layer or of the end code) points at whatever is
        // there now; a cursor inside an earlier layer is unaffected.
        let at_boundary = match self.sec {
            Section::Layer(i) => i >= boundary,
            Section::End => true,
            Section::Start => false,
        };
        if at_boundary {
            self.idx = 0;
            self.sec = if boundary < self.job.layers.len() {
                Section::Layer(boundary)
            } else {
                Section::End
            };
        }
        self.refresh_estimates();
        Ok(r)
    }

    /// Current state.
    pub fn state(&self) -> &State {
        &self.state
    }

    /// The pause method in use (known after M115).
    pub fn method(&self) -> Option<PauseMethod> {
        self.method
    }

    /// What M115 reported.
    pub fn capabilities(&self) -> &Capabilities {
        &self.caps
    }

    /// Progress figures.
    pub fn progress(&self) -> &Progress {
        &self.progress
    }

    /// Seconds since streaming started.
    pub fn elapsed_s(&self, now: Duration) -> f64 {
        self.started
            .map(|s| now.saturating_sub(s).as_secs_f64())
            .unwrap_or(0.0)
    }

    /// Estimated time left, s: the job's commanded-feed estimate of what is left, scaled by how
    /// fast the job has gone so far.
    pub fn time_left_s(&self, now: Duration) -> f64 {
        let p = &self.progress;
        let left = (p.est_total_s - p.est_done_s).max(0.0);
        let el = self.elapsed_s(now);
        if p.est_done_s > 1.0 && el > 1.0 {
            left * (el / p.est_done_s).clamp(0.2, 5.0)
        } else {
            left
        }
    }

    /// Takes the events produced since the last call.
    pub fn drain_events(&mut self) -> Vec<Event> {
        std::mem::take(&mut self.events)
    }

    /// Schedules a pause at the start of layer `index` (before any of its lines is sent).
    pub fn pause_before_layer(&mut self, index: usize) {
        self.pending = Some(Pending::AtLayer { gate: index });
    }

    /// True when the last pause was requested as "pause now" (it may have stopped mid-layer;
    /// edits then apply from the first layer not yet sent).
    pub fn pause_was_now(&self) -> bool {
        self.pause_now
    }

    /// The underlying port.
    pub fn port(&self) -> &P {
        &self.port
    }

    /// The underlying port, mutable.
    pub fn port_mut(&mut self) -> &mut P {
        &mut self.port
    }

    /// True once the session has ended (done, cancelled or failed).
    pub fn finished(&self) -> bool {
        matches!(
            self.state,
            State::Done | State::Cancelled | State::Failed(_)
        )
    }

    fn refresh_estimates(&mut self) {
        let (s, layers, e) = self.job.est_times_s();
        self.progress.lines_total = self.job.line_count();
        self.progress.layers = self.job.layers.len();
        self.progress.est_total_s = s + layers.iter().sum::<f64>() + e;
        let done: f64 = match self.sec {
            Section::Start => 0.0,
            Section::Layer(i) => s + layers.iter().take(i).sum::<f64>(),
            Section::End => s + layers.iter().sum::<f64>(),
        };
        self.progress.est_done_s = self.progress.est_done_s.max(done);
    }

    fn fail(&mut self, msg: impl Into<String>) {
        let m = msg.into();
        if !self.finished() {
            self.state = State::Failed(m.clone());
            self.events.push(Event::Failed(m));
        }
    }

    /// One step: reads what the printer sent, reacts, and sends the next line when the printer
    /// has room. Call it in a loop; the port's read timeout paces it.
    pub fn poll(&mut self, now: Duration) -> std::io::Result<()> {
        if self.finished() {
            return Ok(());
        }
        self.now = now;
        self.read_port(now)?;
        if self.finished() {
            return Ok(());
        }
        if self.state != State::Connecting
            && self.outstanding > 0
            && now.saturating_sub(self.last_ack) > self.opts.ok_timeout
        {
            self.nudge()?;
        }
        match self.state {
            State::Connecting => {
                let since = *self.connecting_since.get_or_insert(now);
                if now.saturating_sub(since) >= self.opts.connect_timeout {
                    self.fail(format!(
                        "no answer from the printer within {} s",
                        self.opts.connect_timeout.as_secs()
                    ));
                    return Ok(());
                }
                let due = self
                    .last_probe
                    .is_none_or(|t| now.saturating_sub(t) >= self.opts.probe_every);
                if due {
                    self.last_probe = Some(now);
                    // Numbered and checksummed (`N0 M110*cs`): a probe garbled on the wire is
                    // refused instead of setting the printer's line counter to a wrong value
                    // (our firmware would then take the next lines as duplicates).
                    self.write_raw(&format!("{}\n", frame(0, "M110")))?;
                }
                return Ok(());
            }
            State::Identifying => {
                if self
                    .identify_sent_at
                    .is_some_and(|t| now.saturating_sub(t) > IDENTIFY_TIMEOUT)
                {
                    self.fail(format!(
                        "the printer did not answer M115 within {} s",
                        IDENTIFY_TIMEOUT.as_secs()
                    ));
                    return Ok(());
                }
                if self.outstanding > 0
                    && now.saturating_sub(self.last_rx) > self.opts.silence_timeout
                {
                    self.fail(format!(
                        "no reply from the printer for {} s",
                        self.opts.silence_timeout.as_secs()
                    ));
                    return Ok(());
                }
            }
            State::Printing | State::Pausing => {
                if self.outstanding > 0
                    && now.saturating_sub(self.last_rx) > self.opts.silence_timeout
                {
                    self.fail(format!(
                        "no reply from the printer for {} s",
                        self.opts.silence_timeout.as_secs()
                    ));
                    return Ok(());
                }
            }
            State::Resuming => {
                if self
                    .resume_requested_at
                    .is_some_and(|t| now.saturating_sub(t) > RESUME_WAIT)
                {
                    self.events.push(Event::Note(format!(
                        "no //action:resumed after {} s: streaming again",
                        RESUME_WAIT.as_secs()
                    )));
                    self.state = State::Printing;
                    self.resume_requested_at = None;
                }
            }
            State::Paused { .. } => {}
            State::Done | State::Cancelled | State::Failed(_) => return Ok(()),
        }
        if let Some(t) = self.pause_requested_at {
            if matches!(self.state, State::Pausing)
                && now.saturating_sub(t) > Duration::from_secs(900)
            {
                self.fail("the printer did not confirm the pause within 900 s");
                return Ok(());
            }
        }
        self.send_next(now)
    }
}
