//! The session's public vocabulary: what M115 reported ([`Capabilities`]), the pause method,
//! requests, states, events, options and progress figures.

use std::time::Duration;

use super::fallback::HostPause;
use super::protocol::{Action, Temps};
use super::LAYER_PAUSE_CAPS;

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
