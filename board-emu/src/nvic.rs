//! The Cortex-M4 System Control Space the core model (Unicorn) does not have: the NVIC, the
//! System Control Block and SysTick, as registers, plus the pending/active state and the
//! priority arithmetic that decides which exception is taken. Unicorn executes instructions
//! only; exception entry and return are done by `crate::cpu` from what this module decides.
//!
//! Sources: ST PM0214 (STM32F3/F4 Cortex-M4 programming manual) §4.2 NVIC, §4.3 SCB, §4.4
//! SysTick, §2.3 exception model; ARMv7-M ARM B1.5 (exception model) and B3 (system address
//! map). The STM32F4 implements 4 priority bits (PM0214 §4.2.7: "each priority field holds a
//! priority value, 0-255 … the processor implements only bits[7:4]").

use crate::time::Cyc;

/// Exception numbers (PM0214 §2.3.2, table 17).
pub mod exc {
    /// Reset.
    pub const RESET: u16 = 1;
    /// Non-maskable interrupt.
    pub const NMI: u16 = 2;
    /// HardFault.
    pub const HARD_FAULT: u16 = 3;
    /// MemManage fault.
    pub const MEM_MANAGE: u16 = 4;
    /// BusFault.
    pub const BUS_FAULT: u16 = 5;
    /// UsageFault.
    pub const USAGE_FAULT: u16 = 6;
    /// Supervisor call.
    pub const SVCALL: u16 = 11;
    /// PendSV.
    pub const PENDSV: u16 = 14;
    /// SysTick.
    pub const SYSTICK: u16 = 15;
    /// First external interrupt (IRQ0).
    pub const IRQ0: u16 = 16;
}

/// STM32F407/F429 interrupt lines used by the board (RM0090 table 61, "Vector table for
/// STM32F405xx/07xx and STM32F415xx/17xx").
pub mod irq {
    /// TIM2 global interrupt (embassy-time's driver).
    pub const TIM2: u16 = 28;
    /// USART1 global interrupt (TFT header).
    pub const USART1: u16 = 37;
    /// SDIO global interrupt.
    pub const SDIO: u16 = 49;
    /// TIM5 global interrupt (step timer).
    pub const TIM5: u16 = 50;
    /// DMA2 stream 3 (SDIO).
    pub const DMA2_STREAM3: u16 = 59;
    /// USB OTG FS.
    pub const OTG_FS: u16 = 67;
    /// FLASH global interrupt.
    pub const FLASH: u16 = 4;
}

/// Exceptions modelled (16 system + up to 96 IRQs; the F429 has 91).
pub const N_EXC: usize = 16 + 96;

/// SysTick (PM0214 §4.4): STK_CTRL (ENABLE bit 0, TICKINT bit 1, CLKSOURCE bit 2, COUNTFLAG
/// bit 16), STK_LOAD (24 bits), STK_VAL, STK_CALIB. The counter is derived from time.
#[derive(Clone, Debug, Default)]
pub struct SysTick {
    /// STK_CTRL without COUNTFLAG.
    pub ctrl: u32,
    /// STK_LOAD.
    pub load: u32,
    /// COUNTFLAG (bit 16 of STK_CTRL): set on each wrap, cleared by a read of STK_CTRL.
    pub countflag: bool,
    /// When the counter last held `val_at_base`.
    base_t: Cyc,
    val_at_base: u32,
    /// Wraps are accounted up to here.
    last_t: Cyc,
}

impl SysTick {
    /// Cycles per SysTick count: CLKSOURCE = 1 is the processor clock, 0 is HCLK/8 (PM0214
    /// §4.4.1, STM32F4: "AHB/8").
    fn period(&self) -> u64 {
        if self.ctrl & 4 != 0 {
            1
        } else {
            8
        }
    }

    fn enabled(&self) -> bool {
        self.ctrl & 1 != 0
    }

    /// STK_VAL now.
    pub fn val(&self, now: Cyc) -> u32 {
        if !self.enabled() {
            return self.val_at_base;
        }
        let ticks = (now - self.base_t) / self.period();
        let reload = u64::from(self.load & 0xFF_FFFF) + 1;
        let v = u64::from(self.val_at_base);
        if ticks <= v {
            (v - ticks) as u32
        } else {
            // After reaching 0 the counter reloads with STK_LOAD on the next tick.
            let after = (ticks - v - 1) % reload;
            (reload - 1 - after) as u32
        }
    }

