//! The SKR 2's micro-SD slot as the card of SD printing: embassy-stm32's SDMMC driver (the
//! STM32F4's SDIO, 4-bit bus) behind embedded-sdmmc's [`BlockDevice`] trait, so the
//! library's FAT job source ([`firmware::storage::sd::Card`]) and the executive's SD commands
//! (`printer/sd.rs`) run on it unchanged. **Not tried on hardware.**
//!
//! Pins (Marlin `pins_BTT_SKR_V2_0_common.h`, `SD_CONNECTION_IS(ONBOARD)`: `SDIO_SUPPORT`,
//! `SDIO_D0_PIN PC8`, `SDIO_D1_PIN PC9`, `SDIO_D2_PIN PC10`, `SDIO_D3_PIN PC11`,
//! `SDIO_CK_PIN PC12`, `SDIO_CMD_PIN PD2`; the on-board slot has no card-detect pin). DMA2
//! stream 3 (channel 4) serves SDIO (RM0090 table 43).
//!
//! The card is brought up (`acquire`: CMD0, CMD8, ACMD41 …) by [`sd_task`] with `.await` when
//! the executive asks for it ([`serve_card`] signals the task), so a slow or absent card never
//! stalls the other tasks; the executive's owner (the motion task) serves the card requests
//! and the job's lines with [`serve_card`] meanwhile only once that is over. After that, block
//! reads for the FAT code
//! run to completion with `embassy_futures::block_on` (embedded-sdmmc's trait is blocking): a
//! 512-byte block at the 24 MHz bus takes well under a millisecond, and the step interrupt
//! runs from its own queue meanwhile. A read error marks the card lost; the next M21 (or any
//! SD command that needs the card) brings it up again.

use core::cell::RefCell;
use core::sync::atomic::{AtomicBool, Ordering};
use embassy_executor::Spawner;
use embassy_stm32::sdmmc::sd::{Addressable, Card as SdCard, CmdBlock, DataBlock, StorageDevice};
use embassy_stm32::sdmmc::{self, Sdmmc};
use embassy_stm32::time::Hertz;
use embassy_stm32::{bind_interrupts, dma, peripherals};
use embedded_sdmmc::{Block, BlockCount, BlockDevice, BlockIdx};
use firmware::printer::Printer;
use firmware::storage::sd::Card;
use static_cell::StaticCell;

bind_interrupts!(struct Irqs {
    SDIO => sdmmc::InterruptHandler<peripherals::SDIO>;
    DMA2_STREAM3 => dma::InterruptHandler<peripherals::DMA2_CH3>;
});

/// SDIO bus clock once the card is up (the F4's SDIO runs up to 48 MHz / 2 in this mode).
const BUS_HZ: u32 = 24_000_000;
/// How often the motion task serves the card, ms.
pub const POLL_MS: u32 = 2;

/// A bring-up is asked for or under way: the card is not the executive's meanwhile.
static BRINGING_UP: AtomicBool = AtomicBool::new(false);
/// The executive wants the card up.
static WANTED: embassy_sync::signal::Signal<
    embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex,
    (),
> = embassy_sync::signal::Signal::new();

type Device = StorageDevice<'static, 'static, SdCard>;

/// The SDIO card, shared by the FAT code (blocking reads) and the card task (bring-up).
pub struct SdioCard {
    dev: &'static RefCell<Device>,
}

/// The card is up (brought up by the card task; lost after a read or write error).
static UP: AtomicBool = AtomicBool::new(false);
/// The executive asked for a bring-up since it last served the card (one try per request:
/// a card that does not come up is the executive's `SD init fail`, not a retry loop).
static TRIED: AtomicBool = AtomicBool::new(false);

/// Why a block could not be read.
#[derive(Clone, Copy, Debug)]
pub enum SdioError {
    /// The card is not up (absent, or lost after an error).
    NotUp,
    /// The driver is in use (a re-entrant call; never expected).
    Busy,
    /// The SDMMC driver failed (logged with defmt).
    Card,
}

impl BlockDevice for SdioCard {
    type Error = SdioError;

    fn read(&self, blocks: &mut [Block], start: BlockIdx) -> Result<(), Self::Error> {
        if !UP.load(Ordering::Acquire) {
            return Err(SdioError::NotUp);
        }
        let mut dev = self.dev.try_borrow_mut().map_err(|_| SdioError::Busy)?;
        let mut data = DataBlock::new();
        for (i, b) in blocks.iter_mut().enumerate() {
            let idx = start.0.saturating_add(i as u32);
            if let Err(e) = embassy_futures::block_on(dev.read_block(idx, &mut data)) {
                defmt::warn!("SD block {=u32} not read: {}", idx, e);
                UP.store(false, Ordering::Release);
                return Err(SdioError::Card);
            }
            b.contents.copy_from_slice(&data[..]);
        }
        Ok(())
    }

