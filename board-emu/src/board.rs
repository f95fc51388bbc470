//! The emulated SKR 2 without its CPU: every peripheral model, the memory-mapped I/O bus that
//! routes the image's register accesses to them (RM0090 §2.3, table 1 "STM32F4xx register
//! boundary addresses"), the board's wiring between pins and models, and the event clock.
//!
//! Register blocks served (everything else in the peripheral space reads back what was
//! written, and the first access of each unmodelled block is listed in `Board::unmodelled`):
//! TIM2 0x4000_0000, TIM4 0x4000_0800, TIM5 0x4000_0C00, IWDG 0x4000_3000, PWR 0x4000_7000,
//! USART1 0x4001_1000, ADC1 0x4001_2000 (common 0x4001_2300), SDIO 0x4001_2C00, GPIOA..E
//! 0x4002_0000..0x4002_1000, RCC 0x4002_3800, FLASH 0x4002_3C00, DMA2 0x4002_6400, USB OTG FS
//! 0x5000_0000 (`crate::otg`, with the USB host of `crate::usbhost` on its cable), and the Cortex-M4's System Control Space 0xE000_E000 (`crate::nvic`).

use crate::adc::{Adc, Heaters, BED, HOTEND};
use crate::axes::{Axes, DIR, EN, ENDSTOP, SAFE_POWER, STEP};
use crate::cycles::{Clock, ClockModel};
use crate::flash::{Flash, FlashOp, STORE_BASE, STORE_LEN};
use crate::gpio::{Edge, Gpio, Pin};
use crate::iwdg::Iwdg;
use crate::nvic::{exc, irq, Nvic};
use crate::otg::Otg;
use crate::rcc::{Rcc, ResetKind};
use crate::sdio::Sdio;
use crate::time::Cyc;
use crate::timer::Timer;
use crate::tmc::{Drivers, UART_PINS};
use crate::usart::Usart;
use crate::usbhost::UsbHost;
use std::collections::{BTreeMap, BTreeSet};

/// Heater pins: hot end PB3, bed PD7.
pub const HEATER_PINS: [Pin; 2] = [Pin::new('B', 3), Pin::new('D', 7)];
/// The pause button (E0DET, PC2), to ground, pulled up.
pub const PAUSE_BUTTON: Pin = Pin::new('C', 2);

/// Registers whose read changes state: USART1 SR (the SR-then-DR clearing sequences) and DR
/// (clears RXNE), the timers' CNT (counter-polling detection), ADC1 DR (clears EOC), the SDIO
/// FIFO, OTG_FS GRXSTSP and the data FIFOs (pops).
fn read_has_side_effects(word: u32) -> bool {
    matches!(
        word,
        0x4001_1000 | 0x4001_1004 | 0x4000_0024 | 0x4000_0824 | 0x4000_0C24 | 0x4001_204C
            | 0x4001_2C80..=0x4001_2CFF
            | 0x5000_0020
            | 0x5000_1000..=0x5003_FFFF
    )
}

/// Why the CPU run stopped (set by the hooks).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stop {
    /// WFI or WFE (`wfe`) at an address; resume after it (`next`).
    Sleep {
        /// WFE (else WFI).
        wfe: bool,
        /// Address after the instruction.
        next: u32,
    },
    /// A branch to an EXC_RETURN value.
    ExcReturn(u32),
    /// A register write may have changed what happens next.
    Resched,
    /// The core model raised an exception of its own (QEMU's exception number).
    CoreException {
        /// QEMU's `EXCP_*` number.
        intno: u32,
        /// Where.
        pc: u32,
    },
}

/// A thread-mode stall injected from outside (see `crate::fault`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Stall {
    /// The stall starts at the first thread-mode read of TIM5_CNT at or after this time.
    pub after: Cyc,
    /// How long thread mode is held (interrupts still run).
    pub duration: Cyc,
}

