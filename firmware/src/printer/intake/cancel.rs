//! The tail of a cancelled job. After a cancel, the host may still stream the rest of the job
//! (printcore ignores `//action:cancel`; lines were in flight). Those lines are discarded
//! (answered `ok`, never executed) until the host starts anew — a numbered line whose number
//! is not beyond the last one taken before the cancel (the host reset its line numbers with
//! M110, as printcore and OctoPrint do at a job's start), or any line after the host sent no
//! discarded line for [`LAYER_PAUSE_IDLE_US`]. Unnumbered lines from a host that numbers its
//! job (OctoPrint's cancel script, a console command) are taken.
//!
//! Some lines of the tail are honoured, not discarded: those that only make the machine safer
//! or report ([`honoured_in_tail`]: heaters and fan off, motors off, temperature, position and
//! status reports). They neither extend the discarding (a host polling M105 every second does
//! not keep the discarding going) nor end it. Moves, homing, heat-ups, settings and the job's
//! messages are discarded (docs/frontend.md, "Cancel").

use super::{Intake, LAYER_PAUSE_IDLE_US};
use crate::gcode::{Command, DriverCommand, HeatCommand, ReportCommand};
use crate::link::ReceivedLine;
use crate::printer::host::Host;

/// What the discarding knows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct AfterCancel {
    /// The last numbered line taken before the cancel.
    after: Option<u32>,
    /// Lines discarded so far.
    discarded: u32,
    /// When the last line was discarded (or the cancel completed), in ms of the printer's
    /// clock (`u32`: 49 days wrap; only differences of a few seconds are asked of it).
    last_discard_ms: u32,
}

impl AfterCancel {
    pub(super) fn new(after: Option<u32>) -> Self {
        Self {
            after,
            discarded: 0,
            last_discard_ms: 0,
        }
    }
}

/// `now_us` as the wrapping millisecond count [`AfterCancel`] keeps.
fn ms(now_us: u64) -> u32 {
    (now_us / 1000) as u32
}

/// What a cancelled job's tail does with a line (see [`Intake::after_cancel`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(in crate::printer) enum TailLine {
    /// Not part of a cancelled job's tail (no cancel, or the host started anew): taken.
    Take,
    /// Part of the tail but safe to run (cooling, motors off, a report): taken.
    Honour,
    /// Part of the tail: answered `ok`, never executed.
    Discard,
}

/// Whether a line of a cancelled job's tail is run anyway: it can only make the machine safer
/// (a heater or the fan off, motors off) or report (temperatures, position, status, endstops,
/// firmware). A heater target other than 0 (a heat-up, or a standby temperature) is not, nor
/// a wait (M109/M190): the cancel switched the heaters off. Moves and homing are not: the
/// cancel parked the head; a tail's "present the bed" move is the file's, not the host's.
pub(in crate::printer) fn honoured_in_tail(cmd: &Command) -> bool {
    match cmd {
        Command::Heat(HeatCommand::SetTemperature {
            wait: false, s, r, ..
        }) => matches!(r.or(*s), Some(t) if t <= 0.0),
        Command::Heat(HeatCommand::FanOff { .. }) => true,
        Command::Heat(HeatCommand::FanOn { speed, .. }) => matches!(speed, Some(s) if *s <= 0.0),
        Command::Driver(DriverCommand::DisableSteppers { .. }) => true,
        Command::Heat(HeatCommand::Report) => true,
        Command::Report(r) => matches!(
            r,
            ReportCommand::Position
                | ReportCommand::Endstops
                | ReportCommand::FirmwareInfo
                | ReportCommand::PrintTime
                | ReportCommand::JobStatus
                | ReportCommand::AutoTemp(_)
        ),
        _ => false,
    }
}

impl Intake {
    /// What the rest of a cancelled job does with `line` ([`TailLine`]); a discarded line is
    /// counted and must be answered `ok` without being executed. Ends the discarding when
    /// the host has started anew.
    pub(in crate::printer) fn after_cancel(
        &mut self,
        line: &ReceivedLine,
        reset: bool,
        now_us: u64,
        host: &mut Host,
    ) -> TailLine {
        let Some(mut a) = self.after_cancel else {
            return TailLine::Take;
        };
        let quiet_ms = ms(now_us).wrapping_sub(a.last_discard_ms);
        let quiet = u64::from(quiet_ms) * 1000 >= LAYER_PAUSE_IDLE_US;
        let fresh = quiet
            || (reset && line.number().is_some())
            || match (line.number(), a.after) {
                // Numbers restarted (M110): a new job.
                (Some(n), Some(after)) => n <= after,
                (Some(_), None) => false,
                // A host that numbers its job sends its own commands unnumbered.
                (None, _) => self.host_numbers,
            };
        if fresh {
            if line.number().is_some() || quiet {
                if a.discarded > 0 {
                    host.say(format_args!(
                        "cancelled: {} lines of the cancelled job discarded",
                        a.discarded
                    ));
                }
                self.after_cancel = None;
            }
            return TailLine::Take;
        }
        if line
            .parse()
            .is_ok_and(|l| l.command.as_ref().is_some_and(honoured_in_tail))
        {
            return TailLine::Honour;
        }
        self.last_activity_us = now_us;
        if a.discarded == 0 {
            host.say(format_args!(
                "cancelled: discarding the rest of the job until the host starts anew"
            ));
        }
        a.discarded = a.discarded.saturating_add(1);
        a.last_discard_ms = ms(now_us);
        self.after_cancel = Some(a);
        TailLine::Discard
    }

    /// The cancel completed: the host's silence is measured from here (lines that waited
    /// during the cancel's park are not a fresh start).
    pub(in crate::printer) fn cancel_done(&mut self, now_us: u64) {
        self.last_activity_us = now_us;
        if let Some(a) = self.after_cancel.as_mut() {
            a.last_discard_ms = ms(now_us);
        }
    }
}