    /// The next time the counter reaches 0 (COUNTFLAG, and the exception when TICKINT).
    pub fn next_wrap(&self, now: Cyc) -> Option<Cyc> {
        if !self.enabled() || self.load & 0xFF_FFFF == 0 {
            return None;
        }
        let v = u64::from(self.val(now));
        // Counts to 0 from `v` takes v ticks; a counter at 0 wraps after LOAD+1.
        let ticks = if v == 0 {
            u64::from(self.load & 0xFF_FFFF) + 1
        } else {
            v
        };
        let phase = (now - self.base_t) % self.period();
        Some(now - phase + ticks * self.period())
    }

    /// Accounts the wraps up to `now`: true when at least one happened (COUNTFLAG set).
    pub fn advance(&mut self, now: Cyc) -> bool {
        let wrapped = self
            .next_wrap(self.last_t)
            .is_some_and(|t| t <= now && now > self.last_t);
        self.last_t = self.last_t.max(now);
        if wrapped {
            self.countflag = true;
        }
        wrapped
    }

    /// Re-bases the counter at `now` with value `v`.
    pub fn rebase(&mut self, now: Cyc, v: u32) {
        self.base_t = now;
        self.last_t = now;
        self.val_at_base = v & 0xFF_FFFF;
    }

    /// A write to STK_CTRL.
    pub fn write_ctrl(&mut self, now: Cyc, v: u32) {
        let cur = self.val(now);
        self.ctrl = v & 0x7;
        self.rebase(now, cur);
    }
}

/// NVIC + SCB state.
#[derive(Clone, Debug)]
pub struct Nvic {
    /// NVIC_ISER: IRQ enabled (exception-number indexed; system exceptions unused here).
    pub enabled: [bool; N_EXC],
    /// Pending (NVIC_ISPR for IRQs, ICSR PENDSTSET/PENDSVSET and SHCSR for system ones).
    pub pending: [bool; N_EXC],
    /// Active (NVIC_IABR, SHCSR ...ACT bits).
    pub active: [bool; N_EXC],
    /// Priority byte of each exception (NVIC_IPR, SCB_SHPR1-3). Fixed ones (-3..-1) aside.
    pub prio: [u8; N_EXC],
    /// Active exceptions, innermost last (for ICSR VECTACTIVE and nesting).
    pub stack: Vec<u16>,
    /// SCB_VTOR (PM0214 §4.3.4).
    pub vtor: u32,
    /// SCB_AIRCR PRIGROUP (bits 10:8, PM0214 §4.3.5).
    pub prigroup: u32,
    /// SCB_SCR (SLEEPONEXIT bit 1, SLEEPDEEP bit 2, SEVONPEND bit 4; PM0214 §4.3.6).
    pub scr: u32,
    /// SCB_CCR (PM0214 §4.3.7), STKALIGN (bit 9) set at reset.
    pub ccr: u32,
    /// SCB_SHCSR enable bits (MEMFAULTENA 16, BUSFAULTENA 17, USGFAULTENA 18; §4.3.9).
    pub shcsr_ena: u32,
    /// SCB_CFSR (§4.3.10), SCB_HFSR (§4.3.11), MMFAR, BFAR.
    pub cfsr: u32,
    /// SCB_HFSR.
    pub hfsr: u32,
    /// SCB_BFAR.
    pub bfar: u32,
    /// CPACR (§4.6.1; the core model's FPU is always enabled, the value is kept for reads).
    pub cpacr: u32,
    /// FPCCR (§4.6.2): ASPEN (31) and LSPEN (30) set at reset.
    pub fpccr: u32,
    /// SysTick.
    pub systick: SysTick,
    /// A write of AIRCR with SYSRESETREQ (bit 2) and the key 0x05FA asked for a reset.
    pub reset_requested: bool,
}

impl Default for Nvic {
    fn default() -> Self {
        Nvic {
            enabled: [false; N_EXC],
            pending: [false; N_EXC],
            active: [false; N_EXC],
            prio: [0; N_EXC],
            stack: Vec::new(),
            vtor: 0,
            prigroup: 0,
            scr: 0,
            ccr: 1 << 9,
            shcsr_ena: 0,
            cfsr: 0,
            hfsr: 0,
            bfar: 0,
            cpacr: 0,
            fpccr: 0xC000_0000,
            systick: SysTick::default(),
            reset_requested: false,
        }
    }
}

