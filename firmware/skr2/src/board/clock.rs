//! The board's time base: TIM5, a 32-bit timer counting at 4 MHz (250 ns), extended to 64 bits
//! in software. Step events are scheduled on it (compare channel 1, see `stepper`), and the
//! executive's time (`Printer` µs) is derived from it, so both agree to the tick.
//!
//! The 32-bit counter wraps every 1073 s; [`now_ticks`] notices a wrap as long as it is called
//! at least once per wrap period (the motion loop calls it every millisecond).

use core::cell::Cell;
use critical_section::{CriticalSection, Mutex};
use embassy_stm32::pac;
use embassy_stm32::time::Hertz;
use embassy_stm32::timer::low_level::Timer;

/// Timer ticks per second.
pub const TICK_HZ: u32 = 4_000_000;
/// Nanoseconds per tick.
pub const NS_PER_TICK: u64 = 1_000_000_000 / TICK_HZ as u64;

struct Ext {
    high: u32,
    last_low: u32,
}

static EXT: Mutex<Cell<Ext>> = Mutex::new(Cell::new(Ext {
    high: 0,
    last_low: 0,
}));

/// Switches the flash's ART accelerator on (RM0090 §3.4.2: instruction prefetch, 64-line
/// instruction cache, 8-line data cache in FLASH_ACR), both caches reset first as §3.4.2 asks
/// (a reset only while disabled). embassy-stm32 0.6's clock set-up writes FLASH_ACR with the
/// wait states alone (`rcc/f247.rs`: `FLASH.acr().write(|w| w.set_latency(..))`), which
/// leaves all three off: every 128-bit flash read then costs its 5 wait states at 168 MHz.
/// Found on the emulated board's cycle model (docs/board-emu.md, "Clock"): 2.6 cycles an
/// instruction before. embassy's flash driver turns the data cache off and resets it around
/// its erases and writes (`flash/f4.rs`).
pub fn enable_flash_accelerator() {
    pac::FLASH.acr().modify(|w| {
        w.set_icen(false);
        w.set_dcen(false);
    });
    pac::FLASH.acr().modify(|w| {
        w.set_icrst(true);
        w.set_dcrst(true);
    });
    pac::FLASH.acr().modify(|w| {
        w.set_icrst(false);
        w.set_dcrst(false);
    });
    pac::FLASH.acr().modify(|w| {
        w.set_prften(true);
        w.set_icen(true);
        w.set_dcen(true);
    });
}

/// Starts TIM5 free-running at [`TICK_HZ`] over its full 32-bit range.
pub fn start(tim: embassy_stm32::Peri<'static, embassy_stm32::peripherals::TIM5>) {
    let mut t = Timer::new(tim);
    t.stop();
    t.set_tick_freq(Hertz(TICK_HZ));
    t.set_max_compare_value(u32::MAX);
    t.generate_update_event();
    t.start();
    // Keep the timer running: dropping the driver would disable its clock.
    core::mem::forget(t);
}

/// The 32-bit counter value.
#[inline(always)]
pub fn counter() -> u32 {
    pac::TIM5.cnt().read()
}

/// 64-bit tick count, inside an existing critical section.
pub fn now_ticks_cs(cs: CriticalSection) -> u64 {
    let cell = EXT.borrow(cs);
    let mut ext = cell.replace(Ext {
        high: 0,
        last_low: 0,
    });
    let low = counter();
    if low < ext.last_low {
        ext.high = ext.high.wrapping_add(1);
    }
    ext.last_low = low;
    let t = (u64::from(ext.high) << 32) | u64::from(low);
    cell.set(ext);
    t
}

/// 64-bit tick count since start.
pub fn now_ticks() -> u64 {
    critical_section::with(now_ticks_cs)
}

/// Nanoseconds since start.
pub fn now_ns() -> u64 {
    now_ticks() * NS_PER_TICK
}

/// The chip's configuration for `embassy_stm32::init`: 8 MHz crystal → 168 MHz SYSCLK (PLL
/// 8/4×168/2), 48 MHz for USB (/7), AHB 168, APB1 42, APB2 84 MHz (RM0090 §6.3.2 limits: APB1
/// ≤ 42, APB2 ≤ 84 MHz); DMA interrupts at `dma_priority`.
pub fn chip_config(dma_priority: embassy_stm32::interrupt::Priority) -> embassy_stm32::Config {
    let mut config = embassy_stm32::Config::default();
    config.dma_interrupt_priority = dma_priority;
    {
        use embassy_stm32::rcc::*;
        use embassy_stm32::time::Hertz;
        // 8 MHz crystal → 168 MHz SYSCLK, 48 MHz for USB.
        config.rcc.hse = Some(Hse {
            freq: Hertz(super::pins::HSE_HZ),
            mode: HseMode::Oscillator,
        });
        config.rcc.pll_src = PllSource::HSE;
        config.rcc.pll = Some(Pll {
            prediv: PllPreDiv::DIV4,
            mul: PllMul::MUL168,
            divp: Some(PllPDiv::DIV2),
            divq: Some(PllQDiv::DIV7),
            divr: None,
        });
        config.rcc.ahb_pre = AHBPrescaler::DIV1;
        config.rcc.apb1_pre = APBPrescaler::DIV4;
        config.rcc.apb2_pre = APBPrescaler::DIV2;
        config.rcc.sys = Sysclk::PLL1_P;
        config.rcc.mux.clk48sel = mux::Clk48sel::PLL1_Q;
    }
    config
}