/// The board.
pub struct Board {
    /// Instructions executed.
    pub insns: u64,
    /// Cycles the core was busy executing (instructions, wait states, exception entries:
    /// `crate::cycles`).
    pub cycles: Cyc,
    /// The clock model and its state (block costs, the ART accelerator).
    pub clock: Clock,
    /// Busy cycles by the exception that was running (0: thread mode), for the CPU load.
    pub busy_by_exc: Vec<Cyc>,
    /// Cycles passed without instructions (sleep, stalls).
    pub skipped: Cyc,
    /// Stop the CPU run before this busy-cycle count.
    pub stop_at: Cyc,
    /// Why the last run stopped.
    pub stop: Option<Stop>,
    /// The WFE event register.
    pub event_reg: bool,
    /// WFI/WFE/SEV locations in the image, by halfword offset from 0x0800_0000.
    pub special: Vec<u8>,
    /// NVIC, SCB, SysTick.
    pub nvic: Nvic,
    /// RCC and PWR.
    pub rcc: Rcc,
    /// Flash interface and settings sectors.
    pub flash: Flash,
    /// GPIO A..E.
    pub gpio: Gpio,
    /// TIM2 (embassy-time), TIM4 (fans), TIM5 (steps).
    pub tim2: Timer,
    /// TIM4.
    pub tim4: Timer,
    /// TIM5.
    pub tim5: Timer,
    /// USART1 (host port).
    pub usart1: Usart,
    /// ADC1.
    pub adc: Adc,
    /// The heater plants.
    pub heaters: Heaters,
    /// IWDG.
    pub iwdg: Iwdg,
    /// The TMC2209 modules.
    pub tmc: Drivers,
    /// The mechanics.
    pub axes: Axes,
    /// SDIO and its card, DMA2 stream 3.
    pub sdio: Sdio,
    /// USB OTG FS (device mode).
    pub otg: Otg,
    /// The USB host at the other end of the cable.
    pub usb: UsbHost,
    /// Registers of blocks without a model: read back what was written.
    pub regs: BTreeMap<u32, u32>,
    /// Unmodelled register blocks touched (1 KiB block base addresses).
    pub unmodelled: BTreeSet<u32>,
    /// Edges waiting to be dispatched to the models.
    edges: Vec<Edge>,
    /// Every edge, when tracing.
    pub trace: Option<Vec<Edge>>,
    /// A reset asked for (watchdog, software).
    pub reset_request: Option<ResetKind>,
    /// Resets so far, with their time.
    pub resets: Vec<(Cyc, ResetKind)>,
    /// Stall injection.
    pub stall: Option<Stall>,
    /// Thread mode held until this time.
    pub thread_hold_until: Option<Cyc>,
    /// Notes (faults seen, odd accesses).
    pub notes: Vec<String>,
    /// Hot end and bed powered when each flash erase started (the core stalls for the whole
    /// erase, so nothing the image does changes them before it ends).
    pub heaters_at_erase: Vec<[bool; 2]>,
    /// Timing of the last edge per pin (for EN/PC13 reports).
    pub last_level: BTreeMap<Pin, (Cyc, bool)>,
    /// When SAFE_POWER (PC13) first went high.
    pub safe_power_first_high: Option<Cyc>,
    /// Heaters powered and drivers enabled, each time either changes.
    pub outputs_log: Vec<(Cyc, [bool; 2], [bool; 4])>,
    /// The stack pointer after each active exception's frame was pushed, innermost last.
    pub frame_sp: Vec<u32>,
    /// The current slice ends at this time.
    pub deadline: Cyc,
    /// The last read of a timer counter: (address, instruction count).
    last_cnt_read: (u32, u64),
    /// Instruction count at the last register write.
    last_write_insn: u64,
    /// Cycles skipped in counter-polling loops.
    pub poll_skipped: Cyc,
}

