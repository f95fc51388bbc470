//! What the executive asks of the store, and what it gets back: [`RecordStore`]. The
//! executive knows when it asks ([`Moment`]); the store knows what a save costs then and says
//! what it did ([`Saved`], [`Ahead`]) or why it did not ([`StoreError`]), so every message
//! can say only what happened.

use super::job::PausedJob;
use super::record::{RecordError, Settings};

/// When the executive asks for a save: what a sector erase (1–2 s with the CPU stalled on the
/// STM32F4) would cost then.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Moment {
    /// No job and nothing moving: an erase costs nothing but the wait.
    Idle,
    /// A pause holds the job, the head parked: an erase only if the store's flash can afford
    /// one now (on the SKR 2: heaters off for it, the watchdog fed; `SettingsStore::new`).
    Paused,
    /// A job runs (the head rests on the print between moves): never an erase.
    Printing,
}

/// How a record was saved (it reads back: a save that does not is an error).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Saved {
    /// Written into erased room.
    Written,
    /// Room had to be made first: a sector holding an older generation or data this store did
    /// not write was erased.
    AfterErase,
}

impl Saved {
    /// What a save's message adds: that a sector was erased first (1–2 s with the CPU
    /// stalled on the STM32F4), or nothing.
    pub fn note(self) -> &'static str {
        match self {
            Saved::Written => "",
            Saved::AfterErase => "; a flash sector was erased first",
        }
    }
}

/// What an erase-ahead found or did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Ahead {
    /// Nothing was ever saved here (the area is erased, or holds data this store did not
    /// write, which only a save the user asks for erases): nothing done.
    NothingSaved,
    /// The records have `free_bytes` of erased room after them and the other sector is
    /// erased; `erased` sectors were erased to get there (0, 1 or 2).
    Ready {
        /// Erased bytes left in the current sector.
        free_bytes: u32,
        /// Sectors erased by this call.
        erased: u32,
    },
}

/// Why the store could not load or save.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StoreError {
    /// The area is not two sectors, or the flash's word or sector size does not fit the format.
    Config,
    /// The flash driver reported an error (the operation may have been cut short).
    Flash,
    /// The area holds bytes but no sector this store committed: another firmware's data, or
    /// this store's first save cut short. Nothing of it is loaded; a save erases a sector of
    /// it first (unless one is erased).
    Foreign,
    /// The save needs an erased sector and there is none, and the moment cannot afford an
    /// erase (a job printing, or a pause on a flash whose erase the board cannot guard).
    NoErasedRoom,
    /// The record has frames in flash but none whole: damaged, or its only save cut short.
    Damaged,
    /// A sector read back not erased after its erase.
    EraseFailed,
    /// The record was written but did not read back.
    NotVerified,
    /// A record longer than the store's frames take.
    TooLarge,
    /// The record was read but refused.
    Record(RecordError),
}

impl core::fmt::Display for StoreError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            StoreError::Config => "settings area misconfigured",
            StoreError::Flash => "flash error",
            StoreError::Foreign => "the flash area holds nothing this firmware saved whole",
            StoreError::NoErasedRoom => {
                "no erased flash room and no erase now (erased ahead when idle)"
            }
            StoreError::Damaged => "record damaged or its save cut short",
            StoreError::EraseFailed => "a flash sector did not erase",
            StoreError::NotVerified => "record did not read back from flash",
            StoreError::TooLarge => "record too long for the store",
            StoreError::Record(e) => return write!(f, "{e}"),
        })
    }
}

/// The settings and paused-job store as the executive uses it: load and save each record,
/// and prepare erased room while idle. `storage::SettingsStore` implements it on a flash.
pub trait RecordStore {
    /// The saved settings: `Ok(None)` when none were ever saved (or the area is erased).
    fn load_settings(&mut self) -> Result<Option<Settings>, StoreError>;
    /// Save `s` (checked first: out-of-range settings are never written).
    fn save_settings(&mut self, s: &Settings, at: Moment) -> Result<Saved, StoreError>;
    /// The paused job kept for a power-cut resume (`None`: none, or cleared).
    fn load_job(&mut self) -> Result<Option<PausedJob>, StoreError>;
    /// Keep `job` for a power-cut resume (the previous record stays until this one is whole).
    fn save_job(&mut self, job: &PausedJob, at: Moment) -> Result<Saved, StoreError>;
    /// Forget the paused job (it resumed, or was cancelled).
    fn clear_job(&mut self, at: Moment) -> Result<Saved, StoreError>;
    /// While idle: make sure the next saves find erased room (see `SettingsStore`).
    fn erase_ahead(&mut self) -> Result<Ahead, StoreError>;
}
