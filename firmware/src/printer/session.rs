//! Host sessions: what the printer does when the host on a port goes away and when one comes
//! (docs/frontend.md, "A session that ends while paused").
//!
//! The driver tells the executive ([`Printer::port_session`]): on the board the USB CDC port's
//! line state (DTR set when a host opens the port, cleared when it closes it; a USB reset or
//! unplug ends it too), in the simulator the pseudo-terminal (a host has it open or not).
//! The TFT UART has no such signal: a TFT is always connected.
//!
//! * **The job's host goes away** (the port that streamed the job being printed: paused, or
//!   moves queued or moving; a job read from the SD card has no host and goes on): the rest
//!   of the job will not come. The job is *orphaned*: a running one gets a layer pause, which stops at the next
//!   boundary it holds or where the held lines end, and parks; a paused one stays parked. A
//!   resume of an orphaned job is refused (it would print the held lines and stop on the
//!   part); M524 cancels it, the head stays parked. No job line of a new session is taken
//!   behind it (they wait, with `busy:` keep-alives, until the cancel).
//! * **A host comes** while the printer is paused: it is told on its port, before anything
//!   else, `//action:paused` and an `echo:` saying which job is held and what M602 and M524
//!   do now; M27 says `state paused` as always.

use super::state::Pause;
use super::Printer;
use crate::link::{HostAction, PortId, Response};
use crate::motion::PauseMode;

impl Printer {
    /// The host on `port` came (`open`) or went away (see the module documentation).
    pub fn port_session(&mut self, port: PortId, open: bool, now_us: u64) {
        self.set_now(now_us);
        if open {
            self.session_opened(port);
        } else {
            self.session_ended(port);
        }
        self.update_state_record();
    }

    /// Whether the job held or running has lost the host that streamed it.
    pub fn job_orphaned(&self) -> bool {
        self.lines.orphaned
    }

    fn session_ended(&mut self, port: PortId) {
        self.link.reset_port(port);
        if self.lines.held_port == Some(port) {
            // Never acknowledged, and nobody is left to expect its `ok`.
            self.lines.held_line = None;
            self.lines.held_port = None;
        }
        let host_job = self.lines.job_port == Some(port) && !self.sd_printing();
        // Paused, or moves queued or moving: a host that leaves an idle printer (its job
        // ended, or only status lines since) leaves nothing behind to park for. Not
        // `in_job()`'s 2 s window: that counts a status line (M114) as a job's line.
        let in_job = !matches!(self.pause, Pause::Run) || self.has_work();
        if !host_job || !in_job || self.is_halted() || self.lines.after_cancel.is_some() {
            return;
        }
        self.lines.orphaned = true;
        self.notice(format_args!(
            "host on the {} port went away during its job: the job stops at a layer boundary \
             and parks; M524 ends it",
            port.name()
        ));
        if matches!(self.pause, Pause::Run) {
            self.request_pause(PauseMode::Layer);
        }
    }

    fn session_opened(&mut self, port: PortId) {
        if !matches!(
            self.pause,
            Pause::Parked { .. } | Pause::Parking { .. } | Pause::Stopping { .. }
        ) || self.pause.cancelling()
        {
            return;
        }
        // Before the layer the held job starts with (a stop at a boundary), else in the layer
        // the head stopped in: M27's counter is the last layer crossed, one below the next.
        let before = match &self.pause {
            Pause::Stopping {
                how: super::state::Stop::Barrier { layer },
                ..
            } => *layer,
            p => p.held().and_then(|h| h.before_layer),
        };
        let mut t: heapless::String<{ super::LINE_LEN }> = heapless::String::new();
        use core::fmt::Write as _;
        let _ = match (before, self.layer) {
            (Some(n), _) => write!(t, "paused: job held before layer {n}; "),
            (None, Some(l)) => write!(t, "paused: job held in layer {l}; "),
            (None, None) => write!(t, "paused: job held; "),
        };
        let _ = if self.lines.orphaned {
            t.write_str("its host went away, so M602 cannot continue it: M524 ends it")
        } else {
            t.write_str("M602 resumes, M524 cancels")
        };
        self.link.respond_on(port, Response::Echo(&t));
        if matches!(self.pause, Pause::Parked { .. }) {
            self.link
                .respond_on(port, Response::Action(HostAction::Paused, ""));
        }
    }
}
