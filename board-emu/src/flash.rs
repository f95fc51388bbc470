//! The embedded flash: its interface registers, sector erase and programming with the
//! datasheet's times, the CPU stalled while an operation runs, and the settings sectors (10
//! and 11) kept in a file across emulated resets and runs.
//!
//! Registers (RM0090 §3.9, table 11 "Flash register map and reset values"): ACR 0x00 (LATENCY
//! 3:0, PRFTEN 8, ICEN 9, DCEN 10, ICRST 11, DCRST 12; §3.9.1), KEYR 0x04 (unlock with
//! KEY1 = 0x45670123 then KEY2 = 0xCDEF89AB, §3.5.1; a wrong sequence locks CR until reset),
//! OPTKEYR 0x08, SR 0x0C (EOP 0, OPERR 1, WRPERR 4, PGAERR 5, PGPERR 6, PGSERR 7, BSY 16;
//! §3.9.4; error flags cleared by writing 1), CR 0x10 (PG 0, SER 1, MER 2, SNB 6:3 (7:3 on the
//! F42x), PSIZE 9:8, STRT 16, EOPIE 24, ERRIE 25, LOCK 31; §3.9.5), OPTCR 0x14 (reset value
//! 0x0FFF_AAED, §3.9.6).
//!
//! Operations (§3.5.3 "Erase", §3.5.4 "Programming"): a sector erase (SER, SNB, STRT) sets
//! every byte of the sector to 0xFF; programming (PG) clears bits only ("successive write
//! operations are possible … when changing bits from 1 to 0"), with an access size that must
//! match PSIZE (else PGPERR, "the write operation is not performed"). BSY is set for the
//! operation's time, and "any attempt to read the flash memory while it is being written or
//! erased causes the bus to stall until the operation is completed" (§3.5): the image runs
//! from the same bank, so the CPU executes nothing, interrupts included, until BSY clears
//! (`Flash::busy_until`); the other peripherals (timers, the watchdog, the heaters) go on.
//!
//! Times (STM32F407xx datasheet DS8626, table 40 "Flash memory programming", typical and
//! maximum, by parallelism PSIZE x8/x16/x32): 16 KiB sector 400/800, 300/600, 250/500 ms;
//! 64 KiB sector 1200/2400, 700/1400, 550/1100 ms; 128 KiB sector 2/4, 1.3/2.6, 1/2 s; word
//! program 16/100 µs. Which column is used is [`FlashTiming`].
//!
//! Sector map (RM0090 §3.3, table 5): sectors 0–3 16 KiB from 0x0800_0000, 4 64 KiB at
//! 0x0801_0000, 5–11 128 KiB from 0x0802_0000. Not modelled: mass erase, option-byte
//! programming, write protection, read protection, the OTP area, dual-bank mode (DB1M).

use crate::time::{cyc_from_ms, cyc_from_us, Cyc};

/// Flash base.
pub const FLASH_BASE: u32 = 0x0800_0000;
/// The settings area (sectors 10 and 11, `firmware::storage::SKR2_AREA`).
pub const STORE_BASE: u32 = 0x080C_0000;
/// Its size.
pub const STORE_LEN: usize = 256 * 1024;

/// Which datasheet column the erase and program times come from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum FlashTiming {
    /// Typical times.
    Typ,
    /// Maximum times.
    Max,
}

/// Start and length of sector `n` (0..=11).
pub fn sector(n: u32) -> Option<(u32, u32)> {
    let k = 1024;
    match n {
        0..=3 => Some((FLASH_BASE + n * 16 * k, 16 * k)),
        4 => Some((FLASH_BASE + 64 * k, 64 * k)),
        5..=11 => Some((FLASH_BASE + 128 * k * (n - 4), 128 * k)),
        _ => None,
    }
}

/// Erase time of a sector of `len` bytes at parallelism `psize` (0 x8, 1 x16, 2/3 x32).
pub fn erase_cyc(len: u32, psize: u32, timing: FlashTiming) -> Cyc {
    let col = psize.min(2) as usize;
    let (typ, max): ([u64; 3], [u64; 3]) = match len {
        l if l <= 16 * 1024 => ([400, 300, 250], [800, 600, 500]),
        l if l <= 64 * 1024 => ([1200, 700, 550], [2400, 1400, 1100]),
        _ => ([2000, 1300, 1000], [4000, 2600, 2000]),
    };
    cyc_from_ms(match timing {
        FlashTiming::Typ => typ[col],
        FlashTiming::Max => max[col],
    })
}

