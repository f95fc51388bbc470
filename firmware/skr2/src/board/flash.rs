//! The settings store on the SKR 2: flash sectors 10 and 11 of the STM32F407VG
//! ([`firmware::storage::SKR2_AREA`], `0x080C_0000..0x0810_0000`) through embassy-stm32's
//! blocking flash driver, the power-up load, and the task that carries out M500/M501, the
//! power-cut record's saves and the erase-ahead.
//!
//! The portable store, the record, the M-codes and the erase-ahead policy are in the library
//! (`firmware::storage`, `printer/settings.rs`); this file binds them to the chip, through
//! [`GuardedFlash`]: a sector erase stalls the MCU for up to 2 s (128 KiB, DS8626 "Flash memory
//! programming", x32 parallelism, which `GuardedFlash` sets: [`erase_parallelism_x32`]): every flash read waits, so
//! the code, the interrupts, the heaters' software PWM and the step interrupt all stop.
//! Before each sector erase the heaters are switched off (their gates low: a heater left on
//! would stay on for the whole erase) and the watchdog is fed (its shortest timeout, 2.5 s at
//! the fastest LSI, covers one erase: `board::watchdog`); writes go in chunks of at most
//! [`WRITE_CHUNK`] bytes with a feed between. The feeding is bounded in time
//! ([`SERVICE_BUDGET_US`] per store call): a store that never returns still ends in a
//! watchdog reset. The erase-ahead (`SettingsStore::erase_ahead`) makes erases happen while
//! the printer is idle, not during a layer pause's save; one that still finds no erased room
//! while paused may erase ([`ERASE_WHILE_PAUSED`]). `memory.x` must end the image below
//! `0x080C_0000` (see `docs/settings.md`).

use embassy_stm32::flash::{Blocking, Error as FlashError, Flash};
use embassy_stm32::pac;
use embedded_storage::nor_flash::{ErrorType, NorFlash, ReadNorFlash};
use firmware::printer::Printer;
use firmware::storage::{SettingsStore, SKR2_AREA};

use super::{clock, safety, watchdog};

/// Start of the flash: embassy-stm32's flash offsets count from here.
const FLASH_BASE: u32 = 0x0800_0000;

/// How often the motion task serves the store (a pending M500/M501, a record), ms.
pub const POLL_MS: u32 = 20;

/// Most bytes programmed between two watchdog feeds (64 words: at most 6.4 ms at the
/// datasheet's 100 µs per word).
pub const WRITE_CHUNK: usize = 256;

/// How long one store call may keep the watchdog fed from inside flash operations, µs: the
/// longest call is an erase-ahead (a sector switch and two 2 s erases).
pub const SERVICE_BUDGET_US: u64 = 6_000_000;

/// The longest erase of one 128 KiB sector at x32 parallelism, µs (DS8626 "Flash memory
/// programming", maximum).
pub const ERASE_MAX_US: u32 = 2_000_000;

/// An erase fits one watchdog period at its shortest (fed right before the erase), so a save
/// while paused may erase when it finds no erased room (the store's
/// `SettingsStore::erase_while_paused`): the heaters are off for it (`GuardedFlash`).
pub const ERASE_WHILE_PAUSED: bool = ERASE_MAX_US < super::watchdog::MIN_TIMEOUT_US;
const _: () = assert!(ERASE_WHILE_PAUSED);

// The sim's and the tests' model of this area has the driver's geometry: the store's layout
// follows the program word and the sector size, so an area written by `sim serve --flash` or
// crafted in a test reads the same here.
const _: () = {
    type Model = firmware::storage::Skr2FlashModel<[u8; 0]>;
    assert!(<GuardedFlash as NorFlash>::WRITE_SIZE == <Model as NorFlash>::WRITE_SIZE);
    assert!(<GuardedFlash as NorFlash>::ERASE_SIZE == <Model as NorFlash>::ERASE_SIZE);
    assert!(SKR2_AREA.sector_bytes as usize == <Model as NorFlash>::ERASE_SIZE);
};

/// The chip's flash with the heater and watchdog guards around its erases and writes.
pub struct GuardedFlash {
    flash: Flash<'static, Blocking>,
    /// Feed the watchdog from flash operations until this time, ns (0: not in a store call).
    feed_until_ns: u64,
    /// Sector erases done since start-up.
    pub erases: u32,
}

impl GuardedFlash {
    fn feed(&self) {
        if clock::now_ns() < self.feed_until_ns {
            watchdog::feed();
        }
    }

    /// A store call begins: flash operations may feed the watchdog for [`SERVICE_BUDGET_US`].
    pub fn begin(&mut self) {
        self.feed_until_ns = clock::now_ns() + SERVICE_BUDGET_US * 1000;
    }

