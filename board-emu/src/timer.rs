//! General-purpose timers TIM2..TIM5 (RM0090 §18, "General-purpose timers (TIM2 to TIM5)"):
//! TIM2 is embassy-time's driver, TIM5 the step timer, TIM4 the fans' PWM. The counter counts
//! up on the timer clock (84 MHz, `time::TIM_APB1_HZ`) divided by PSC+1, from 0 to ARR, then
//! wraps with an update event; compare channel x sets CCxIF when the counter reaches CCRx.
//! Everything is derived from virtual time: the counter is computed when read, flags are
//! set by [`Timer::advance`] up to the current time, and [`Timer::next_event`] says when the
//! next enabled interrupt flag will be set, so the CPU run stops exactly there.
//!
//! Registers (RM0090 §18.4.21, table 99 "TIM2 to TIM5 register map and reset values"):
//! CR1 0x00 (CEN bit 0, UDIS bit 1, URS bit 2, OPM bit 3, DIR bit 4, ARPE bit 7; §18.4.1),
//! DIER 0x0C (UIE bit 0, CC1IE..CC4IE bits 1..4; §18.4.4), SR 0x10 (UIF bit 0, CC1IF..CC4IF
//! bits 1..4, rc_w0; §18.4.5), EGR 0x14 (UG bit 0; §18.4.6), CNT 0x24 (§18.4.10), PSC 0x28
//! (buffered: loaded at the next update event, §18.4.11 and §18.3.2), ARR 0x2C (§18.4.12),
//! CCR1..CCR4 0x34..0x40 (§18.4.13-16). TIM2 and TIM5 are 32-bit, TIM3/TIM4 16-bit (§18.1).
//! Not modelled: down/centre-aligned counting (DIR, CMS), one-pulse mode, slave modes, input
//! capture, DMA requests, the preload of CCRx (OCxPE) and ARR (ARPE): writes take effect at
//! once.

use crate::time::Cyc;
use std::collections::BTreeMap;

/// One general-purpose timer.
#[derive(Clone, Debug)]
pub struct Timer {
    /// A 32-bit counter (TIM2, TIM5).
    pub bits32: bool,
    cr1: u32,
    dier: u32,
    sr: u32,
    /// PSC as written (preload).
    psc: u32,
    /// The prescaler in force.
    psc_active: u32,
    arr: u32,
    /// CCR1..CCR4.
    pub ccr: [u32; 4],
    /// Registers kept as written (CR2, SMCR, CCMRx, CCER, DCR, OR...).
    other: BTreeMap<u32, u32>,
    /// The counter's linear count (not wrapped) at `base_t`.
    base_cnt: u64,
    base_t: Cyc,
    /// Flags are up to date until here.
    last_t: Cyc,
    /// Every write of CCR1: (when, when the counter reaches it): the step timer's schedule
    /// as the image armed it.
    pub ccr1_writes: Vec<(Cyc, Cyc)>,
    /// Keep `ccr1_writes` (the step timer only).
    pub log_ccr1: bool,
}

impl Timer {
    /// A timer in its reset state.
    pub fn new(bits32: bool) -> Self {
        Timer {
            bits32,
            cr1: 0,
            dier: 0,
            sr: 0,
            psc: 0,
            psc_active: 0,
            arr: if bits32 { u32::MAX } else { 0xFFFF },
            ccr: [0; 4],
            other: BTreeMap::new(),
            base_cnt: 0,
            base_t: 0,
            last_t: 0,
            ccr1_writes: Vec::new(),
            log_ccr1: false,
        }
    }

    fn running(&self) -> bool {
        self.cr1 & 1 != 0
    }

    /// CPU cycles per count (the timer clock is half the CPU clock).
    fn period(&self) -> u64 {
        2 * (u64::from(self.psc_active) + 1)
    }

    fn modulus(&self) -> u64 {
        u64::from(self.arr) + 1
    }

    /// Linear count at `t` (≥ `base_t`).
    fn lin(&self, t: Cyc) -> u64 {
        if self.running() {
            self.base_cnt + (t.saturating_sub(self.base_t)) / self.period()
        } else {
            self.base_cnt
        }
    }

    /// When the linear count reaches `l` (> current).
    fn time_of(&self, l: u64) -> Cyc {
        self.base_t + (l - self.base_cnt) * self.period()
    }

    /// When the counter next changes after `t` (None: stopped).
    pub fn next_tick(&self, t: Cyc) -> Option<Cyc> {
        self.running().then(|| self.time_of(self.lin(t) + 1))
    }

    /// The counter value at `t`.
    pub fn cnt(&self, t: Cyc) -> u32 {
        (self.lin(t) % self.modulus()) as u32
    }

    /// Re-bases the counter at `t` to `cnt`, keeping the prescaler's phase.
    fn rebase(&mut self, t: Cyc, cnt: u64) {
        let phase = if self.running() {
            t.saturating_sub(self.base_t) % self.period()
        } else {
            0
        };
        self.base_t = t - phase;
        self.base_cnt = cnt;
    }

    /// Sets the flags of every overflow and compare match up to `now` (and loads a new PSC at
    /// the first overflow).
    pub fn advance(&mut self, now: Cyc) {
        if now <= self.last_t {
            return;
        }
        if !self.running() {
            self.last_t = now;
            return;
        }
        let m = self.modulus();
        let l0 = self.lin(self.last_t);
        let l1 = self.lin(now);
        if l1 > l0 {
            let first_ovf = (l0 / m + 1) * m;
            if first_ovf <= l1 {
                if self.cr1 & 2 == 0 {
                    self.sr |= 1;
                }
                if self.psc != self.psc_active {
                    // The update event loads the new prescaler: re-base there and go on.
                    let t_o = self.time_of(first_ovf);
                    self.set_compare_flags(l0, first_ovf);
                    self.psc_active = self.psc;
                    self.base_t = t_o;
                    self.base_cnt = 0;
                    self.last_t = t_o;
                    return self.advance(now);
                }
            }
            self.set_compare_flags(l0, l1);
        }
        self.last_t = now;
    }