impl Board {
    /// A powered-off board with these models.
    pub fn new(flash: Flash, iwdg: Iwdg, tmc: Drivers, axes: Axes, sdio: Sdio) -> Self {
        let mut tim5 = Timer::new(true);
        tim5.log_ccr1 = true;
        let mut b = Board {
            insns: 0,
            cycles: 0,
            clock: Clock::new(ClockModel::Chip),
            busy_by_exc: vec![0; crate::nvic::N_EXC],
            skipped: 0,
            stop_at: 0,
            stop: None,
            event_reg: false,
            special: Vec::new(),
            nvic: Nvic::default(),
            rcc: Rcc::default(),
            flash,
            gpio: Gpio::default(),
            tim2: Timer::new(true),
            tim4: Timer::new(false),
            tim5,
            usart1: Usart::default(),
            adc: Adc::default(),
            heaters: Heaters::default(),
            iwdg,
            tmc,
            axes,
            sdio,
            otg: Otg::default(),
            usb: UsbHost::new(false),
            regs: BTreeMap::new(),
            unmodelled: BTreeSet::new(),
            edges: Vec::new(),
            trace: None,
            reset_request: None,
            resets: Vec::new(),
            stall: None,
            thread_hold_until: None,
            notes: Vec::new(),
            heaters_at_erase: Vec::new(),
            last_level: BTreeMap::new(),
            frame_sp: Vec::new(),
            outputs_log: Vec::new(),
            safe_power_first_high: None,
            deadline: 0,
            last_cnt_read: (0, 0),
            last_write_insn: 0,
            poll_skipped: 0,
        };
        // The board's own resistors: MOSFET gates (heaters, SAFE_POWER) pulled down; the
        // pause button input pulled up by its own pull-up (the image enables it anyway).
        for p in HEATER_PINS.into_iter().chain([SAFE_POWER]) {
            b.gpio.board_pull[usize::from(p.port)][usize::from(p.n)] = Some(false);
        }
        b.gpio.board_pull[usize::from(PAUSE_BUTTON.port)][usize::from(PAUSE_BUTTON.n)] = Some(true);
        b.wire_inputs();
        b
    }

    /// Virtual time now.
    pub fn now(&self) -> Cyc {
        self.cycles + self.skipped
    }

    /// A system reset of `kind`: every peripheral at its reset value (RAM and flash keep
    /// their contents; the outside world stays).
    pub fn reset(&mut self, kind: ResetKind) {
        let now = self.now();
        self.rcc.reset(kind);
        self.nvic = Nvic::default();
        self.gpio.reset();
        let log = std::mem::take(&mut self.tim5.ccr1_writes);
        self.tim2 = Timer::new(true);
        self.tim4 = Timer::new(false);
        self.tim5 = Timer::new(true);
        self.tim5.log_ccr1 = true;
        self.tim5.ccr1_writes = log;
        self.usart1.reset();
        self.adc.reset();
        self.iwdg.reset();
        self.flash.reset();
        self.sdio.reset();
        self.otg.reset();
        self.regs.clear();
        self.clock.reset();
        self.event_reg = false;
        self.thread_hold_until = None;
        self.frame_sp.clear();
        self.resets.push((now, kind));
        self.pins_changed(now);
    }

    /// The models' drive on the board's input pins.
    fn wire_inputs(&mut self) {
        for (i, p) in ENDSTOP.iter().enumerate() {
            self.gpio.ext[usize::from(p.port)][usize::from(p.n)] = Some(self.axes.endstop_level(i));
        }
        let en = self.tmc.en_levels();
        for (i, p) in EN.iter().enumerate() {
            self.gpio.ext[usize::from(p.port)][usize::from(p.n)] = Some(en[i]);
        }
    }

    /// Re-evaluates the pins and dispatches their edges.
    pub fn pins_changed(&mut self, now: Cyc) {
        self.gpio.sample(now, &mut self.edges);
        self.dispatch_edges();
    }

    fn dispatch_edges(&mut self) {
        let mut any = false;
        while !self.edges.is_empty() {
            let edges = std::mem::take(&mut self.edges);
            for e in edges {
                let t = e.t;
                self.on_edge(e);
                any = true;
                let state = (self.heaters_powered(), self.drivers_enabled());
                if self.outputs_log.last().map(|(_, h, d)| (*h, *d)) != Some(state) {
                    self.outputs_log.push((t, state.0, state.1));
                }
            }
        }
        let _ = any;
    }