/// Programming time of one access.
pub fn program_cyc(timing: FlashTiming) -> Cyc {
    cyc_from_us(match timing {
        FlashTiming::Typ => 16,
        FlashTiming::Max => 100,
    })
}

/// What a completed operation changed (for the CPU model to apply to code memory).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum FlashOp {
    /// Sector `n` erased (`addr`, `len`).
    Erased {
        /// Sector number.
        n: u32,
        /// First address.
        addr: u32,
        /// Length.
        len: u32,
    },
}

/// The flash interface and the settings sectors.
#[derive(Clone, Debug)]
pub struct Flash {
    acr: u32,
    sr: u32,
    cr: u32,
    optcr: u32,
    key_step: u8,
    locked_until_reset: bool,
    /// BSY until this time: the CPU is stalled.
    pub busy_until: Option<Cyc>,
    /// Sectors 10–11.
    pub store: Vec<u8>,
    /// The store changed since it was last saved.
    pub store_dirty: bool,
    /// Times used.
    pub timing: FlashTiming,
    /// Every erase: (start time, sector, duration).
    pub erases: Vec<(Cyc, u32, Cyc)>,
    /// Words programmed.
    pub programmed: u64,
}

impl Flash {
    /// An interface with an erased settings area.
    pub fn new(timing: FlashTiming) -> Self {
        Flash {
            acr: 0,
            sr: 0,
            cr: 1 << 31,
            optcr: 0x0FFF_AAED,
            key_step: 0,
            locked_until_reset: false,
            busy_until: None,
            store: vec![0xFF; STORE_LEN],
            store_dirty: false,
            timing,
            erases: Vec::new(),
            programmed: 0,
        }
    }

    /// A system reset: registers back to their reset values (an operation in progress is cut
    /// short; the array keeps what was done).
    pub fn reset(&mut self) {
        self.acr = 0;
        self.sr = 0;
        self.cr = 1 << 31;
        self.key_step = 0;
        self.locked_until_reset = false;
        self.busy_until = None;
    }

    /// The CPU is stalled at `now` (an operation in progress).
    pub fn stalled(&self, now: Cyc) -> bool {
        self.busy_until.is_some_and(|t| t > now)
    }

    /// Ends an operation whose time is up (BSY clear, EOP set when EOPIE).
    pub fn advance(&mut self, now: Cyc) {
        if self.busy_until.is_some_and(|t| t <= now) {
            self.busy_until = None;
            if self.cr & (1 << 24) != 0 {
                self.sr |= 1;
            }
        }
    }

    /// The interrupt line (EOP with EOPIE).
    pub fn irq(&self) -> bool {
        self.sr & 1 != 0 && self.cr & (1 << 24) != 0
    }

    /// Interface register read.
    pub fn read(&mut self, off: u32, now: Cyc) -> u32 {
        self.read_reg(off, now)
    }

    /// FLASH_ACR (wait states and the ART accelerator's enables, for `crate::cycles`).
    pub fn acr(&self) -> u32 {
        self.acr
    }

    fn read_reg(&mut self, off: u32, now: Cyc) -> u32 {
        self.advance(now);
        match off {
            0x00 => self.acr,
            0x0C => self.sr | if self.stalled(now) { 1 << 16 } else { 0 },
            0x10 => self.cr,
            0x14 => self.optcr,
            _ => 0,
        }
    }

    /// Interface register write; returns an erase that starts now.
    pub fn write(&mut self, off: u32, v: u32, now: Cyc) -> Option<FlashOp> {
        self.advance(now);
        match off {
            // ICRST/DCRST are self-clearing in effect; LATENCY reads back.
            0x00 => {
                self.acr = v & !((1 << 11) | (1 << 12));
                None
            }
            0x04 => {
                match (self.key_step, v) {
                    (0, 0x4567_0123) => self.key_step = 1,
                    (1, 0xCDEF_89AB) if !self.locked_until_reset => {
                        self.cr &= !(1 << 31);
                        self.key_step = 0;
                    }
                    _ => {
                        self.locked_until_reset = true;
                        self.key_step = 0;
                    }
                }
                None
            }
            0x0C => {
                self.sr &= !(v & 0xF3);
                None
            }
            0x10 => {
                if self.cr & (1 << 31) != 0 {
                    // Locked: only LOCK itself stays; writes are ignored.
                    return None;
                }
                self.cr = v & !(1 << 16);
                if v & (1 << 16) != 0 && v & 2 != 0 {
                    return self.start_erase(v, now);
                }
                None
            }
            0x14 => {
                self.optcr = v;
                None
            }
            _ => None,
        }
    }

