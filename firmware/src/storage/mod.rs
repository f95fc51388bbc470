//! Settings kept in flash: the record M500 saves ([`Settings`]), the paused-job record
//! ([`PausedJob`]), the store that keeps both power-safe in two NOR-flash sectors
//! ([`SettingsStore`], behind the executive's interface [`RecordStore`]), and a NOR-flash model
//! that can lose power at any operation ([`NorFlashModel`], for the sim and the tests).
//!
//! Layers, each using only those below it: `record`/`job` (the records' bytes), `format` (the
//! on-flash layout), `sector` (reading it from a flash), `store` (writing it: saves, sector
//! switches, erase-ahead), `api` (what the executive asks and gets back).
//!
//! On the SKR 2 (STM32F407VG, 1 MiB) the area is the last two 128 KiB sectors, 10 and 11
//! (`0x080C_0000..0x0810_0000`; RM0090 table 5: sectors 5–11 are 128 KiB each on the 1 MiB
//! parts, F407 and F429 alike); see [`SKR2_AREA`]. The image must end below it (`memory.x`).
//! See `docs/settings.md` for the M-codes, the format and the power-fail guarantees.

mod api;
mod crc;
mod flash;
mod format;
mod job;
mod record;
// SD-card printing: the FAT job source (embedded-sdmmc).
pub mod sd;
mod sector;
mod store;

pub use api::{Ahead, Moment, RecordStore, Saved, StoreError};
pub use crc::crc32;
pub use flash::{Cut, FlashOp, ModelError, NorFlashModel};
pub use format::{MAX_DATA, STORE_FORMAT};
pub use job::{
    JobSource, ModalState, PausedJob, JOB_BODY_LEN, JOB_FORMAT_VERSION, JOB_PATH_CAP,
    JOB_RECORD_LEN,
};
pub use record::{
    RecordError, Settings, BODY_LEN, DEFAULT_DRIVER_CURRENT_MA, FORMAT_VERSION, RECORD_LEN,
};
// The ranges every saved value is checked against: the table the commands use too.
pub use crate::ranges::{
    Bound, ACCEL, DRIVER_CURRENT, HOME_OFFSET, JUNCTION_DEVIATION, MAX_FEED, PID_GAIN, STEPS_PER_MM,
};
pub use store::{SettingsStore, JOB_KEY, SETTINGS_KEY};

/// Where the settings live on the SKR 2: absolute addresses of the area in the STM32F407's
/// flash, and its sector size.
pub struct FlashArea {
    /// First byte (absolute address).
    pub start: u32,
    /// One past the last byte.
    pub end: u32,
    /// Erase unit, bytes.
    pub sector_bytes: u32,
}

impl FlashArea {
    /// Size of the area, bytes.
    pub const fn len(&self) -> u32 {
        self.end - self.start
    }

    /// True for an area of no bytes.
    pub const fn is_empty(&self) -> bool {
        self.end == self.start
    }
}

/// The SKR 2's settings area: sectors 10 and 11 of the STM32F407VG.
pub const SKR2_AREA: FlashArea = FlashArea {
    start: 0x080C_0000,
    end: 0x0810_0000,
    sector_bytes: 128 * 1024,
};

/// The flash model the sim uses for `--flash FILE`: the SKR 2's area geometry as the board's
/// driver sees it (two 128 KiB sectors; 4-byte program words: embassy-stm32's `WRITE_SIZE`
/// for the F4, which programs one 32-bit word at a time at x32 parallelism). The store's
/// layout follows the word, so an area written with another word size is unreadable on the
/// board: `board/flash.rs` checks at compile time that the two agree (issue 29 found the
/// model at 16 bytes while the board used 4).
pub type Skr2FlashModel<B> = NorFlashModel<B, 4, { 128 * 1024 }>;
