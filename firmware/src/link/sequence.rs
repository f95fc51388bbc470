//! Line-number bookkeeping (Marlin behaviour): the next line is taken, a recent duplicate is
//! acknowledged, a gap asks for a resend; realtime lines act once however they arrive.

use super::{HostLink, ReceivedLine, Response, DUPLICATE_WINDOW};
use crate::motion::Realtime;

/// How a line's number compares with the expected one.
pub(super) enum Seq {
    Next,
    Duplicate,
    Gap,
}

impl HostLink {
    /// Refuse a line and ask for `L+1` again (Marlin: error, `Resend:`, `ok`).
    pub(super) fn resend(&mut self, msg: &str) {
        self.stats.rejected = self.stats.rejected.saturating_add(1);
        self.respond(Response::LineError(msg, self.last_line));
        self.stats.resends = self.stats.resends.saturating_add(1);
        self.respond(Response::Resend(self.last_line.wrapping_add(1)));
        self.respond(Response::Ok);
    }

    /// Whether a command line with this number would go into the FIFO.
    pub(super) fn takes_slot(&self, number: Option<u32>) -> bool {
        number.is_none_or(|n| matches!(self.seq(n), Seq::Next))
    }

    pub(super) fn seq(&self, n: u32) -> Seq {
        if n == self.last_line.wrapping_add(1) {
            Seq::Next
        } else if n <= self.last_line && self.last_line - n < DUPLICATE_WINDOW {
            Seq::Duplicate
        } else {
            Seq::Gap
        }
    }

    /// Line-number bookkeeping for a line that is not realtime: true (and `L` advanced) when
    /// the line is to be handled; a duplicate is acknowledged, a gap asks for a resend.
    pub(super) fn number_ok(&mut self, number: Option<u32>) -> bool {
        let Some(n) = number else {
            return true;
        };
        match self.seq(n) {
            Seq::Next => {
                self.last_line = n;
                true
            }
            Seq::Duplicate => {
                self.stats.duplicates = self.stats.duplicates.saturating_add(1);
                self.respond(Response::Ok);
                false
            }
            Seq::Gap => {
                self.resend("Line Number is not Last Line Number+1");
                false
            }
        }
    }

    /// A realtime line taken; `acted`: the emergency scan acted on it already (or knew it for
    /// a resent line that had acted), so only its number and its `ok` are left to do.
    pub(super) fn realtime_line(&mut self, number: Option<u32>, rt: Realtime, acted: bool) {
        // M112 halts: like Marlin's kill(), no `ok`.
        let answer = rt != Realtime::EmergencyStop;
        let Some(n) = number else {
            if !acted {
                self.push_realtime(rt);
            }
            if answer {
                self.respond(Response::Ok);
            }
            return;
        };
        match self.seq(n) {
            Seq::Next => {
                // Acted already when it first arrived ahead of its turn?
                if self.early != Some((n, rt)) && !acted {
                    self.push_realtime(rt);
                }
                self.early = None;
                self.last_line = n;
                if answer {
                    self.respond(Response::Ok);
                }
            }
            Seq::Duplicate => {
                self.stats.duplicates = self.stats.duplicates.saturating_add(1);
                self.respond(Response::Ok);
            }
            Seq::Gap => {
                if self.early != Some((n, rt)) && !acted {
                    self.push_realtime(rt);
                    self.early = Some((n, rt));
                }
                if answer {
                    self.resend("Line Number is not Last Line Number+1");
                }
            }
        }
    }

    /// A checked command line for the FIFO (room was checked).
    pub(super) fn command_line(&mut self, mut line: ReceivedLine) {
        if !self.number_ok(line.number) {
            return;
        }
        line.after_reset = core::mem::take(&mut self.reset_pending);
        if self.lines.push_back(line).is_ok() {
            self.stats.lines = self.stats.lines.saturating_add(1);
        }
    }
}