    fn powered(&self) -> bool {
        self.gpio.level(SAFE_POWER)
    }

    fn on_edge(&mut self, e: Edge) {
        if let Some(t) = &mut self.trace {
            t.push(e);
        }
        self.last_level.insert(e.pin, (e.t, e.high));
        if let Some(i) = STEP.iter().position(|&p| p == e.pin) {
            let moving = !self.gpio.level(EN[i]) && self.powered();
            let before: Vec<bool> = (0..3).map(|k| self.axes.pressed(k)).collect();
            self.axes.step_edge(i, e.t, e.high, moving);
            if (0..3).any(|k| self.axes.pressed(k) != before[k]) {
                self.wire_inputs();
                self.gpio.sample(e.t, &mut self.edges);
            }
        } else if let Some(i) = DIR.iter().position(|&p| p == e.pin) {
            self.axes.dir_edge(i, e.t, e.high);
        } else if let Some(i) = UART_PINS.iter().position(|&p| p == e.pin) {
            if self.gpio.is_output(e.pin) {
                self.tmc.mcu_edge(i, e.t, e.high);
            }
        }
        if let Some(i) = HEATER_PINS.iter().position(|&p| p == e.pin) {
            let on = e.high && self.powered();
            self.heaters.set_powered(i, on, e.t);
        }
        if e.pin == SAFE_POWER {
            if e.high && self.safe_power_first_high.is_none() {
                self.safe_power_first_high = Some(e.t);
            }
            for (i, p) in HEATER_PINS.iter().enumerate() {
                let on = e.high && self.gpio.level(*p);
                self.heaters.set_powered(i, on, e.t);
            }
            if !e.high {
                // The modules lose their supply: registers back to power-on values.
                self.tmc.power_cycle();
            }
        }
    }

    /// Brings every model up to `now`: events due are processed, interrupt lines sampled
    /// into the NVIC.
    pub fn advance(&mut self, now: Cyc) {
        self.tim2.advance(now);
        self.tim4.advance(now);
        self.tim5.advance(now);
        self.usart1.advance(now);
        self.adc.advance(now, &mut self.heaters);
        self.heaters.advance(now);
        self.flash.advance(now);
        let before = self.gpio.clone();
        self.tmc.advance(now, &mut self.gpio);
        let _ = before;
        self.gpio.sample(now, &mut self.edges);
        self.dispatch_edges();
        self.sdio.advance(now);
        self.usb.advance(now, &mut self.otg);
        if self.nvic.systick.advance(now) && self.nvic.systick.ctrl & 2 != 0 {
            self.nvic.pend(exc::SYSTICK);
        }
        if let Some(t) = self.iwdg.expires_at() {
            if t <= now && self.reset_request.is_none() {
                self.reset_request = Some(ResetKind::Watchdog);
            }
        }
        self.sync_irqs();
    }

    /// Interrupt lines into the NVIC's pending bits (level-sensitive: a line still high
    /// while its handler is active pends again only when the handler returns).
    pub fn sync_irqs(&mut self) {
        let lines = [
            (irq::TIM2, self.tim2.irq()),
            (irq::TIM5, self.tim5.irq()),
            (irq::USART1, self.usart1.irq()),
            (irq::FLASH, self.flash.irq()),
            (irq::SDIO, self.sdio.irq()),
            (irq::DMA2_STREAM3, self.sdio.dma_irq()),
            (irq::OTG_FS, self.otg.irq()),
        ];
        for (n, level) in lines {
            let e = usize::from(exc::IRQ0 + n);
            if level && !self.nvic.active[e] {
                self.nvic.pending[e] = true;
            }
        }
    }

    /// The next time something happens without the CPU.
    pub fn next_event(&self, now: Cyc) -> Option<Cyc> {
        [
            self.tim2.next_event(now),
            self.tim5.next_event(now),
            self.usart1.next_event(now),
            self.adc.next_event(),
            self.flash.busy_until,
            self.tmc.next_event(),
            self.sdio.next_event(),
            self.nvic
                .systick
                .next_wrap(now)
                .filter(|_| self.nvic.systick.ctrl & 2 != 0),
            self.iwdg.expires_at(),
            self.usb.next_event(),
        ]
        .into_iter()
        .flatten()
        .map(|t| t.max(now))
        .min()
    }

