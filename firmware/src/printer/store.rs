//! The driver's flash store, as the executive uses it: settings saved and loaded (M500, M501,
//! the boot's load), the paused job's record kept and cleared, and the store's erase-ahead
//! while idle. The driver calls [`Printer::load_settings`] at boot and
//! [`Printer::service_store`] from its main loop with its store; the executive never blocks
//! on flash and never erases while stepping.

use super::job::{JobRequest, PlaceText, Where};
use super::settings::StoreRequest;
use super::{Printer, State};
use crate::storage::{Moment, PausedJob, RecordStore, Saved, StoreError};

/// How long the printer must have been idle before the store may erase a sector ahead, µs
/// (`storage::reserve`: the erase stalls the MCU for up to 2 s, heaters off meanwhile).
pub const ERASE_AHEAD_IDLE_US: u64 = 10_000_000;

impl Printer {
    /// Boot: load the saved settings and apply them. Nothing saved: the factory values stay,
    /// silently. A store that cannot be read or a record that is refused (corrupt, another
    /// format version, out of range): the factory values stay, with an `echo:` saying why.
    pub fn load_settings(&mut self, store: &mut dyn RecordStore) {
        if !self.settings.has_factory() {
            self.set_factory_settings();
        }
        self.job.attach();
        self.load_and_apply(store, false);
        self.announce_kept_job(store);
    }

    fn load_and_apply(&mut self, store: &mut dyn RecordStore, report_empty: bool) {
        match store.load_settings() {
            Ok(Some(s)) => match self.apply_settings(&s) {
                Ok(()) => self.host.say(format_args!("Settings loaded from flash")),
                Err(e) => self
                    .host
                    .say(format_args!("saved settings not applied: {e}")),
            },
            Ok(None) => {
                if report_empty {
                    self.host
                        .say(format_args!("no saved settings: nothing changed"));
                }
            }
            Err(e) => self.fall_back(e),
        }
    }

    fn fall_back(&mut self, e: StoreError) {
        let f = self.factory_settings();
        match self.apply_settings(&f) {
            Ok(()) if e == StoreError::Foreign => self.host.say(format_args!(
                "no saved settings: {e} (factory defaults; M500 saves over it)"
            )),
            Ok(()) => self.host.say(format_args!(
                "saved settings unusable ({e}): factory defaults loaded"
            )),
            Err(why) => self.host.say(format_args!(
                "saved settings unusable ({e}); factory defaults not applied: {why}"
            )),
        }
    }

    /// Main loop: carry out a pending M500/M501 and paused-job save/clear with the driver's
    /// store once nothing moves (a flash erase on the STM32F4 stalls every read of the flash,
    /// so code running from it stalls too: never while stepping).
    ///
    /// With nothing to do, after [`ERASE_AHEAD_IDLE_US`] of idle (no job, nothing moving or
    /// paused), once per idle period: the store's erase-ahead (`storage::reserve`), so the
    /// saves of the next print (a power-cut record at every layer pause) find erased room.
    pub fn service_store(&mut self, store: &mut dyn RecordStore) {
        if !self.store_request_pending() {
            self.erase_ahead_when_idle(store);
            return;
        }
        if !self.still() {
            return;
        }
        let at = self.store_moment();
        match self.settings.take_request() {
            Some(StoreRequest::Save(s)) => match store.save_settings(&s, at) {
                Ok(how) => self.host.say(format_args!(
                    "Settings Stored ({} bytes, format {}{})",
                    crate::storage::RECORD_LEN,
                    crate::storage::FORMAT_VERSION,
                    how.note()
                )),
                Err(e) => self.host.say(format_args!("settings not saved: {e}")),
            },
            Some(StoreRequest::Load) => self.load_and_apply(store, true),
            None => {}
        }
        match self.job.take_request() {
            Some(JobRequest::Save(j)) => {
                let saved = store.save_job(&j, at);
                self.job_saved(&j, saved);
            }
            Some(JobRequest::Clear) => {
                if let Err(e) = store.clear_job(at) {
                    self.host.say(format_args!(
                        "power-cut resume: the kept job was not cleared: {e}"
                    ));
                }
            }
            None => {}
        }
    }

    fn erase_ahead_when_idle(&mut self, store: &mut dyn RecordStore) {
        let idle = self.state() == State::Idle;
        if !self
            .settings
            .erase_ahead_due(idle, self.now_us, ERASE_AHEAD_IDLE_US)
        {
            return;
        }
        if let Err(e) = store.erase_ahead() {
            self.host
                .say(format_args!("settings flash: erase ahead failed: {e}"));
        }
    }

    /// What a sector erase would cost now (`service_store` runs only when nothing steps):
    /// parked in a pause; idle (nothing queued, no card print); or between the moves of a job
    /// (lines queued, or a card print: never an erase then).
    fn store_moment(&self) -> Moment {
        use super::pause::Pause;
        match self.pause.state() {
            Pause::Parked { .. } | Pause::Returning { .. } => Moment::Paused,
            Pause::Run if self.state() == State::Idle && !self.sd_printing() => Moment::Idle,
            _ => Moment::Printing,
        }
    }

    /// Nothing steps now: the printer is idle, or paused (the held job waits in the planner)
    /// with no service move running (parked, or about to return and waiting for this store).
    fn still(&self) -> bool {
        use super::pause::Pause;
        !self.motion.executing()
            && (self.motion.planner().is_empty()
                || matches!(
                    self.pause.state(),
                    Pause::Parked { .. } | Pause::Returning { .. }
                ))
    }

    /// True while an M500/M501 or a paused-job save/clear waits for the driver.
    pub fn store_request_pending(&self) -> bool {
        self.settings.request_pending() || self.job.request_pending()
    }

    /// The driver's store has written `j` (or failed to): say which. Only a record in flash is
    /// announced as kept.
    fn job_saved(&mut self, j: &PausedJob, saved: Result<Saved, StoreError>) {
        let mut t = PlaceText::new();
        let _ = match saved {
            Ok(how) => core::fmt::Write::write_fmt(
                &mut t,
                format_args!(
                    "power-cut resume: keeping job at layer {}, {}{}",
                    j.layer,
                    Where(&j.source),
                    how.note()
                ),
            ),
            Err(e) => core::fmt::Write::write_fmt(
                &mut t,
                format_args!("power-cut resume: job at layer {} not kept: {e}", j.layer),
            ),
        };
        self.host.respond(crate::link::Response::Echo(&t));
    }
}