    fn start_erase(&mut self, cr: u32, now: Cyc) -> Option<FlashOp> {
        if self.stalled(now) {
            return None;
        }
        let n = (cr >> 3) & 0x1F;
        let Some((addr, len)) = sector(n) else {
            self.sr |= 1 << 7; // PGSERR
            return None;
        };
        let psize = (cr >> 8) & 3;
        let d = erase_cyc(len, psize, self.timing);
        self.busy_until = Some(now + d);
        self.erases.push((now, n, d));
        if (STORE_BASE..STORE_BASE + STORE_LEN as u32).contains(&addr) {
            let o = (addr - STORE_BASE) as usize;
            self.store[o..o + len as usize].fill(0xFF);
            self.store_dirty = true;
        }
        Some(FlashOp::Erased { n, addr, len })
    }

    /// A CPU write of `size` bytes to flash address `addr`: programs it when PG is set and
    /// the size matches PSIZE. Returns false when the write is refused (an error flag set).
    pub fn program(&mut self, addr: u32, size: usize, v: u64, now: Cyc) -> bool {
        self.advance(now);
        if self.cr & 1 == 0 || self.cr & (1 << 31) != 0 {
            self.sr |= 1 << 7; // PGSERR: a write without PG.
            return false;
        }
        let psize_bytes = 1usize << ((self.cr >> 8) & 3);
        if size != psize_bytes {
            self.sr |= 1 << 6; // PGPERR
            return false;
        }
        if (STORE_BASE..STORE_BASE + STORE_LEN as u32).contains(&addr) {
            let o = (addr - STORE_BASE) as usize;
            for i in 0..size {
                if let Some(b) = self.store.get_mut(o + i) {
                    *b &= (v >> (8 * i)) as u8;
                }
            }
            self.store_dirty = true;
        } else {
            // Only the settings area is programmable here: the code sectors are the image.
            self.sr |= 1 << 4; // WRPERR
            return false;
        }
        let start = self.busy_until.filter(|&t| t > now).unwrap_or(now);
        self.busy_until = Some(start + program_cyc(self.timing));
        self.programmed += 1;
        true
    }

    /// A read of the settings area.
    pub fn read_store(&self, addr: u32, size: usize) -> u64 {
        let o = (addr - STORE_BASE) as usize;
        (0..size).fold(0, |acc, i| {
            acc | u64::from(self.store.get(o + i).copied().unwrap_or(0xFF)) << (8 * i)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unlock_erase_program() {
        let mut f = Flash::new(FlashTiming::Typ);
        f.write(0x04, 0x4567_0123, 0);
        f.write(0x04, 0xCDEF_89AB, 0);
        assert_eq!(f.read(0x10, 0) >> 31, 0, "unlocked");
        // Erase sector 10 at x32.
        let op = f.write(0x10, (2 << 8) | (10 << 3) | 2 | (1 << 16), 0);
        assert_eq!(
            op,
            Some(FlashOp::Erased {
                n: 10,
                addr: STORE_BASE,
                len: 128 * 1024
            })
        );
        assert!(f.stalled(cyc_from_ms(999)));
        assert!(!f.stalled(cyc_from_ms(1000)));
        f.write(0x10, (2 << 8) | 1, cyc_from_ms(1000));
        assert!(f.program(STORE_BASE, 4, 0x1234_5678, cyc_from_ms(1000)));
        assert_eq!(f.read_store(STORE_BASE, 4), 0x1234_5678);
        // Programming only clears bits.
        f.advance(cyc_from_ms(1001));
        assert!(f.program(STORE_BASE, 4, 0xFFFF_0000, cyc_from_ms(1001)));
        assert_eq!(f.read_store(STORE_BASE, 4), 0x1234_0000);
        // Wrong size for PSIZE x32.
        assert!(!f.program(STORE_BASE + 4, 2, 0, cyc_from_ms(1002)));
    }
}