    /// A read of `size` bytes at `addr` in a peripheral region.
    pub fn mmio_read(&mut self, addr: u32, size: usize, in_thread: bool) -> u64 {
        let now = self.now();
        let word = addr & !3;
        let v = self.read_word(word, now, in_thread);
        let shift = (addr & 3) * 8;
        let v = u64::from(v >> shift);
        match size {
            1 => v & 0xFF,
            2 => v & 0xFFFF,
            _ => v,
        }
    }

    fn read_word(&mut self, a: u32, now: Cyc, in_thread: bool) -> u32 {
        let now = if a == 0x4000_0024 || a == 0x4000_0C24 {
            self.poll_fast_forward(a, now)
        } else {
            now
        };
        match a {
            0x4000_0000..=0x4000_03FF => self.tim2.read(a - 0x4000_0000, now),
            0x4000_0800..=0x4000_0BFF => self.tim4.read(a - 0x4000_0800, now),
            0x4000_0C00..=0x4000_0FFF => {
                if a == 0x4000_0C24 && in_thread {
                    self.maybe_start_stall(now);
                }
                self.tim5.read(a - 0x4000_0C00, now)
            }
            0x4000_3000..=0x4000_33FF => self.iwdg.read(a - 0x4000_3000, now),
            0x4000_7000..=0x4000_73FF => self.rcc.pwr_read(a - 0x4000_7000),
            0x4001_1000..=0x4001_13FF => self.usart1.read(a - 0x4001_1000, now),
            0x4001_2000..=0x4001_23FF => self.adc.read(a - 0x4001_2000, now, &mut self.heaters),
            0x4001_2C00..=0x4001_2FFF => self.sdio.read(a - 0x4001_2C00, now),
            0x4002_6400..=0x4002_67FF => self.sdio.dma_read(a - 0x4002_6400),
            0x4002_0000..=0x4002_13FF => {
                self.advance_pins(now);
                let port = ((a - 0x4002_0000) / 0x400) as usize;
                self.gpio.read(port, a & 0x3FF)
            }
            0x4002_3800..=0x4002_3BFF => self.rcc.read(a - 0x4002_3800),
            0x4002_3C00..=0x4002_3FFF => self.flash.read(a - 0x4002_3C00, now),
            0x5000_0000..=0x5003_FFFF => self.otg.read(a - 0x5000_0000),
            0xE000_E000..=0xE000_EFFF => self.nvic.read(a - 0xE000_E000, now),
            _ => {
                self.unmodelled.insert(a & !0x3FF);
                self.regs.get(&a).copied().unwrap_or(0)
            }
        }
    }

    /// A counter read again within a few instructions, with no register written in
    /// between, is a polling loop (`while cnt - start < ticks {}`): time moves on to the
    /// counter's next value (never past the slice's end, so no event is skipped). Each value
    /// is still read, in order; only the loop's repeated reads of one value are not executed.
    fn poll_fast_forward(&mut self, a: u32, now: Cyc) -> Cyc {
        let (last_a, last_i) = self.last_cnt_read;
        self.last_cnt_read = (a, self.insns);
        if last_a != a || self.insns - last_i > 8 || self.last_write_insn > last_i {
            return now;
        }
        let tim = if a == 0x4000_0024 {
            &self.tim2
        } else {
            &self.tim5
        };
        let Some(t) = tim.next_tick(now) else {
            return now;
        };
        let t = t.min(self.deadline);
        if t <= now {
            return now;
        }
        self.skipped += t - now;
        self.poll_skipped += t - now;
        self.stop_at = self.stop_at.min(self.cycles + (self.deadline - t));
        t
    }

    /// Models whose outside drive depends on time (TMC replies) brought up to `now` before
    /// a pin is read.
    fn advance_pins(&mut self, now: Cyc) {
        self.tmc.advance(now, &mut self.gpio);
        self.gpio.sample(now, &mut self.edges);
        self.dispatch_edges();
    }