    /// The store call ended.
    pub fn end(&mut self) {
        self.feed_until_ns = 0;
    }
}

impl ErrorType for GuardedFlash {
    type Error = FlashError;
}

impl ReadNorFlash for GuardedFlash {
    const READ_SIZE: usize = <Flash<'static, Blocking> as ReadNorFlash>::READ_SIZE;

    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        self.flash.blocking_read(offset, bytes)
    }

    fn capacity(&self) -> usize {
        ReadNorFlash::capacity(&self.flash)
    }
}

impl NorFlash for GuardedFlash {
    const WRITE_SIZE: usize = <Flash<'static, Blocking> as NorFlash>::WRITE_SIZE;
    const ERASE_SIZE: usize = <Flash<'static, Blocking> as NorFlash>::ERASE_SIZE;

    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        let mut at = offset;
        for chunk in bytes.chunks(WRITE_CHUNK) {
            self.feed();
            self.flash.blocking_write(at, chunk)?;
            at += chunk.len() as u32;
        }
        self.feed();
        Ok(())
    }

    fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        let sector = Self::ERASE_SIZE as u32;
        let mut at = from;
        while at < to {
            let end = (at + sector).min(to);
            // Heaters off before the MCU stalls (their PWM cannot run during the erase), x32
            // parallelism, and a full watchdog period for the erase itself.
            safety::heaters_off();
            erase_parallelism_x32();
            self.feed();
            let t0 = clock::now_ns();
            let r = self.flash.blocking_erase(at, end);
            self.feed();
            self.erases = self.erases.saturating_add(1);
            defmt::info!(
                "flash: sector at {=u32:#010x} erased in {=u64} ms (heaters were off)",
                FLASH_BASE + at,
                (clock::now_ns() - t0) / 1_000_000
            );
            r?;
            at = end;
        }
        Ok(())
    }
}

/// Sets FLASH_CR.PSIZE to x32 for the next erase (unlocking CR first, as embassy does: KEYR
/// 0x45670123, 0xCDEF89AB, RM0090 §3.5.1). embassy-stm32 0.6's `blocking_erase_sector` keeps
/// whatever PSIZE CR holds (it only `modify`s SER/SNB/STRT), and its blocking write leaves
/// PSIZE 0 behind (`disable_blocking_write` writes CR with PG alone): its erases ran at x8,
/// 2 s typical and **4 s** maximum for a 128 KiB sector (DS8626 "Flash memory programming"),
/// longer than any watchdog period here (found on the emulated board, which times the erase
/// by PSIZE). x32 is valid at 2.7–3.6 V (RM0090 §3.6.2 "Program/erase parallelism"; the SKR 2
/// runs at 3.3 V): 1 s typical, 2 s maximum. embassy locks CR again after its erase.
fn erase_parallelism_x32() {
    let f = pac::FLASH;
    if f.cr().read().lock() {
        f.keyr().write_value(0x4567_0123);
        f.keyr().write_value(0xCDEF_89AB);
    }
    f.cr()
        .modify(|w| w.set_psize(pac::flash::vals::Psize::PSIZE32));
}

/// The store on the chip's flash.
pub type Store = SettingsStore<GuardedFlash>;

/// Load the saved settings into `printer` now (before any host line is read); the store is
/// the caller's (the motion task serves M500/M501 with it: [`serve_store`]). A misconfigured
/// area is logged; the printer then runs on its factory values.
pub fn start(printer: &mut Printer) -> Option<Store> {
    // SAFETY: FLASH is used nowhere else in this image (`pins::split` does not take it), so
    // this is its only instance.
    let flash = Flash::new_blocking(unsafe { embassy_stm32::peripherals::FLASH::steal() });
    let flash = GuardedFlash {
        flash,
        feed_until_ns: 0,
        erases: 0,
    };
    let area = SKR2_AREA.start - FLASH_BASE..SKR2_AREA.end - FLASH_BASE;
    let mut store = match SettingsStore::new(flash, area) {
        Ok(s) => s.erase_while_paused(ERASE_WHILE_PAUSED),
        Err(_) => {
            defmt::error!("settings store: area misconfigured; factory settings only");
            return None;
        }
    };
    printer.load_settings(&mut store);
    Some(store)
}

/// The executive's side (motion task, every [`POLL_MS`]): a pending M500/M501 or power-cut
/// record once nothing moves (`Printer::service_store` waits for that), and the erase-ahead
/// once idle.
pub fn serve_store(p: &mut Printer, store: &mut Store) {
    store.flash_mut().begin();
    p.service_store(store);
    store.flash_mut().end();
}