    fn set_compare_flags(&mut self, l0: u64, l1: u64) {
        let m = self.modulus();
        for (i, &c) in self.ccr.iter().enumerate() {
            let c = u64::from(c);
            if c >= m {
                continue;
            }
            let mut k = l0 - l0 % m + c;
            if k <= l0 {
                k += m;
            }
            if k <= l1 {
                self.sr |= 1 << (i + 1);
            }
        }
    }

    /// When the next interrupt-enabled flag will be set (or a pending PSC load happens).
    pub fn next_event(&self, now: Cyc) -> Option<Cyc> {
        if !self.running() {
            return None;
        }
        let m = self.modulus();
        let l = self.lin(now);
        let mut best: Option<u64> = None;
        let mut consider = |k: u64| best = Some(best.map_or(k, |b| b.min(k)));
        if self.dier & 1 != 0 || self.psc != self.psc_active {
            consider((l / m + 1) * m);
        }
        for (i, &c) in self.ccr.iter().enumerate() {
            if self.dier & (1 << (i + 1)) == 0 || u64::from(c) >= m {
                continue;
            }
            let mut k = l - l % m + u64::from(c);
            if k <= l {
                k += m;
            }
            consider(k);
        }
        best.map(|k| self.time_of(k))
    }

    /// The interrupt line: a flag set whose interrupt is enabled.
    pub fn irq(&self) -> bool {
        self.sr & self.dier & 0x5F != 0
    }

    /// A read of the register at `off`.
    pub fn read(&mut self, off: u32, now: Cyc) -> u32 {
        self.advance(now);
        match off {
            0x00 => self.cr1,
            0x0C => self.dier,
            0x10 => self.sr,
            0x24 => self.cnt(now),
            0x28 => self.psc,
            0x2C => self.arr,
            0x34..=0x40 => self.ccr[((off - 0x34) / 4) as usize],
            _ => self.other.get(&off).copied().unwrap_or(0),
        }
    }

    /// A write of `v` to the register at `off`.
    pub fn write(&mut self, off: u32, v: u32, now: Cyc) {
        self.advance(now);
        let width = |v: u32| if self.bits32 { v } else { v & 0xFFFF };
        match off {
            0x00 => {
                let cnt = self.lin(now);
                let was = self.running();
                self.cr1 = v & 0x3FF;
                if was != self.running() {
                    self.base_t = now;
                    self.base_cnt = cnt % self.modulus();
                }
            }
            0x0C => self.dier = v & 0x5F5F,
            // rc_w0: writing 0 clears a flag, 1 leaves it.
            0x10 => self.sr &= v,
            0x14 => {
                if v & 1 != 0 {
                    // UG: counter and prescaler counter cleared, PSC loaded, UIF unless URS.
                    self.psc_active = self.psc;
                    self.base_t = now;
                    self.base_cnt = 0;
                    if self.cr1 & 4 == 0 && self.cr1 & 2 == 0 {
                        self.sr |= 1;
                    }
                }
                self.sr |= v & 0x1E;
            }
            0x24 => {
                let c = u64::from(width(v));
                self.rebase(now, c);
            }
            0x28 => self.psc = v & 0xFFFF,
            0x2C => {
                let cnt = u64::from(self.cnt(now));
                self.arr = width(v);
                self.rebase(now, cnt);
            }
            0x34..=0x40 => {
                let i = ((off - 0x34) / 4) as usize;
                self.ccr[i] = width(v);
                if i == 0 && self.log_ccr1 {
                    // When the counter will reach the new value (the compare match).
                    let m = self.modulus();
                    let l = self.lin(now);
                    let mut k = l - l % m + u64::from(self.ccr[0]);
                    if k <= l {
                        k += m;
                    }
                    let t = if self.running() { self.time_of(k) } else { now };
                    self.ccr1_writes.push((now, t));
                }
            }
            _ => {
                self.other.insert(off, v);
            }
        }
        self.last_t = now;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_compares_and_wraps() {
        let mut t = Timer::new(false);
        t.write(0x28, 83, 0); // 1 MHz
        t.write(0x14, 1, 0); // UG loads PSC
        t.write(0x10, 0, 0);
        t.write(0x34, 10, 0);
        t.write(0x0C, 0b10, 0);
        t.write(0x00, 1, 0);
        assert_eq!(t.cnt(168 * 5), 5);
        assert_eq!(t.next_event(0), Some(168 * 10));
        t.advance(168 * 9);
        assert!(!t.irq());
        t.advance(168 * 10);
        assert!(t.irq());
        t.write(0x10, !0b10, 168 * 10);
        assert!(!t.irq());
        // Wrap at 65536 µs.
        assert_eq!(t.cnt(168 * 65_536), 0);
    }

    #[test]
    fn a_new_prescaler_waits_for_the_update_event() {
        let mut t = Timer::new(true);
        t.write(0x00, 1, 0);
        t.write(0x28, 1, 0);
        assert_eq!(t.cnt(20), 10, "old prescaler (1) still in force");
        t.write(0x14, 1, 20);
        assert_eq!(t.cnt(20 + 40), 10, "new prescaler (2) after UG");
    }
}
