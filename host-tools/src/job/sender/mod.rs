//! The sender: streams a [`Job`] to a printer over any `Read + Write` byte stream (a serial port,
//! a pseudo-terminal, or an in-memory fake printer in tests) with line numbers, XOR checksums and
//! `ok` flow control; handles `Resend:`, `busy:`, `echo:`, `Error:`, temperature reports and
//! `//action:` notifications; detects our layer-aware pause from M115; pauses at a layer
//! boundary (the firmware's pause, or the host-side [`fallback`] on stock firmware) so the rest
//! of the job can be edited with [`crate::job::ops`] before resuming.
//!
//! [`Session`] is a state machine driven by [`Session::poll`] with the current time, so tests run
//! it against a scripted printer without threads or a clock.

pub mod fallback;
pub mod protocol;
pub mod tui;

use std::collections::VecDeque;
use std::io::{ErrorKind, Read, Write};
use std::time::Duration;

use crate::job::gcode;
use crate::job::modal::Modal;
use crate::job::ops::PROMPT_PREFIX;
use crate::job::{Job, Section};
use fallback::HostPause;
use protocol::{frame, strip_comment, Action, Response, Temps};

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

/// What the printer reported in M115.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Capabilities {
    /// The `FIRMWARE_NAME:` line, when sent.
    pub firmware: Option<String>,
    /// Every `Cap:` line: name and enabled flag.
    pub caps: Vec<(String, bool)>,
}

impl Capabilities {
    /// Whether capability `name` was reported enabled.
    pub fn has(&self, name: &str) -> bool {
        self.caps.iter().any(|(n, e)| n == name && *e)
    }

    /// Whether the firmware has our layer-aware pause.
    pub fn layer_pause(&self) -> bool {
        LAYER_PAUSE_CAPS.iter().any(|c| self.has(c))
    }
}

/// Who performs the pause.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PauseMethod {
    /// Our firmware: realtime `M25` / `M25 S1`, `M24` to resume.
    Firmware,
    /// Stock firmware: split moves, stop at the layer end, host pause/resume sequences.
    HostSide,
}

/// A user's (or a script's) request.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Request {
    /// Finish the current layer, stop at its end, park.
    PauseAtLayer,
    /// Stop as soon as possible (mid-layer), park.
    PauseNow,
    /// Resume a paused job.
    Resume,
    /// Cancel the job.
    Cancel,
    /// M112.
    EmergencyStop,
}

/// Where the session is.
#[derive(Clone, Debug, PartialEq)]
pub enum State {
    /// Waiting for the printer to answer.
    Connecting,
    /// Sending M115 and waiting for its report.
    Identifying,
    /// Streaming the job.
    Printing,
    /// A pause is under way.
    Pausing,
    /// Paused. `boundary` is the first layer not yet sent when the pause is at a layer boundary
    /// (the job can then be edited from there); `None` for a pause in the middle of a layer.
    Paused {
        /// First unsent layer when paused at a boundary.
        boundary: Option<usize>,
        /// Text of a host prompt (`@pause`) that caused the pause.
        prompt: Option<String>,
    },
    /// Every line sent and acknowledged, motion finished.
    Done,
    /// Cancelled by request.
    Cancelled,
    /// Stopped on an error.
    Failed(String),
    /// Resume requested from the firmware; waiting for `//action:resumed`.
    Resuming,
}

/// Something worth telling the user.
#[derive(Clone, Debug, PartialEq)]
pub enum Event {
    /// M115 answered; the pause method chosen.
    Connected(PauseMethod),
    /// The host started sending layer `index`.
    Layer(usize),
    /// A pause was requested and is under way.
    Pausing,
    /// Paused (see [`State::Paused`]).
    Paused(Option<usize>),
    /// Resumed.
    Resumed,
    /// An `echo:` line or `//action:notification` from the printer.
    Message(String),
    /// The sender's own note (a request ignored, a resend decision, the speed-up...).
    Note(String),
    /// An `Error:` line from the printer.
    PrinterError(String),
    /// The printer asked for a resend.
    Resend(u32),
    /// The printer sent an `//action:` notification.
    Action(Action),
    /// Job complete.
    Done,
    /// Job cancelled.
    Cancelled,
    /// The session failed.
    Failed(String),
}