    fn maybe_start_stall(&mut self, now: Cyc) {
        if let Some(s) = self.stall {
            if now >= s.after {
                self.stall = None;
                self.thread_hold_until = Some(now + s.duration);
                self.notes.push(format!(
                    "stall injected: thread mode held {:.1} ms from t = {:.4} s",
                    crate::time::s_from_cyc(s.duration) * 1e3,
                    crate::time::s_from_cyc(now)
                ));
                self.stop_at = self.cycles;
            }
        }
    }

    /// A write of `size` bytes of `v` at `addr`.
    pub fn mmio_write(&mut self, addr: u32, size: usize, v: u64) {
        let now = self.now();
        self.last_write_insn = self.insns;
        let word = addr & !3;
        let v32 = v as u32;
        let value = if size == 4 {
            v32
        } else {
            let shift = (addr & 3) * 8;
            let mask: u32 = if size == 1 { 0xFF } else { 0xFFFF };
            // Sub-word writes to set/clear registers touch only their bits; a register whose
            // read has a side effect is not read to merge the other bytes (a byte write of
            // USART1 DR read DR first, which cleared RXNE and lost a received byte when one
            // arrived between the handler's SR read and its write: found when the cycle
            // model moved the byte's arrival there).
            let base = match word {
                0x4002_0018 | 0x4002_0418 | 0x4002_0818 | 0x4002_0C18 | 0x4002_1018 => 0,
                0xE000_E100..=0xE000_E2FF => 0,
                // A store reads nothing with side effects (USART1 DR: RXNE cleared, the
                // received byte taken; docs/board-emu.md, 'What the emulated board found' 4).
                w if read_has_side_effects(w) => 0,
                _ => self.read_word(word, now, false),
            };
            (base & !(mask << shift)) | ((v32 & mask) << shift)
        };
        self.write_word(word, value, now);
        self.sync_irqs();
        // Stop before the next instruction: the write may pend an interrupt or move an event.
        self.stop_at = self.cycles;
        if self.stop.is_none() {
            self.stop = Some(Stop::Resched);
        }
    }

    fn write_word(&mut self, a: u32, v: u32, now: Cyc) {
        match a {
            0x4000_0000..=0x4000_03FF => self.tim2.write(a - 0x4000_0000, v, now),
            0x4000_0800..=0x4000_0BFF => self.tim4.write(a - 0x4000_0800, v, now),
            0x4000_0C00..=0x4000_0FFF => self.tim5.write(a - 0x4000_0C00, v, now),
            0x4000_3000..=0x4000_33FF => self.iwdg.write(a - 0x4000_3000, v, now),
            0x4000_7000..=0x4000_73FF => self.rcc.pwr_write(a - 0x4000_7000, v),
            0x4001_1000..=0x4001_13FF => self.usart1.write(a - 0x4001_1000, v, now),
            0x4001_2000..=0x4001_23FF => self.adc.write(a - 0x4001_2000, v, now, &mut self.heaters),
            0x4001_2C00..=0x4001_2FFF => self.sdio.write(a - 0x4001_2C00, v, now),
            0x4002_6400..=0x4002_67FF => self.sdio.dma_write(a - 0x4002_6400, v, now),
            0x4002_0000..=0x4002_13FF => {
                self.advance_pins(now);
                let port = ((a - 0x4002_0000) / 0x400) as usize;
                self.gpio.write(port, a & 0x3FF, v, now, &mut self.edges);
                self.dispatch_edges();
            }
            0x4002_3800..=0x4002_3BFF => self.rcc.write(a - 0x4002_3800, v),
            0x4002_3C00..=0x4002_3FFF => {
                if let Some(FlashOp::Erased { n, .. }) = self.flash.write(a - 0x4002_3C00, v, now) {
                    self.heaters_at_erase.push(self.heaters_powered());
                    self.notes.push(format!(
                        "flash sector {n} erase at t = {:.4} s",
                        crate::time::s_from_cyc(now)
                    ));
                }
            }
            0x5000_0000..=0x5003_FFFF => {
                self.otg.write(a - 0x5000_0000, v);
                if std::mem::take(&mut self.otg.kicked) {
                    self.usb.kick(now);
                }
            }
            0xE000_E000..=0xE000_EFFF => self.nvic.write(a - 0xE000_E000, v, now),
            _ => {
                self.unmodelled.insert(a & !0x3FF);
                self.regs.insert(a, v);
            }
        }
        if self.nvic.reset_requested {
            self.nvic.reset_requested = false;
            self.reset_request = Some(ResetKind::Software);
        }
    }

