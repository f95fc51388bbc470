//! M400's owed `ok`. An M400 answers when the moves before it have ended (as Marlin's
//! `planner.synchronize()`); no further line is taken meanwhile. While the printer is parked
//! the moves before a job M400 are held until the resume, and a host that waits for that `ok`
//! before it sends anything else (printcore's and OctoPrint's send loops) could never send the
//! resume: so while parked the `ok` is paid as soon as the machine is at rest (nothing moves
//! until the resume), and its wait left in the queue is passed over when the job reaches it.
//! A manual M400 while parked (a console line) waits for the manual moves only.

use super::Intake;
use super::CMD_SLOTS;

/// Whose moves an owed M400 waits for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Owed {
    /// The job's: a [`super::Command::Sync`] is queued behind them.
    Queued,
    /// The manual moves of a parked printer (the service lane): nothing is queued.
    Manual,
}

/// The M400 `ok` owed, and the queued waits whose `ok` went out while parked.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct SyncOk {
    owed: Option<Owed>,
    /// Queued waits already answered (paid while parked), in queue order: they are ahead of
    /// any wait queued later, so the first ones reached are theirs.
    paid_early: u8,
}

// Every queued wait fits the count: the queue holds fewer.
const _: () = assert!(CMD_SLOTS < u8::MAX as usize);

impl SyncOk {
    pub(super) const NONE: SyncOk = SyncOk {
        owed: None,
        paid_early: 0,
    };
}

impl Intake {
    /// An M400 waits with its `ok` owed.
    pub(in crate::printer) fn sync_owed(&self) -> bool {
        self.sync.owed.is_some()
    }

    /// A job M400 queued its wait: its `ok` is owed.
    pub(in crate::printer) fn owe_sync(&mut self) {
        self.sync.owed = Some(Owed::Queued);
    }

    /// A manual M400 while parked: its `ok` is owed until the manual moves have ended.
    pub(in crate::printer) fn owe_manual_sync(&mut self) {
        self.sync.owed = Some(Owed::Manual);
    }

    /// A queued wait reached the front with the motion ended: whether an `ok` is to be paid
    /// (not when it was paid while parked).
    pub(in crate::printer) fn sync_reached(&mut self) -> bool {
        if self.sync.paid_early > 0 {
            self.sync.paid_early -= 1;
            return false;
        }
        self.sync.owed.take().is_some()
    }

    /// The owed wait was dropped with the queue (a cancel, a halt): whether an `ok` is to be
    /// paid.
    pub(in crate::printer) fn pay_sync(&mut self) -> bool {
        let owed = self.sync.owed.is_some();
        self.sync = SyncOk::NONE;
        owed
    }

    /// Pay an owed `ok` the machine's rest allows: `parked` and `service_busy` (manual
    /// moves queued or the head moving). Whether an `ok` is to be paid.
    pub(in crate::printer) fn pay_sync_at_rest(
        &mut self,
        parked: bool,
        service_busy: bool,
    ) -> bool {
        match self.sync.owed {
            Some(Owed::Manual) if !service_busy => {}
            Some(Owed::Queued) if parked && !service_busy => {
                self.sync.paid_early = self.sync.paid_early.saturating_add(1);
            }
            _ => return false,
        }
        self.sync.owed = None;
        true
    }
}