    fn write(&self, blocks: &[Block], start: BlockIdx) -> Result<(), Self::Error> {
        // Only the parked intake's spill file is written (storage/sd, printer/spill.rs).
        if !UP.load(Ordering::Acquire) {
            return Err(SdioError::NotUp);
        }
        let mut dev = self.dev.try_borrow_mut().map_err(|_| SdioError::Busy)?;
        let mut data = DataBlock::new();
        for (i, b) in blocks.iter().enumerate() {
            let idx = start.0.saturating_add(i as u32);
            data.copy_from_slice(&b.contents);
            if let Err(e) = embassy_futures::block_on(dev.write_block(idx, &data)) {
                defmt::warn!("SD block {=u32} not written: {}", idx, e);
                UP.store(false, Ordering::Release);
                return Err(SdioError::Card);
            }
        }
        Ok(())
    }

    fn num_blocks(&self) -> Result<BlockCount, Self::Error> {
        if !UP.load(Ordering::Acquire) {
            return Err(SdioError::NotUp);
        }
        let dev = self.dev.try_borrow().map_err(|_| SdioError::Busy)?;
        Ok(BlockCount(
            u32::try_from(dev.card().size() / 512).unwrap_or(u32::MAX),
        ))
    }
}

/// Take the SDIO peripheral, its pins and DMA stream, tell the executive it has a card slot,
/// and start the card task; the card is the caller's (the motion task serves it).
pub fn start(spawner: &Spawner, printer: &mut Printer) -> Card<SdioCard> {
    static SDMMC: StaticCell<Sdmmc<'static>> = StaticCell::new();
    static DEV: StaticCell<RefCell<Device>> = StaticCell::new();
    // SAFETY: SDIO, DMA2 stream 3 and PC8–PC12, PD2 are used nowhere else in this image
    // (`pins::split` does not take them: see docs/board.md), so these are their only instances.
    let sdmmc = unsafe {
        Sdmmc::new_4bit(
            peripherals::SDIO::steal(),
            peripherals::DMA2_CH3::steal(),
            Irqs,
            peripherals::PC12::steal(),
            peripherals::PD2::steal(),
            peripherals::PC8::steal(),
            peripherals::PC9::steal(),
            peripherals::PC10::steal(),
            peripherals::PC11::steal(),
            sdmmc::Config::default(),
        )
    };
    let sdmmc = SDMMC.init(sdmmc);
    let dev = DEV.init(RefCell::new(StorageDevice::new_uninit_sd_card(sdmmc)));
    printer.attach_card();
    match sd_task(dev) {
        Ok(t) => spawner.spawn(t),
        Err(_) => defmt::error!("SD card task could not be spawned"),
    }
    Card::new(SdioCard { dev })
}

/// The executive's side (motion task, every [`POLL_MS`]): a card wanted and not up is
/// brought up by the card task first; otherwise the executive's card requests and the job's
/// lines are served.
pub fn serve_card(p: &mut Printer, card: &mut Card<SdioCard>, now_us: u64) {
    if BRINGING_UP.load(Ordering::Acquire) {
        return;
    }
    if !UP.load(Ordering::Acquire) && p.sd_request_pending() && !TRIED.load(Ordering::Relaxed) {
        TRIED.store(true, Ordering::Relaxed);
        BRINGING_UP.store(true, Ordering::Release);
        WANTED.signal(());
        return;
    }
    TRIED.store(false, Ordering::Relaxed);
    p.service_card(card, now_us);
}

/// Bring the card up when the executive wants it (at power-up, M21, a command after a lost
/// card), then hand it back.
#[embassy_executor::task]
async fn sd_task(dev: &'static RefCell<Device>) {
    let mut cmd = CmdBlock::new();
    loop {
        WANTED.wait().await;
        // Awaited, not blocked on: the other tasks run while the card answers (or not).
        match bring_up(dev, &mut cmd).await {
            Ok(()) => UP.store(true, Ordering::Release),
            Err(e) => defmt::warn!("SD card not up: {}", e),
        }
        BRINGING_UP.store(false, Ordering::Release);
    }
}

/// Bring the card up (CMD0, CMD8, ACMD41, … at 400 kHz, then the bus at [`BUS_HZ`]).
// The borrow spans the await: the executive leaves the card alone while `BRINGING_UP` is set
// (the FAT code reads blocks only inside `service_card`, never during a bring-up).
#[allow(clippy::await_holding_refcell_ref)]
async fn bring_up(dev: &RefCell<Device>, cmd: &mut CmdBlock) -> Result<(), sdmmc::Error> {
    dev.borrow_mut().reacquire(cmd, Hertz(BUS_HZ)).await
}