    /// A read of the settings sectors.
    pub fn store_read(&mut self, off: u64, size: usize) -> u64 {
        let addr = STORE_BASE + off as u32;
        if self.flash.stalled(self.now()) {
            self.notes
                .push("read of the settings area while flash busy".into());
        }
        self.flash.read_store(addr, size)
    }

    /// A write to the settings sectors: programming.
    pub fn store_write(&mut self, off: u64, size: usize, v: u64) {
        let now = self.now();
        let addr = STORE_BASE + off as u32;
        if !self.flash.program(addr, size, v, now) {
            self.notes.push(format!(
                "refused flash write of {size} bytes at {addr:#010x} (t = {:.4} s)",
                crate::time::s_from_cyc(now)
            ));
        }
        self.stop_at = self.cycles;
        if self.stop.is_none() {
            self.stop = Some(Stop::Resched);
        }
        let _ = STORE_LEN;
    }

    /// When `pin` first went high (SAFE_POWER only is tracked).
    pub fn trace_first_high(&self, pin: Pin) -> Option<Cyc> {
        (pin == SAFE_POWER)
            .then_some(self.safe_power_first_high)
            .flatten()
    }

    /// Heater pins' power state, for reports.
    pub fn heaters_powered(&self) -> [bool; 2] {
        [self.heaters.powered(HOTEND), self.heaters.powered(BED)]
    }

    /// Drivers enabled (EN low while outputs) and powered.
    pub fn drivers_enabled(&self) -> [bool; 4] {
        let p = self.powered();
        EN.map(|pin| p && self.gpio.is_output(pin) && !self.gpio.level(pin))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::axes::Axes;
    use crate::flash::{Flash, FlashTiming};
    use crate::iwdg::Iwdg;
    use crate::sdio::Sdio;
    use crate::tmc::{Drivers, Seating};

    /// A byte store to USART1's DR (embassy's transmit path) while a received byte waits in
    /// it: the byte stays for the interrupt to read (a store reads nothing). Issue 29: the
    /// merge read DR, so a byte arriving between the interrupt's SR read and its transmit store
    /// vanished, and a line's last bytes with it.
    #[test]
    fn a_byte_store_to_the_usart_data_register_keeps_the_received_byte() {
        let mut b = Board::new(
            Flash::new(FlashTiming::Typ),
            Iwdg::new(32_000),
            Drivers::new([Seating::Correct; 4]),
            Axes::new(&firmware::config::MachineConfig::ENDER3, [60.0, 60.0, 10.0]),
            Sdio::with_card(None),
        );
        let now = b.now();
        b.usart1.write(0x08, 0x5B, now); // BRR: 115 200 Bd at 84 MHz
        b.usart1.write(0x0C, 1 << 13 | 1 << 3 | 1 << 2, now); // UE, TE, RE
        b.usart1.host_tx.push_back(b'8');
        b.usart1.advance(now);
        b.usart1.advance(now + 1_000_000);
        assert_eq!(b.usart1.peek(0x00) & (1 << 5), 1 << 5, "RXNE: a byte waits");
        b.mmio_write(0x4001_1004, 1, u64::from(b'o'));
        assert_eq!(
            b.usart1.peek(0x00) & (1 << 5),
            1 << 5,
            "RXNE after the store"
        );
        assert_eq!(b.usart1.read(0x04, now + 1_000_000), u32::from(b'8'));
    }
}
