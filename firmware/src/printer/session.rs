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
//!   of the job will not come. The job is *orphaned*: a running one gets a layer pause, which
//!   stops at the next boundary it holds or where the held lines end, and parks; a paused one
//!   stays parked. A resume of an orphaned job is refused (it would print the held lines and
//!   stop on the part); M524 cancels it, the head stays parked. No job line of a new session
//!   is taken behind it (they wait, with `busy:` keep-alives, until the cancel).
//! * **A host comes** while the printer is paused: it is told on its port, before anything
//!   else, `//action:paused` and an `echo:` saying which job is held and what M602 and M524
//!   do now; M27 says `state paused` as always.

use super::pause::Pause;
use super::{Printer, LINE_LEN};
use crate::link::{HostAction, PortId, Response};
use crate::motion::PauseMode;
use core::fmt::Write as _;

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
        self.intake.orphaned()
    }

    fn session_ended(&mut self, port: PortId) {
        self.host.reset_port(port);
        let host_job = self.intake.job_port() == Some(port) && !self.sd_printing();
        // Paused, or moves queued or moving: a host that leaves an idle printer (its job
        // ended, or only status lines since) leaves nothing behind to park for. Not
        // `in_job()`'s 2 s window: that counts a status line (M114) as a job's line.
        let in_job = !self.pause.running() || self.has_work();
        let orphan = host_job && in_job && !self.pause.halted() && !self.intake.cancelled();
        self.intake.session_ended(port, orphan);
        if !orphan {
            return;
        }
        self.host.notice(format_args!(
            "host on the {} port went away during its job: the job stops at a layer boundary \
             and parks; M524 ends it",
            port.name()
        ));
        if self.pause.running() {
            let (in_job, queued) = (self.in_job(), self.intake.len());
            self.pause
                .request_pause(PauseMode::Layer, in_job, queued, cx!(self));
        }
    }

    fn session_opened(&mut self, port: PortId) {
        let p = self.pause.state();
        if !matches!(
            p,
            Pause::Parked { .. } | Pause::Parking { .. } | Pause::Stopping { .. }
        ) || p.cancelling()
        {
            return;
        }
        // Before the layer the held job starts with (a stop at a boundary), else in the layer
        // the head stopped in: M27's counter is the last layer crossed, one below the next.
        let mut t: heapless::String<LINE_LEN> = heapless::String::new();
        let _ = match (p.before_layer(), self.job.layer()) {
            (Some(n), _) => write!(t, "paused: job held before layer {n}; "),
            (None, Some(l)) => write!(t, "paused: job held in layer {l}; "),
            (None, None) => write!(t, "paused: job held; "),
        };
        let _ = if self.intake.orphaned() {
            t.write_str("its host went away, so M602 cannot continue it: M524 ends it")
        } else {
            t.write_str("M602 resumes, M524 cancels")
        };
        let parked = self.pause.parked();
        self.host.respond_on(port, Response::Echo(&t));
        if parked {
            self.host
                .respond_on(port, Response::Action(HostAction::Paused, ""));
        }
    }
}