impl Nvic {
    /// Priority of exception `e` as a signed value (Reset -3, NMI -2, HardFault -1; others
    /// their priority byte's group-priority part, PM0214 §4.3.5 table 40 "priority grouping").
    pub fn group_prio(&self, e: u16) -> i32 {
        match e {
            exc::RESET => -3,
            exc::NMI => -2,
            exc::HARD_FAULT => -1,
            _ => {
                let p = u32::from(self.prio[usize::from(e)]) & 0xF0;
                // PRIGROUP n: bits [7:n+1] are the group priority.
                let mask = !((1u32 << (self.prigroup + 1)) - 1) & 0xFF;
                (p & mask) as i32
            }
        }
    }

    /// The execution priority (ARMv7-M B1.5.4): the highest (lowest value) of the active
    /// exceptions' group priorities, BASEPRI when non-zero, and 0 when PRIMASK is set; 256 in
    /// thread mode with nothing masked.
    pub fn exec_prio(&self, primask: bool, basepri: u32) -> i32 {
        let mut p = 256;
        for &e in &self.stack {
            p = p.min(self.group_prio(e));
        }
        let bp = (basepri & 0xF0) as i32;
        if bp != 0 {
            let mask = !((1i32 << (self.prigroup + 1)) - 1) & 0xFF;
            p = p.min(bp & mask);
        }
        if primask {
            p = p.min(0);
        }
        p
    }

    /// Whether exception `e` may be taken when pending (IRQs need their NVIC_ISER bit).
    fn can_pend(&self, e: u16) -> bool {
        if e >= exc::IRQ0 {
            self.enabled[usize::from(e)]
        } else {
            true
        }
    }

    /// The pending exception with the highest priority (ties: the lowest number, PM0214
    /// §2.3.6), if it preempts the current execution priority.
    pub fn next_to_take(&self, primask: bool, basepri: u32) -> Option<u16> {
        let cur = self.exec_prio(primask, basepri);
        let mut best: Option<(i32, u16)> = None;
        for e in 1..N_EXC as u16 {
            if !self.pending[usize::from(e)] || !self.can_pend(e) {
                continue;
            }
            let p = self.group_prio(e);
            if best.is_none_or(|(bp, _)| p < bp) {
                best = Some((p, e));
            }
        }
        best.filter(|(p, _)| *p < cur).map(|(_, e)| e)
    }

    /// Any exception pending and enabled, taken or not (wakes WFI/WFE when it would preempt,
    /// or with SCR.SEVONPEND for WFE).
    pub fn any_pending(&self) -> bool {
        (1..N_EXC).any(|e| self.pending[e] && self.can_pend(e as u16))
    }

    /// Pends exception `e`.
    pub fn pend(&mut self, e: u16) {
        if let Some(p) = self.pending.get_mut(usize::from(e)) {
            *p = true;
        }
    }

    /// Marks `e` active (its handler entered).
    pub fn activate(&mut self, e: u16) {
        self.pending[usize::from(e)] = false;
        self.active[usize::from(e)] = true;
        self.stack.push(e);
    }

    /// Ends the innermost active exception; returns it.
    pub fn deactivate(&mut self) -> Option<u16> {
        let e = self.stack.pop()?;
        self.active[usize::from(e)] = false;
        Some(e)
    }

    /// ICSR (PM0214 §4.3.3): VECTACTIVE [8:0], RETTOBASE bit 11, VECTPENDING [18:12],
    /// ISRPENDING bit 22, PENDSTSET bit 26, PENDSVSET bit 28.
    pub fn icsr(&self) -> u32 {
        let active = u32::from(self.stack.last().copied().unwrap_or(0));
        let pending = (1..N_EXC)
            .find(|&e| self.pending[e] && self.can_pend(e as u16))
            .unwrap_or(0) as u32;
        let mut v = active | (pending << 12);
        if self.stack.len() <= 1 {
            v |= 1 << 11;
        }
        if (16..N_EXC).any(|e| self.pending[e]) {
            v |= 1 << 22;
        }
        if self.pending[usize::from(exc::SYSTICK)] {
            v |= 1 << 26;
        }
        if self.pending[usize::from(exc::PENDSV)] {
            v |= 1 << 28;
        }
        v
    }

