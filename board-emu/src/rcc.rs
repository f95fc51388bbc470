//! RCC and PWR: clocks that are ready when asked for, and the reset flags that tell the image
//! why it restarted.
//!
//! RCC (RM0090 §7.3 for the STM32F407, §6.3 for the F429; table 34/32 register maps): CR 0x00
//! (HSION 0 / HSIRDY 1, HSEON 16 / HSERDY 17, PLLON 24 / PLLRDY 25, PLLI2SON 26 / PLLI2SRDY 27,
//! PLLSAION 28 / PLLSAIRDY 29; §7.3.1), CFGR 0x08 (SW 1:0, SWS 3:2 follows SW; §7.3.3), BDCR
//! 0x70 (LSEON 0 / LSERDY 1; §7.3.20), CSR 0x74 (LSION 0 / LSIRDY 1, RMVF 24, BORRSTF 25,
//! PINRSTF 26, PORRSTF 27, SFTRSTF 28, IWDGRSTF 29, WWDGRSTF 30, LPWRRSTF 31; §7.3.21). Every
//! ready bit follows its enable bit at once (the oscillators' start-up and the PLL's lock
//! times, ~100 µs to 2 ms, are not modelled). Other registers (enables, resets, PLLCFGR...)
//! read back what was written.
//!
//! Reset flags (§7.3.21 and §7.1.2 "System reset"): a power-on sets PORRSTF, PINRSTF and
//! BORRSTF; an independent-watchdog reset sets IWDGRSTF and PINRSTF (the internal reset drives
//! NRST low); a software reset (AIRCR.SYSRESETREQ) sets SFTRSTF and PINRSTF. The flags survive
//! system resets and are cleared only by writing RMVF.
//!
//! PWR (RM0090 §5.4): CR 0x00 (DBP 8, VOS 15:14, ODEN 16, ODSWEN 17), CSR 0x04 (VOSRDY 14,
//! ODRDY 16, ODSWRDY 17: set when asked for; §5.4.2, the F429's over-drive, §5.1.4).

use std::collections::BTreeMap;

/// Why the MCU reset.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ResetKind {
    /// Power applied.
    PowerOn,
    /// The independent watchdog expired.
    Watchdog,
    /// AIRCR.SYSRESETREQ (`SCB::sys_reset`, after a fault).
    Software,
    /// The reset button (NRST).
    Pin,
}

/// RCC + PWR registers.
#[derive(Clone, Debug, Default)]
pub struct Rcc {
    cr: u32,
    cfgr: u32,
    bdcr: u32,
    csr_lsion: u32,
    /// The reset flags (bits 31:25 of RCC_CSR).
    pub reset_flags: u32,
    other: BTreeMap<u32, u32>,
    pwr_cr: u32,
}

impl Rcc {
    /// After a reset of `kind`: registers at their reset values, the reset flags updated.
    pub fn reset(&mut self, kind: ResetKind) {
        let flags = match kind {
            ResetKind::PowerOn => (1 << 27) | (1 << 26) | (1 << 25),
            ResetKind::Watchdog => self.reset_flags | (1 << 29) | (1 << 26),
            ResetKind::Software => self.reset_flags | (1 << 28) | (1 << 26),
            ResetKind::Pin => self.reset_flags | (1 << 26),
        };
        *self = Rcc {
            // HSION set at reset (§7.3.1, reset value 0x0000 XX83).
            cr: 0x83,
            reset_flags: flags,
            ..Default::default()
        };
    }

    /// RCC register read (`off` from 0x4002_3800).
    pub fn read(&self, off: u32) -> u32 {
        match off {
            0x00 => {
                let on = self.cr & ((1 << 0) | (1 << 16) | (1 << 24) | (1 << 26) | (1 << 28));
                self.cr | (on << 1)
            }
            0x08 => (self.cfgr & !0xC) | ((self.cfgr & 3) << 2),
            0x70 => self.bdcr | ((self.bdcr & 1) << 1),
            0x74 => self.csr_lsion | ((self.csr_lsion & 1) << 1) | self.reset_flags,
            _ => self.other.get(&off).copied().unwrap_or(0),
        }
    }

    /// RCC register write.
    pub fn write(&mut self, off: u32, v: u32) {
        match off {
            0x00 => self.cr = v & !((1 << 1) | (1 << 17) | (1 << 25) | (1 << 27) | (1 << 29)),
            0x08 => self.cfgr = v & !0xC,
            0x70 => self.bdcr = v & !2,
            0x74 => {
                self.csr_lsion = v & 1;
                if v & (1 << 24) != 0 {
                    self.reset_flags = 0;
                }
            }
            _ => {
                self.other.insert(off, v);
            }
        }
    }

    /// PWR register read (`off` from 0x4000_7000).
    pub fn pwr_read(&self, off: u32) -> u32 {
        match off {
            0x00 => self.pwr_cr,
            0x04 => {
                let mut v = 1 << 14;
                if self.pwr_cr & (1 << 16) != 0 {
                    v |= 1 << 16;
                }
                if self.pwr_cr & (1 << 17) != 0 {
                    v |= 1 << 17;
                }
                v
            }
            _ => 0,
        }
    }

    /// PWR register write.
    pub fn pwr_write(&mut self, off: u32, v: u32) {
        if off == 0 {
            self.pwr_cr = v;
        }
    }
}
