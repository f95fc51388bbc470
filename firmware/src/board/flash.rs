//! The settings store on the SKR 2: flash sectors 10 and 11 of the STM32F407VG
//! ([`firmware::storage::SKR2_AREA`], `0x080C_0000..0x0810_0000`) through embassy-stm32's
//! blocking flash driver, the power-up load, and the task that carries out M500/M501.
//!
//! The portable store, the record and the M-codes are in the library (`firmware::storage`,
//! `printer/settings.rs`); this file only binds them to the chip. `memory.x` must end the image
//! below `0x080C_0000` (see `docs/settings.md`).

use core::cell::RefCell;
use embassy_executor::Spawner;
use embassy_stm32::flash::{Blocking, Flash};
use embassy_time::Timer;
use firmware::printer::Printer;
use firmware::storage::{SettingsStore, SKR2_AREA};

/// Start of the flash: embassy-stm32's flash offsets count from here.
const FLASH_BASE: u32 = 0x0800_0000;

/// How often the store task looks for a pending M500/M501, ms.
const POLL_MS: u64 = 20;

/// The store on the chip's flash.
pub type Store = SettingsStore<Flash<'static, Blocking>>;

/// Load the saved settings into `printer` now (before any host line is read) and start the
/// task that carries out M500/M501. A misconfigured area is logged; the printer then runs on
/// its factory values.
pub fn start(spawner: &Spawner, printer: &'static RefCell<Printer>) {
    // SAFETY: FLASH is used nowhere else in this image (`pins::split` does not take it), so
    // this is its only instance.
    let flash = Flash::new_blocking(unsafe { embassy_stm32::peripherals::FLASH::steal() });
    let area = SKR2_AREA.start - FLASH_BASE..SKR2_AREA.end - FLASH_BASE;
    let mut store = match SettingsStore::new(flash, area) {
        Ok(s) => s,
        Err(_) => {
            defmt::error!("settings store: area misconfigured; factory settings only");
            return;
        }
    };
    printer.borrow_mut().load_settings(&mut store);
    match store_task(printer, store) {
        Ok(t) => spawner.spawn(t),
        Err(_) => defmt::error!("settings task could not be spawned"),
    }
}

/// Carry out a pending M500/M501 once nothing moves (`Printer::service_store` waits for
/// that: a sector erase stalls every flash read, the code's included, for up to 2 s).
#[embassy_executor::task]
async fn store_task(printer: &'static RefCell<Printer>, mut store: Store) {
    loop {
        Timer::after_millis(POLL_MS).await;
        let mut p = printer.borrow_mut();
        if p.store_request_pending() {
            p.service_store(&mut store);
        }
    }
}