    /// ICSR write: PENDSVSET (28), PENDSVCLR (27), PENDSTSET (26), PENDSTCLR (25),
    /// NMIPENDSET (31).
    pub fn write_icsr(&mut self, v: u32) {
        if v & (1 << 28) != 0 {
            self.pend(exc::PENDSV);
        }
        if v & (1 << 27) != 0 {
            self.pending[usize::from(exc::PENDSV)] = false;
        }
        if v & (1 << 26) != 0 {
            self.pend(exc::SYSTICK);
        }
        if v & (1 << 25) != 0 {
            self.pending[usize::from(exc::SYSTICK)] = false;
        }
        if v & (1 << 31) != 0 {
            self.pend(exc::NMI);
        }
    }

    /// A 32-bit bank of the IRQ bit arrays (ISER/ICER/ISPR/ICPR/IABR word `n`).
    fn bank(arr: &[bool; N_EXC], n: usize) -> u32 {
        (0..32).fold(0, |acc, i| {
            let e = 16 + n * 32 + i;
            if e < N_EXC && arr[e] {
                acc | (1 << i)
            } else {
                acc
            }
        })
    }

    fn set_bank(arr: &mut [bool; N_EXC], n: usize, v: u32, to: bool) {
        for i in 0..32 {
            let e = 16 + n * 32 + i;
            if v & (1 << i) != 0 && e < N_EXC {
                arr[e] = to;
            }
        }
    }

    /// Reads a System Control Space register at `off` from 0xE000_E000 (word access).
    pub fn read(&mut self, off: u32, now: Cyc) -> u32 {
        match off {
            // SysTick, PM0214 §4.4.
            0x010 => {
                self.systick.advance(now);
                let v = self.systick.ctrl | (u32::from(self.systick.countflag) << 16);
                self.systick.countflag = false;
                v
            }
            0x014 => self.systick.load,
            0x018 => self.systick.val(now),
            // STK_CALIB: TENMS for 1 ms at HCLK/8 (21 MHz), NOREF clear, SKEW set.
            0x01C => 0x4000_0000 | 20_999,
            // NVIC_ISER/ICER (both read the enable bits), ISPR/ICPR, IABR; PM0214 §4.2.2-4.2.6.
            0x100..=0x10C => Self::bank(&self.enabled, ((off - 0x100) / 4) as usize),
            0x180..=0x18C => Self::bank(&self.enabled, ((off - 0x180) / 4) as usize),
            0x200..=0x20C => Self::bank(&self.pending, ((off - 0x200) / 4) as usize),
            0x280..=0x28C => Self::bank(&self.pending, ((off - 0x280) / 4) as usize),
            0x300..=0x30C => Self::bank(&self.active, ((off - 0x300) / 4) as usize),
            // NVIC_IPR0-, one byte per IRQ (§4.2.7).
            0x400..=0x45C => {
                let first = 16 + (off - 0x400) as usize;
                (0..4).fold(0, |acc, i| {
                    acc | u32::from(self.prio.get(first + i).copied().unwrap_or(0)) << (8 * i)
                })
            }
            // CPUID (§4.3.1): Cortex-M4 r0p1.
            0xD00 => 0x410F_C241,
            0xD04 => self.icsr(),
            0xD08 => self.vtor,
            0xD0C => 0xFA05_0000 | (self.prigroup << 8),
            0xD10 => self.scr,
            0xD14 => self.ccr,
            // SHPR1-3 (§4.3.8): priorities of exceptions 4..15.
            0xD18..=0xD20 => {
                let first = 4 + (off - 0xD18) as usize;
                (0..4).fold(0, |acc, i| acc | u32::from(self.prio[first + i]) << (8 * i))
            }
            // SHCSR (§4.3.9).
            0xD24 => {
                let mut v = self.shcsr_ena;
                for (e, bit) in [(4usize, 0), (5, 1), (6, 3), (11, 7), (14, 10), (15, 11)] {
                    if self.active[e] {
                        v |= 1 << bit;
                    }
                }
                v
            }
            0xD28 => self.cfsr,
            0xD2C => self.hfsr,
            0xD38 => self.bfar,
            0xD88 => self.cpacr,
            // DHCSR (ARMv7-M C1.6.2): no debugger attached (C_DEBUGEN clear).
            0xDF0 => 0,
            0xF34 => self.fpccr,
            _ => 0,
        }
    }

