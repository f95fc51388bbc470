//! The independent watchdog (RM0090 §21, "Independent watchdog (IWDG)"), clocked by the LSI
//! RC oscillator, whose frequency the datasheet gives only as a range: STM32F407xx datasheet
//! DS8626, table 33 "LSI oscillator characteristics": f_LSI min 17 kHz, typ 32 kHz, max 47 kHz.
//! The emulated board runs at the frequency it is given (`--lsi-hz`), so both ends can be
//! tried: at 47 kHz a timeout computed for 32 kHz is 32/47 as long.
//!
//! Registers (RM0090 §21.4, table 107): KR 0x00 (0x5555 enables access to PR and RLR, 0xAAAA
//! reloads the counter with RLR, 0xCCCC starts the watchdog; §21.4.1), PR 0x04 (prescaler
//! /4 × 2^PR, PR 2:0, 6 and 7 both /256; §21.4.2), RLR 0x08 (12 bits, reset 0xFFF; §21.4.3),
//! SR 0x0C (PVU bit 0, RVU bit 1: an update of PR/RLR in progress; §21.4.4). The down-counter
//! starts from 0xFFF when started and "when the down-counter reaches the end value (0x000) a
//! reset signal is generated" (§21.3). Once started it cannot be stopped (only a reset does).
//! The PVU/RVU busy time ("up to 5 RC 40 kHz cycles", §21.4.4) is modelled as 5 LSI periods.

use crate::time::{Cyc, CPU_HZ};

/// The watchdog.
#[derive(Clone, Debug)]
pub struct Iwdg {
    /// LSI frequency, Hz.
    pub lsi_hz: u32,
    access: bool,
    pr: u32,
    rlr: u32,
    started: bool,
    /// When the counter was last reloaded, and with what value.
    reload_t: Cyc,
    reload_val: u32,
    /// PR/RLR update busy until.
    update_busy_until: Cyc,
    /// Every reload (KR = 0xAAAA), for the report.
    pub feeds: u64,
}

impl Iwdg {
    /// A stopped watchdog with an LSI of `lsi_hz`.
    pub fn new(lsi_hz: u32) -> Self {
        Iwdg {
            lsi_hz,
            access: false,
            pr: 0,
            rlr: 0xFFF,
            started: false,
            reload_t: 0,
            reload_val: 0xFFF,
            update_busy_until: 0,
            feeds: 0,
        }
    }

    /// Back to the reset state (stopped).
    pub fn reset(&mut self) {
        *self = Iwdg::new(self.lsi_hz);
    }

    /// CPU cycles per counter tick.
    fn tick_cyc(&self) -> f64 {
        let div = 4u64 << self.pr.min(6);
        div as f64 * CPU_HZ as f64 / f64::from(self.lsi_hz)
    }

    /// When the counter reaches 0 (the reset), if running.
    pub fn expires_at(&self) -> Option<Cyc> {
        self.started
            .then(|| self.reload_t + (f64::from(self.reload_val) * self.tick_cyc()) as Cyc)
    }

    /// The timeout the image programmed, at this LSI frequency, s.
    pub fn timeout_s(&self) -> f64 {
        f64::from(self.rlr) * self.tick_cyc() / CPU_HZ as f64
    }

    /// Running.
    pub fn started(&self) -> bool {
        self.started
    }

    /// Register read.
    pub fn read(&self, off: u32, now: Cyc) -> u32 {
        match off {
            0x04 => self.pr,
            0x08 => self.rlr,
            0x0C if now < self.update_busy_until => 3,
            _ => 0,
        }
    }

    /// Register write.
    pub fn write(&mut self, off: u32, v: u32, now: Cyc) {
        let v = v & 0xFFFF;
        let busy = now + (5.0 * CPU_HZ as f64 / f64::from(self.lsi_hz)) as Cyc;
        match off {
            0x00 => match v {
                0x5555 => self.access = true,
                0xAAAA => {
                    self.access = false;
                    self.reload_t = now;
                    self.reload_val = self.rlr;
                    self.feeds += 1;
                }
                0xCCCC => {
                    self.access = false;
                    if !self.started {
                        self.started = true;
                        self.reload_t = now;
                        self.reload_val = 0xFFF;
                    }
                }
                _ => self.access = false,
            },
            0x04 if self.access => {
                self.pr = v & 7;
                self.update_busy_until = busy;
            }
            0x08 if self.access => {
                self.rlr = v & 0xFFF;
                self.update_busy_until = busy;
            }
            _ => {}
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_2s_timeout_at_both_lsi_ends() {
        // embassy's IndependentWatchdog for 2 s at its assumed 32 kHz: PR /64 (4), RLR 999.
        for (lsi, want_s) in [(32_000, 2.0), (47_000, 1.36), (17_000, 3.76)] {
            let mut w = Iwdg::new(lsi);
            w.write(0, 0x5555, 0);
            w.write(4, 4, 0);
            w.write(8, 999, 0);
            w.write(0, 0xCCCC, 0);
            w.write(0, 0xAAAA, 0);
            let s = w.expires_at().unwrap() as f64 / CPU_HZ as f64;
            assert!((s - want_s).abs() < 0.01, "{lsi} Hz: {s} s");
        }
    }
}