/// Session options.
#[derive(Clone, Debug)]
pub struct Options {
    /// Force a pause method instead of detecting it from M115.
    pub method: Option<PauseMethod>,
    /// Host-side pause parameters (fallback).
    pub host_pause: HostPause,
    /// Lines sent after M115 when our firmware's pause is used (e.g. `M760 S2 V10`: its
    /// speed-up factor and flow bound).
    pub firmware_setup: Vec<String>,
    /// Give up when the printer says nothing for this long while lines are outstanding.
    pub silence_timeout: Duration,
    /// Resend the oldest unacknowledged line when it has had no `ok` (and the printer no
    /// `busy:`) for this long: the line or its `ok` was lost on the wire. Temperature
    /// auto-reports do not count, so a lost `ok` never stalls the job behind them.
    pub ok_timeout: Duration,
    /// Re-send the connection probe this often until the printer answers.
    pub probe_every: Duration,
    /// Give up connecting after this long.
    pub connect_timeout: Duration,
    /// Ask for temperatures (M105) this often when the firmware does not auto-report.
    pub temp_every: Duration,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            method: None,
            host_pause: HostPause::default(),
            firmware_setup: Vec::new(),
            silence_timeout: Duration::from_secs(60),
            ok_timeout: Duration::from_secs(30),
            probe_every: Duration::from_secs(2),
            connect_timeout: Duration::from_secs(30),
            temp_every: Duration::from_secs(5),
        }
    }
}

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

/// Progress figures for displays.
#[derive(Clone, Debug, Default)]
pub struct Progress {
    /// Job lines sent (comment lines skipped count as sent).
    pub lines_sent: usize,
    /// Job lines in total.
    pub lines_total: usize,
    /// Layer being sent (index), if in the main code.
    pub layer: Option<usize>,
    /// Number of layers.
    pub layers: usize,
    /// Estimated print time of the lines sent, s.
    pub est_done_s: f64,
    /// Estimated print time of the whole job, s.
    pub est_total_s: f64,
    /// Last temperatures.
    pub temps: Temps,
    /// Resends served.
    pub resends: usize,
    /// Numbered lines written to the port (job, host sequences, split pieces, queries).
    pub lines_written: usize,
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

    /// Handles a request now. Realtime requests are written at once, ahead of queued lines.
    pub fn request(&mut self, r: Request, now: Duration) -> std::io::Result<()> {
        match r {
            Request::EmergencyStop => {
                self.write_realtime("M112", false)?;
                self.fail("emergency stop (M112) sent");
            }
            Request::Cancel => {
                if self.finished() {
                    return Ok(());
                }
                match self.method {
                    Some(PauseMethod::Firmware) => self.write_realtime("M524", true)?,
                    _ => self.write_realtime("M410", true)?,
                }
                self.queue.clear();
                self.state = State::Cancelled;
                self.events.push(Event::Cancelled);
            }
            Request::PauseAtLayer | Request::PauseNow => {
                if !matches!(self.state, State::Printing) {
                    self.events
                        .push(Event::Note("pause ignored: not printing".to_string()));
                    return Ok(());
                }
                self.pause_requested_at = Some(now);
                self.pause_now = r == Request::PauseNow;
                if r == Request::PauseNow {
                    self.pending = Some(Pending::Now);
                    if self.method == Some(PauseMethod::Firmware) {
                        self.write_realtime("M25 S1", true)?;
                    }
                } else {
                    self.normalize_cursor();
                    let gate = self.first_unsent_layer();
                    self.pending = Some(Pending::AtLayer { gate });
                    if self.method == Some(PauseMethod::Firmware) {
                        // React at once: the firmware speeds the layer up and stops at its next
                        // boundary; the host stops sending at the same layer end.
                        self.write_realtime("M25", true)?;
                    } else if self.opts.host_pause.speedup_factor > 1.0 {
                        let hp = &self.opts.host_pause;
                        self.events.push(Event::Note(format!(
                            "the rest of the layer runs up to ×{} (extrusion up to {} mm³/s)",
                            hp.speedup_factor, hp.max_volumetric_mm3_s
                        )));
                    }
                }
                self.state = State::Pausing;
                self.events.push(Event::Pausing);
            }
            Request::Resume => {
                let State::Paused { prompt, .. } = &self.state else {
                    self.events
                        .push(Event::Note("resume ignored: not paused".to_string()));
                    return Ok(());
                };
                let mut next = State::Printing;
                if prompt.is_none() {
                    if self.paused_by_firmware {
                        self.write_realtime("M24", true)?;
                        if std::mem::take(&mut self.scheduled) {
                            // A schedule hit while a pause was already in progress stays set
                            // in the firmware: clear it before the next layer arrives.
                            self.queue.push_back(Out::plain("M761 C"));
                        }
                        // Job lines wait until the firmware reports it is back at the pause
                        // point, so none is interpreted while it is still returning.
                        next = State::Resuming;
                        self.resume_requested_at = Some(now);
                    } else if let Some(m) = self.paused_modal.take() {
                        let seq = fallback::resume_sequence(&m, &self.opts.host_pause);
                        self.queue.extend(seq.into_iter().map(Out::plain));
                    }
                }
                self.paused_by_firmware = false;
                self.pending = None;
                self.state = next;
                self.events.push(Event::Resumed);
            }
        }
        Ok(())
    }