    /// Writes a System Control Space register (word access).
    pub fn write(&mut self, off: u32, v: u32, now: Cyc) {
        match off {
            0x010 => self.systick.write_ctrl(now, v),
            0x014 => self.systick.load = v & 0xFF_FFFF,
            // "A write of any value clears the field to 0, and also clears COUNTFLAG".
            0x018 => {
                self.systick.rebase(now, 0);
                self.systick.countflag = false;
            }
            0x100..=0x10C => {
                Self::set_bank(&mut self.enabled, ((off - 0x100) / 4) as usize, v, true)
            }
            0x180..=0x18C => {
                Self::set_bank(&mut self.enabled, ((off - 0x180) / 4) as usize, v, false)
            }
            0x200..=0x20C => {
                Self::set_bank(&mut self.pending, ((off - 0x200) / 4) as usize, v, true)
            }
            0x280..=0x28C => {
                Self::set_bank(&mut self.pending, ((off - 0x280) / 4) as usize, v, false)
            }
            0x400..=0x45C => {
                let first = 16 + (off - 0x400) as usize;
                for i in 0..4 {
                    if let Some(p) = self.prio.get_mut(first + i) {
                        *p = ((v >> (8 * i)) & 0xF0) as u8;
                    }
                }
            }
            0xD04 => self.write_icsr(v),
            0xD08 => self.vtor = v & 0xFFFF_FE00,
            // Writes need the key 0x05FA in VECTKEY (bits 31:16).
            0xD0C if v >> 16 == 0x05FA => {
                self.prigroup = (v >> 8) & 7;
                if v & 4 != 0 {
                    self.reset_requested = true;
                }
            }
            0xD10 => self.scr = v & 0x16,
            0xD14 => self.ccr = v,
            0xD18..=0xD20 => {
                let first = 4 + (off - 0xD18) as usize;
                for i in 0..4 {
                    self.prio[first + i] = ((v >> (8 * i)) & 0xF0) as u8;
                }
            }
            0xD24 => self.shcsr_ena = v & (7 << 16),
            // CFSR and HFSR are write-1-to-clear.
            0xD28 => self.cfsr &= !v,
            0xD2C => self.hfsr &= !v,
            0xD88 => self.cpacr = v,
            0xF34 => self.fpccr = v,
            // STIR (§4.2.8): software-triggered interrupt.
            0xF00 => self.pend(exc::IRQ0 + (v & 0x1FF) as u16),
            _ => {}
        }
    }

    /// The byte-wide view of IPR/SHPR writes (`strb`): merged into the word.
    pub fn write_sized(&mut self, off: u32, size: usize, v: u32, now: Cyc) {
        if size == 4 {
            return self.write(off, v, now);
        }
        let word = off & !3;
        let shift = (off & 3) * 8;
        let mask = if size == 1 { 0xFF } else { 0xFFFF } << shift;
        let cur = match word {
            // Set/clear registers: write only the addressed bits.
            0x100..=0x2FC => 0,
            _ => self.read(word, now),
        };
        self.write(word, (cur & !mask) | ((v << shift) & mask), now);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn priority_and_preemption() {
        let mut n = Nvic::default();
        let tim5 = exc::IRQ0 + irq::TIM5;
        let usart = exc::IRQ0 + irq::USART1;
        n.enabled[usize::from(tim5)] = true;
        n.enabled[usize::from(usart)] = true;
        n.prio[usize::from(tim5)] = 0x00;
        n.prio[usize::from(usart)] = 0x10;
        n.pend(usart);
        assert_eq!(n.next_to_take(false, 0), Some(usart));
        assert_eq!(n.next_to_take(true, 0), None, "PRIMASK masks");
        n.activate(usart);
        n.pend(tim5);
        assert_eq!(
            n.next_to_take(false, 0),
            Some(tim5),
            "higher priority preempts"
        );
        n.activate(tim5);
        n.pend(usart);
        assert_eq!(
            n.next_to_take(false, 0),
            None,
            "same or lower never preempts"
        );
        assert_eq!(n.deactivate(), Some(tim5));
        assert_eq!(n.deactivate(), Some(usart));
        assert_eq!(
            n.next_to_take(false, 0x10),
            None,
            "BASEPRI masks priority 0x10"
        );
        assert_eq!(n.next_to_take(false, 0x20), Some(usart));
    }

    #[test]
    fn systick_counts_down_and_wraps() {
        let mut s = SysTick {
            load: 99,
            ..Default::default()
        };
        s.rebase(0, 0);
        s.write_ctrl(0, 0b111);
        assert_eq!(s.val(0), 0);
        assert_eq!(s.val(1), 99);
        assert_eq!(s.val(100), 0);
        assert_eq!(s.next_wrap(1), Some(100));
    }
}
