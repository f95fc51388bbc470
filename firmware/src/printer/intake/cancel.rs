//! The tail of a cancelled job. After a cancel, the host may still stream the rest of the job
//! (printcore ignores `//action:cancel`; lines were in flight): those lines are discarded
//! (answered `ok`, never executed) until the host starts anew — a numbered line whose number
//! is not beyond the last one taken before the cancel (the host reset its line numbers with
//! M110, as printcore and OctoPrint do at a job's start), or any line after the host was
//! silent for [`LAYER_PAUSE_IDLE_US`]. Unnumbered lines from a host that numbers its job
//! (OctoPrint's cancel script, a console command) are taken.

use super::{Intake, LAYER_PAUSE_IDLE_US};
use crate::link::ReceivedLine;
use crate::printer::host::Host;

/// What the discarding knows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct AfterCancel {
    /// The last numbered line taken before the cancel.
    after: Option<u32>,
    /// Lines discarded so far.
    discarded: u32,
}

impl AfterCancel {
    pub(super) fn new(after: Option<u32>) -> Self {
        Self {
            after,
            discarded: 0,
        }
    }
}

impl Intake {
    /// Whether `line` is the rest of a cancelled job: then it is counted and must be answered
    /// `ok` without being executed. Ends the discarding when the host has started anew.
    pub(in crate::printer) fn discard_after_cancel(
        &mut self,
        line: &ReceivedLine,
        reset: bool,
        now_us: u64,
        host: &mut Host,
    ) -> bool {
        let Some(mut a) = self.after_cancel else {
            return false;
        };
        let silent_us = now_us.saturating_sub(self.last_activity_us);
        let fresh = silent_us >= LAYER_PAUSE_IDLE_US
            || (reset && line.number().is_some())
            || match (line.number(), a.after) {
                // Numbers restarted (M110): a new job.
                (Some(n), Some(after)) => n <= after,
                (Some(_), None) => false,
                // A host that numbers its job sends its own commands unnumbered.
                (None, _) => self.host_numbers,
            };
        self.last_activity_us = now_us;
        if fresh {
            if line.number().is_some() || silent_us >= LAYER_PAUSE_IDLE_US {
                if a.discarded > 0 {
                    host.say(format_args!(
                        "cancelled: {} lines of the cancelled job discarded",
                        a.discarded
                    ));
                }
                self.after_cancel = None;
            }
            return false;
        }
        if a.discarded == 0 {
            host.say(format_args!(
                "cancelled: discarding the rest of the job until the host starts anew"
            ));
        }
        a.discarded = a.discarded.saturating_add(1);
        self.after_cancel = Some(a);
        true
    }
}