    fn fail(&mut self, msg: impl Into<String>) {
        let m = msg.into();
        if !self.finished() {
            self.state = State::Failed(m.clone());
            self.events.push(Event::Failed(m));
        }
    }

    /// Writes a realtime request at once, unnumbered, ahead of everything queued. Our firmware
    /// (and Marlin's emergency parser for M108/M410) still answers it with an `ok`, which is
    /// counted so it is not taken for the `ok` of a numbered line.
    fn write_realtime(&mut self, line: &str, answered: bool) -> std::io::Result<()> {
        if answered {
            self.rt_oks += 1;
        }
        self.write_raw(&format!("{line}\n"))
    }

    fn write_raw(&mut self, s: &str) -> std::io::Result<()> {
        self.port.write_all(s.as_bytes())?;
        self.port.flush()
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

    /// No `ok` for the oldest unacknowledged line within [`Options::ok_timeout`]: the line or
    /// its `ok` was lost. Resend it: a printer that never got it runs it now; one that did
    /// refuses the repeat by its line number (Marlin asks for the next line, ours acknowledges
    /// the duplicate), so it never runs twice. Every `ok` still owed is written off.
    fn nudge(&mut self) -> std::io::Result<()> {
        self.nudges += 1;
        let line = self.acked + 1;
        if self.nudges > MAX_NUDGES {
            self.fail(format!(
                "no ok from the printer for line {line}, sent {} times",
                MAX_NUDGES + 1
            ));
            return Ok(());
        }
        self.events.push(Event::Note(format!(
            "no ok for line {line} within {} s: resending it",
            self.opts.ok_timeout.as_secs()
        )));
        self.outstanding = 0;
        self.rt_oks = 0;
        self.rejected = true;
        self.last_ack = self.now;
        self.resend_from = (line < self.next_no).then_some(line);
        if self.resend_from.is_none() {
            // Every line is known taken (the printer said so in a `Resend:`); only the `ok`
            // was lost.
            self.settled(self.now)?;
        }
        Ok(())
    }

    fn read_port(&mut self, now: Duration) -> std::io::Result<()> {
        let mut buf = [0u8; 1024];
        match self.port.read(&mut buf) {
            Ok(0) => {}
            Ok(n) => {
                self.last_rx = now;
                self.rx.extend_from_slice(&buf[..n]);
            }
            Err(e)
                if matches!(
                    e.kind(),
                    ErrorKind::TimedOut | ErrorKind::WouldBlock | ErrorKind::Interrupted
                ) => {}
            Err(e) => return Err(e),
        }
        while let Some(pos) = self.rx.iter().position(|&b| b == b'\n') {
            let line: Vec<u8> = self.rx.drain(..=pos).collect();
            let text = String::from_utf8_lossy(&line).trim().to_string();
            if !text.is_empty() {
                if self.log_rx {
                    self.rx_log.push(text.clone());
                }
                self.handle_line(&text, now)?;
            }
        }
        if self.rx.len() > 4096 {
            self.rx.clear();
        }
        Ok(())
    }

    fn handle_line(&mut self, line: &str, now: Duration) -> std::io::Result<()> {
        if self.finished() {
            // Done, cancelled or failed: nothing the printer says changes that.
            return Ok(());
        }
        match Response::parse(line) {
            Response::Ok { temps, .. } => {
                if let Some(t) = temps {
                    self.progress.temps = t;
                }
                if self.state == State::Connecting {
                    if self.last_probe.is_none() {
                        // Left over from before this session (no probe written yet).
                        return Ok(());
                    }
                    self.state = State::Identifying;
                    self.next_no = 1;
                    self.acked = 0;
                    self.identify_sent_at = Some(now);
                    self.send_numbered("M115".to_string(), None)?;
                    return Ok(());
                }
                self.last_ack = now;
                self.error_resend = None;
                if self.rt_oks > 0 {
                    self.rt_oks -= 1;
                    return Ok(());
                }
                if self.outstanding > 0 {
                    self.nudges = 0;
                }
                self.outstanding = self.outstanding.saturating_sub(1);
                if self.outstanding == 0 && !self.rejected && self.last_written > self.acked {
                    self.acked = self.last_written;
                    self.suspect = None;
                    // Progress: "rejected N times in a row" counts from here.
                    self.last_resend = (0, 0);
                }
                self.settled(now)?;
            }
            Response::Resend(n) => {
                if self.error_resend.take() == Some(n) {
                    // Already handled from the `Error:…, Last Line: n-1` before it.
                    return Ok(());
                }
                self.resend_request(n, now)?;
            }
            Response::Busy(_) => self.last_ack = now,
            Response::Echo(e) => {
                if e.contains("nothing to pause") && self.state == State::Pausing {
                    // The firmware had already finished every queued move (the head waits at
                    // the boundary): park from the host.
                    let m = self.modal.clone();
                    let seq = fallback::pause_sequence(&m, &self.opts.host_pause);
                    self.paused_modal = Some(m);
                    self.queue.extend(seq.into_iter().map(Out::plain));
                    self.queue.push_back(Out {
                        line: "M400".into(),
                        sync: Some(Sync::HostParked),
                        tracked: true,
                    });
                }
                self.events.push(Event::Message(e));
            }
            Response::Error(e) => {
                let fatal = e.contains("halted") || e.contains("kill") || e.contains("Killed");
                self.events.push(Event::PrinterError(e.clone()));
                if fatal {
                    self.fail(format!("printer error: {e}"));
                    return Ok(());
                }
                // A line error (`Error:checksum mismatch, Last Line: L`, Marlin's and ours) is
                // followed by `Resend: L+1`; act on the error already, so a `Resend:` line lost
                // on the wire cannot make its `ok` look like an acceptance.
                if self.state == State::Connecting {
                    return Ok(());
                }
                if let Some(l) = protocol::last_line(&e) {
                    let n = l.saturating_add(1);
                    self.error_resend = Some(n);
                    self.resend_request(n, now)?;
                } else if protocol::is_link_error(&e) && self.acked < self.last_written {
                    // A checksum error without a line number: our line arrived with its `N`
                    // garbled, and no `Resend:` can follow. Resend the oldest line not
                    // acknowledged (a repeat is refused by the printer's counter).
                    let n = self.acked + 1;
                    self.resend_request(n, now)?;
                }
            }
            Response::Temperature(t) => self.progress.temps = t,
            Response::Action(a) => {
                self.events.push(Event::Action(a.clone()));
                match a {
                    Action::Paused => self.on_firmware_paused(),
                    Action::Resumed if self.state == State::Resuming => {
                        self.state = State::Printing;
                        self.resume_requested_at = None;
                    }
                    // Before the job has started there is nothing of ours to cancel (the printer
                    // may be asking an earlier host to stop).
                    Action::Cancel
                        if !self.finished()
                            && !matches!(self.state, State::Connecting | State::Identifying) =>
                    {
                        self.state = State::Cancelled;
                        self.events.push(Event::Cancelled);
                    }
                    Action::Pause => self.request(Request::PauseAtLayer, now)?,
                    // The printer asks to resume (its button) or announces its own return.
                    Action::Resume if matches!(self.state, State::Paused { .. }) => {
                        self.request(Request::Resume, now)?
                    }
                    Action::Notification(t) => self.events.push(Event::Message(t)),
                    _ => {}
                }
            }
            Response::FirmwareInfo(f) => self.caps.firmware = Some(f),
            Response::Capability { name, enabled } => self.caps.caps.push((name, enabled)),
            Response::Start => match self.state {
                State::Connecting => {}
                State::Identifying => {
                    // The board rebooted after the M115 query: connect again.
                    self.state = State::Connecting;
                    self.last_probe = None;
                    self.connecting_since = None;
                    self.identify_sent_at = None;
                    self.outstanding = 0;
                    self.rt_oks = 0;
                    self.resend_from = None;
                    self.history.clear();
                    self.caps = Capabilities::default();
                    self.events.push(Event::Note(
                        "the printer restarted while connecting: connecting again".into(),
                    ));
                }
                _ => self.fail("the printer restarted during the job"),
            },
            Response::Other(_) => {}
        }
        Ok(())
    }

    /// Every line written is answered and none waits to be resent: finish identifying, or act
    /// on the synchronising line (the last one written) now that it is taken.
    fn settled(&mut self, now: Duration) -> std::io::Result<()> {
        if self.outstanding > 0 || self.resend_from.is_some() {
            return Ok(());
        }
        if self.state == State::Identifying {
            self.identified(now);
            return Ok(());
        }
        if let Some((no, _)) = &self.sync {
            if no + 1 == self.next_no {
                if let Some((_, kind)) = self.sync.take() {
                    self.on_synced(kind)?;
                }
            }
        }
        Ok(())
    }

    /// A resend request for line `n` (from `Resend:` or a line error): counted, then
    /// [`Session::on_resend`].
    fn resend_request(&mut self, n: u32, now: Duration) -> std::io::Result<()> {
        self.progress.resends += 1;
        if self.last_resend.0 == n {
            self.last_resend.1 += 1;
        } else {
            self.last_resend = (n, 1);
        }
        if self.last_resend.1 > MAX_RESENDS {
            self.fail(format!(
                "the printer rejected line {n} {MAX_RESENDS} times in a row"
            ));
            return Ok(());
        }
        self.events.push(Event::Resend(n));
        self.last_ack = now;
        self.on_resend(n)
    }

    /// M115 answered (its `ok`): choose the pause method and start streaming.
    fn identified(&mut self, now: Duration) {
        self.identify_sent_at = None;
        let method = self.opts.method.unwrap_or(if self.caps.layer_pause() {
            PauseMethod::Firmware
        } else {
            PauseMethod::HostSide
        });
        self.method = Some(method);
        self.state = if matches!(self.pending, Some(Pending::Now)) {
            State::Pausing
        } else {
            State::Printing
        };
        self.started = Some(now);
        self.last_temp_req = now;
        if self.caps.has("AUTOREPORT_TEMP") {
            self.queue.push_back(Out::plain("M155 S2"));
        }
        if method == PauseMethod::Firmware {
            let setup = self.opts.firmware_setup.clone();
            self.queue.extend(setup.into_iter().map(Out::plain));
        }
        if let (PauseMethod::Firmware, Some(Pending::AtLayer { gate })) = (method, &self.pending) {
            // The firmware counts layers with the same detector over the same stream: schedule
            // the pause there too (M761), so it holds at the mark however fast it drains its
            // queue.
            if let Some(l) = self.job.layers.get(*gate) {
                let line = format!("M761 L{}", l.number);
                self.queue.push_back(Out::plain(line));
                self.scheduled = true;
            }
        }
        self.events.push(Event::Connected(method));
    }

    /// `Resend: n`. The printer's line counter says it accepted every line up to `n - 1`:
    ///
    /// - `acked < n < next_no`, a line sent but not known accepted: the usual case (checksum
    ///   error, lost line) — resend from `n`;
    /// - `n == next_no`: the printer has every line sent (it refused a repeat) — nothing to
    ///   resend;
    /// - `acked - n < ACK_DOUBT` (`n` one of the last lines taken as acknowledged): an `ok`
    ///   was not that line's (a doubled `ok`, or the `Error:`/`Resend:` of its refusal lost on
    ///   the wire so only the `ok` arrived) — resend from `n`; the printer's counter refuses
    ///   anything it already has;
    /// - anything else — a line acknowledged earlier (its counter went back: a reset that printed
    ///   no `start`, an `M110` from elsewhere, `Resend: 0`), or a line never sent (its counter is
    ///   ahead): resending from `n` would run acknowledged lines a second time, and sending on
    ///   would be refused line after line. The first time, the sender resends from the first
    ///   line not acknowledged (the number may have been garbled on the wire; a repeat is
    ///   refused by a printer whose counter is right); when the printer asks for the same line
    ///   [`RESYNC_AFTER`] times in a row, it sets the printer's counter to the last line it acknowledged (`N<acked>
    ///   M110*cs`), resends from the first line not acknowledged, and says so in a message.
    ///
    /// Before the printer has answered the connection probe there is nothing to resend: ignored.
    fn on_resend(&mut self, n: u32) -> std::io::Result<()> {
        if self.state == State::Connecting {
            self.events.push(Event::Note(format!(
                "Resend: {n} before the connection was made: ignored"
            )));
            return Ok(());
        }
        self.rejected = true;
        if n > self.acked && n < self.next_no {
            self.resend_from = Some(n);
            return Ok(());
        }
        if n == self.next_no && self.suspect.is_none() {
            self.acked = n - 1;
            self.resend_from = None;
            self.events.push(Event::Note(format!(
                "the printer asked for line {n}, which is not sent yet: nothing to resend"
            )));
            return Ok(());
        }
        if n > 0 && n <= self.acked && self.acked - n < ACK_DOUBT {
            self.acked = n - 1;
            self.resend_from = Some(n);
            self.events.push(Event::Note(format!(
                "the printer asked again for line {n}, taken as acknowledged (a doubled ok, or \
                 a refusal garbled on the wire?): resending from it"
            )));
            return Ok(());
        }
        let k = self.acked;
        let seen = match self.suspect {
            Some((m, c)) if m == n => c + 1,
            _ => 1,
        };
        if seen < RESYNC_AFTER {
            // Could be a line number garbled on the wire: resend the first line not
            // acknowledged (a repeat is refused by the printer's counter if it is right) and
            // set the counter only if the printer keeps asking for the same line.
            self.suspect = Some((n, seen));
            self.resend_from = (k + 1 < self.next_no).then_some(k + 1);
            self.events.push(Event::Note(format!(
                "the printer asked for line {n}, but it had acknowledged every line up to {k}: \
                 resending from line {}",
                k + 1
            )));
            return Ok(());
        }
        self.suspect = None;
        self.events.push(Event::Note(format!(
            "the printer asked for line {n}, but it had acknowledged every line up to {k}: \
             asked {RESYNC_AFTER} times: its line counter is out of step (reset or M110?); setting it back \
             with N{k} M110 and resending from line {}",
            k + 1
        )));
        // Checksummed, like the connection probe: a garbled one is refused, not obeyed.
        self.write_realtime(&frame(k, "M110"), true)?;
        self.resend_from = (k + 1 < self.next_no).then_some(k + 1);
        Ok(())
    }

    fn at_boundary(&self) -> Option<usize> {
        match (self.sec, self.idx) {
            (Section::Layer(i), 0) => Some(i),
            (Section::End, 0) => Some(self.job.layers.len()),
            _ => None,
        }
    }

    fn on_firmware_paused(&mut self) {
        if !matches!(self.state, State::Pausing | State::Printing) {
            return;
        }
        self.paused_by_firmware = true;
        let b = self.first_unsent_layer();
        self.enter_paused(Some(b), None);
    }

    fn enter_paused(&mut self, boundary: Option<usize>, prompt: Option<String>) {
        self.state = State::Paused { boundary, prompt };
        self.pause_requested_at = None;
        self.events.push(Event::Paused(boundary));
    }

    fn on_synced(&mut self, kind: Sync) -> std::io::Result<()> {
        if self.finished() {
            return Ok(());
        }
        match kind {
            Sync::Trigger => {
                if self.state == State::Pausing {
                    self.write_realtime("M25", true)?;
                }
            }
            Sync::HostDrain => {
                let m = self.modal.clone();
                let seq = fallback::pause_sequence(&m, &self.opts.host_pause);
                self.paused_modal = Some(m);
                self.queue.extend(seq.into_iter().map(Out::plain));
                self.queue.push_back(Out {
                    line: "M400".into(),
                    sync: Some(Sync::HostParked),
                    tracked: true,
                });
            }
            Sync::HostParked => {
                let b = self.first_unsent_layer();
                self.enter_paused(Some(b), None);
            }
            Sync::Prompt(text) => {
                let b = self.at_boundary();
                self.enter_paused(b, Some(text));
            }
            Sync::Finish => {
                self.state = State::Done;
                self.events.push(Event::Done);
            }
        }
        Ok(())
    }

    fn send_numbered(&mut self, line: String, sync: Option<Sync>) -> std::io::Result<()> {
        let no = self.next_no;
        let framed = frame(no, &line);
        self.next_no += 1;
        self.history.push_back((no, framed.clone()));
        while self.history.len() > HISTORY_LINES {
            self.history.pop_front();
        }
        self.outstanding += 1;
        self.last_ack = self.now;
        self.last_written = no;
        self.rejected = false;
        self.progress.lines_written += 1;
        if let Some(k) = sync {
            self.sync = Some((no, k));
        }
        self.write_raw(&format!("{framed}\n"))
    }

    fn send_next(&mut self, now: Duration) -> std::io::Result<()> {
        if self.outstanding > 0 {
            return Ok(());
        }
        if let Some(n) = self.resend_from {
            let framed = self
                .history
                .iter()
                .find(|(no, _)| *no == n)
                .map(|(_, f)| f.clone());
            let Some(framed) = framed else {
                self.fail(format!("line {n} is not in the history"));
                return Ok(());
            };
            self.resend_from = (n + 1 < self.next_no).then_some(n + 1);
            self.outstanding += 1;
            self.last_ack = self.now;
            self.last_written = n;
            self.rejected = false;
            return self.write_raw(&format!("{framed}\n"));
        }
        if self.sync.is_some() {
            return Ok(());
        }
        let streaming = matches!(self.state, State::Printing | State::Pausing);
        if streaming
            && !self.caps.has("AUTOREPORT_TEMP")
            && now.saturating_sub(self.last_temp_req) >= self.opts.temp_every
        {
            self.last_temp_req = now;
            return self.send_numbered("M105".into(), None);
        }
        if let Some(out) = self.queue.pop_front() {
            if out.tracked {
                self.track(&out.line);
            }
            return self.send_numbered(out.line, out.sync);
        }
        if !streaming {
            return Ok(());
        }
        // Pause gating.
        self.normalize_cursor();
        match self.pending.clone() {
            Some(Pending::Now) => {
                if self.state == State::Pausing {
                    if self.method == Some(PauseMethod::HostSide) {
                        self.pending = None;
                        return self.send_numbered("M400".into(), Some(Sync::HostDrain));
                    }
                    // Firmware: wait for //action:paused.
                    return Ok(());
                }
            }
            Some(Pending::AtLayer { .. }) => {
                if self.at_gate() {
                    self.pending = None;
                    if self.state == State::Printing {
                        self.state = State::Pausing;
                        self.pause_requested_at = Some(now);
                        self.events.push(Event::Pausing);
                    }
                    return match self.method {
                        Some(PauseMethod::Firmware) => {
                            // The layer's marker comments are sent; the firmware places the
                            // mark before the next command. A harmless command delivers it, so
                            // the firmware stops at this boundary without any line of the next
                            // layer (which may still be edited).
                            self.send_numbered("M400".into(), Some(Sync::Trigger))
                        }
                        _ => {
                            let m = self.modal.clone();
                            let seq = fallback::pause_sequence(&m, &self.opts.host_pause);
                            self.paused_modal = Some(m);
                            self.queue.extend(seq.into_iter().map(Out::plain));
                            self.queue.push_back(Out {
                                line: "M400".into(),
                                sync: Some(Sync::HostParked),
                                tracked: true,
                            });
                            self.send_next(now)
                        }
                    };
                }
            }
            None => {
                if self.state == State::Pausing {
                    return Ok(());
                }
            }
        }
        // Next job line.
        loop {
            if self.at_gate() {
                // Skipped lines brought the cursor to the gate: gate on the next poll.
                return Ok(());
            }
            let Some(raw) = self.next_job_line() else {
                return self.send_numbered("M400".into(), Some(Sync::Finish));
            };
            let trimmed = raw.trim();
            if let Some(text) = trimmed.strip_prefix(PROMPT_PREFIX) {
                self.state = State::Pausing;
                self.pending = None;
                return self.send_numbered("M400".into(), Some(Sync::Prompt(text.trim().into())));
            }
            if trimmed.starts_with('@') {
                continue;
            }
            let code = strip_comment(trimmed);
            let cap = match self.method {
                Some(PauseMethod::Firmware) => LINE_CAP_FIRMWARE,
                _ => LINE_CAP_STOCK,
            };
            if code.is_empty() {
                // Our firmware's layer detector reads slicer comments: send comment-only lines
                // (layer markers are short; long comments such as the slicer's settings dump
                // are skipped, and so are comments with a `*`, which the link would take for
                // a merged checksum and refuse).
                if self.method == Some(PauseMethod::Firmware)
                    && trimmed.starts_with(';')
                    && !trimmed.contains('*')
                    && frame(self.next_no, trimmed).len() < cap
                {
                    let line = trimmed.to_string();
                    return self.send_numbered(line, None);
                }
                continue;
            }
            if frame(self.next_no, code).len() >= cap {
                self.fail(format!(
                    "job line {code:?} is longer than the printer accepts ({cap} bytes with line number and checksum)"
                ));
                return Ok(());
            }
            let code = code.to_string();
            if self.method == Some(PauseMethod::HostSide) && matches!(self.sec, Section::Layer(_)) {
                if let Ok(Some(cmd)) = gcode::parse(&code) {
                    let hp = &self.opts.host_pause;
                    // After a layer pause request every move of the rest of the layer carries
                    // its own (sped-up) feed.
                    let feed = if self.speeding_up() {
                        let mut after = self.modal.clone();
                        after
                            .apply(&cmd)
                            .and_then(|mv| fallback::sped_up_feed_mm_min(&mv, hp))
                    } else {
                        None
                    };
                    if let Some(pieces) =
                        fallback::rewrite_move(&cmd, &self.modal, hp.split_mm, feed)
                    {
                        let mut it = pieces.into_iter();
                        if let Some(first) = it.next() {
                            self.queue.extend(it.map(Out::piece));
                            self.track(&code);
                            return self.send_numbered(first, None);
                        }
                    }
                }
            }
            self.track(&code);
            return self.send_numbered(code, None);
        }
    }

    /// True while the rest of a layer runs faster on the host side: a layer pause was requested
    /// (interactively: a pause scheduled with [`Session::pause_before_layer`] keeps the job's
    /// speeds) and the layer has not ended yet.
    fn speeding_up(&self) -> bool {
        self.method == Some(PauseMethod::HostSide)
            && self.state == State::Pausing
            && matches!(self.pending, Some(Pending::AtLayer { .. }))
            && self.opts.host_pause.speedup_factor > 1.0
    }

    /// Updates the modal state and the time estimate with a line about to be sent.
    fn track(&mut self, line: &str) {
        if let Ok(Some(cmd)) = gcode::parse(line) {
            if let Some(mv) = self.modal.apply(&cmd) {
                self.progress.est_done_s += mv.est_time_s();
            }
        }
    }

    /// True when a layer pause is pending and the (normalized) cursor has reached its gate.
    fn at_gate(&mut self) -> bool {
        let Some(Pending::AtLayer { gate }) = self.pending else {
            return false;
        };
        self.normalize_cursor();
        match self.sec {
            Section::Layer(i) => i > gate || (i == gate && self.idx == 0),
            Section::End => true,
            Section::Start => false,
        }
    }

    /// Moves the cursor past exhausted sections (without taking a line).
    fn normalize_cursor(&mut self) {
        while self.idx >= self.job.section(self.sec).len() {
            let next = match self.sec {
                Section::Start if self.job.layers.is_empty() => Section::End,
                Section::Start => Section::Layer(0),
                Section::Layer(i) if i + 1 < self.job.layers.len() => Section::Layer(i + 1),
                Section::Layer(_) => Section::End,
                Section::End => return,
            };
            self.sec = next;
            self.idx = 0;
        }
    }

    /// Takes the next raw job line at the (normalized) cursor; `None` at the end of the job.
    fn next_job_line(&mut self) -> Option<String> {
        self.normalize_cursor();
        let l = self.job.section(self.sec).get(self.idx)?.clone();
        if self.idx == 0 {
            if let Section::Layer(i) = self.sec {
                self.progress.layer = Some(i);
                self.events.push(Event::Layer(i));
            }
        }
        self.idx += 1;
        self.progress.lines_sent += 1;
        Some(l)
    }
}
