//! Builds the emulated board a run needs from its [`Options`]: the flash with its settings
//! sectors (a file, or erased, or foreign data), the card, the drivers, the axes, the clock
//! model and the USB cable; loads the image, paints the stack; and at the end keeps the
//! settings sectors in their file.

use crate::axes::Axes;
use crate::board::Board;
use crate::cpu::Emulator;
use crate::cycles::Clock;
use crate::flash::{Flash, STORE_LEN};
use crate::iwdg::Iwdg;
use crate::options::{FlashFill, HostPort, Options};
use crate::sdio::Sdio;
use crate::tmc::{Drivers, Seating};
use crate::usbhost::UsbHost;
use anyhow::{Context, Result};
use firmware::config::MachineConfig;

/// The stack's bounds from the ELF (`_stack_end` .. `_stack_start`, cortex-m-rt's symbols).
fn stack_bounds(elf: &std::path::Path) -> Result<(u32, u32)> {
    use object::{Object, ObjectSymbol};
    let data = std::fs::read(elf).with_context(|| format!("reading {}", elf.display()))?;
    let file = object::File::parse(&*data)?;
    let sym = |n: &str| {
        file.symbols()
            .find(|s| s.name() == Ok(n))
            .map(|s| s.address() as u32)
    };
    Ok((
        sym("_stack_end").context("no _stack_end in the ELF")?,
        sym("_stack_start").context("no _stack_start in the ELF")?,
    ))
}

fn initial_store(o: &Options) -> Result<Vec<u8>> {
    if let Some(f) = &o.flash_file {
        if f.exists() {
            let d = std::fs::read(f)?;
            anyhow::ensure!(
                d.len() == STORE_LEN,
                "{} is not {} bytes",
                f.display(),
                STORE_LEN
            );
            return Ok(d);
        }
    }
    Ok(match o.flash_fill {
        None => vec![0xFF; STORE_LEN],
        Some(FlashFill::Zeros) => vec![0; STORE_LEN],
        Some(FlashFill::Random) => {
            let mut x: u32 = 0x2545_F491;
            (0..STORE_LEN)
                .map(|_| {
                    x ^= x << 13;
                    x ^= x >> 17;
                    x ^= x << 5;
                    x as u8
                })
                .collect()
        }
    })
}

/// Paint pattern for the stack.
const PAINT: u32 = 0xC5C5_C5C5;

/// The board of `o`, powered on, and the stack's bounds (when the ELF is given) painted.
pub fn build<'a>(o: &Options) -> Result<(Emulator<'a>, Option<(u32, u32)>)> {
    let image =
        std::fs::read(&o.image).with_context(|| format!("reading {}", o.image.display()))?;
    let mut flash = Flash::new(o.flash_timing);
    flash.store = initial_store(o)?;
    let mut seating = [Seating::Correct; 4];
    if let Some(i) = o.reversed_driver {
        seating[i.min(3)] = Seating::Reversed;
    }
    let card = match &o.sd_image {
        Some(p) => Some(std::fs::read(p).with_context(|| format!("reading {}", p.display()))?),
        None => None,
    };
    let cfg = MachineConfig::ENDER3;
    let axes = Axes::new(&cfg, o.start_mm);
    let mut board = Board::new(
        flash,
        Iwdg::new(o.lsi_hz),
        Drivers::new(seating),
        axes,
        Sdio::with_card(card),
    );
    board.clock = Clock::new(o.clock);
    if o.usb_plugged || o.port == HostPort::Usb {
        board.usb = UsbHost::new(true);
    }
    if o.port == HostPort::Usb {
        // The host program holds the port from the start: DTR once enumerated.
        board.usb.set_open(0, true);
    }
    let mut emu = Emulator::new(board, image, o.f429)?;
    let stack = match &o.elf {
        Some(e) => Some(stack_bounds(e)?),
        None => None,
    };
    if let Some((lo, hi)) = stack {
        emu.paint(lo, hi, PAINT)?;
    }

    Ok((emu, stack))
}

/// Keeps the settings sectors in their file (`Options::flash_file`).
pub fn finish(emu: &Emulator, o: &Options) -> Result<()> {
    if let Some(f) = &o.flash_file {
        std::fs::write(f, &emu.board().flash.store)
            .with_context(|| format!("writing {}", f.display()))?;
    }
    Ok(())
}
