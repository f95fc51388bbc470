//! The driver's flash store, as the executive uses it: settings saved and loaded (M500, M501,
//! the boot's load), the paused job's record kept and cleared, and the store's erase-ahead
//! while idle. The driver calls [`Printer::load_settings`] at boot and
//! [`Printer::service_store`] from its main loop with its store; the executive never blocks
//! on flash and never erases while stepping.

use super::job::{JobRequest, PlaceText, Where};
use super::settings::StoreRequest;
use super::{Printer, State};
use crate::storage::{PausedJob, SettingsStore, StoreError, Stored};
use embedded_storage::nor_flash::NorFlash;

/// What a store says when it had to reclaim the area (nothing when it appended).
struct Reclaim(Stored);

impl core::fmt::Display for Reclaim {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self.0 {
            Stored::Appended => Ok(()),
            Stored::Reclaimed => f.write_str("; the unreadable settings area was erased first"),
        }
    }
}

/// How long the printer must have been idle before the store may erase a sector ahead, µs
/// (`storage::reserve`: the erase stalls the MCU for up to 2 s, heaters off meanwhile).
pub const ERASE_AHEAD_IDLE_US: u64 = 10_000_000;

impl Printer {
    /// Boot: load the saved settings and apply them. Nothing saved: the factory values stay,
    /// silently. A store that cannot be read or a record that is refused (corrupt, another
    /// format version, out of range): the factory values stay, with an `echo:` saying why.
    pub fn load_settings<F: NorFlash>(&mut self, store: &mut SettingsStore<F>) {
        if !self.settings.has_factory() {
            self.set_factory_settings();
        }
        self.job.attach();
        self.load_and_apply(store, false);
        self.announce_kept_job(store);
    }

    fn load_and_apply<F: NorFlash>(&mut self, store: &mut SettingsStore<F>, report_empty: bool) {
        match store.load() {
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
            Ok(()) => self.host.say(format_args!(
                "saved settings unusable ({e}): factory defaults loaded{}",
                if matches!(e, StoreError::Corrupted | StoreError::Full) {
                    " (M500 erases the area and saves)"
                } else {
                    ""
                }
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
    pub fn service_store<F: NorFlash>(&mut self, store: &mut SettingsStore<F>) {
        if !self.store_request_pending() {
            self.erase_ahead_when_idle(store);
            return;
        }
        if !self.still() {
            return;
        }
        match self.settings.take_request() {
            Some(StoreRequest::Save(s)) => match store.save(&s) {
                Ok(how) => self.host.say(format_args!(
                    "Settings Stored ({} bytes, format {}{})",
                    crate::storage::RECORD_LEN,
                    crate::storage::FORMAT_VERSION,
                    Reclaim(how)
                )),
                Err(e) => self.host.say(format_args!("settings not saved: {e}")),
            },
            Some(StoreRequest::Load) => self.load_and_apply(store, true),
            None => {}
        }
        match self.job.take_request() {
            Some(JobRequest::Save(j)) => {
                let saved = store.save_job(&j);
                self.job_saved(&j, saved);
            }
            Some(JobRequest::Clear) => {
                if let Err(e) = store.clear_job() {
                    self.host.say(format_args!(
                        "power-cut resume: the kept job was not cleared: {e}"
                    ));
                }
            }
            None => {}
        }
    }

    fn erase_ahead_when_idle<F: NorFlash>(&mut self, store: &mut SettingsStore<F>) {
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
    fn job_saved(&mut self, j: &PausedJob, saved: Result<Stored, StoreError>) {
        let mut t = PlaceText::new();
        let _ = match saved {
            Ok(how) => core::fmt::Write::write_fmt(
                &mut t,
                format_args!(
                    "power-cut resume: keeping job at layer {}, {}{}",
                    j.layer,
                    Where(&j.source),
                    Reclaim(how)
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
