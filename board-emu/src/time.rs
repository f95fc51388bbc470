//! Virtual time on the emulated board.
//!
//! The unit is one CPU cycle at 168 MHz (the image's clock tree: 8 MHz HSE → PLL → 168 MHz
//! SYSCLK, APB1 42 MHz with its timers at 84 MHz, APB2 84 MHz; docs/board.md). Assumptions,
//! stated once: **one instruction takes one cycle** (flash wait states, the ART accelerator,
//! pipeline refills and multi-cycle instructions are not modelled), and the CPU is taken to run
//! at 168 MHz from reset (on the chip the first few microseconds, before `embassy_stm32::init`
//! switches SYSCLK to the PLL, run at the 16 MHz HSI). Time also advances without instructions
//! while the CPU sleeps (WFI/WFE, fast-forwarded to the next event) and while it is stalled
//! (a flash erase or program, RM0090 §3.5.4: "any attempt to read the Flash memory while it is
//! being written or erased causes the bus to stall").

/// Virtual time in CPU cycles.
pub type Cyc = u64;

/// SYSCLK (= HCLK = the Cortex-M4 core clock), Hz.
pub const CPU_HZ: u64 = 168_000_000;
/// APB2 (USART1, ADC1, SDIO's APB interface) clock, Hz: HCLK / 2.
pub const PCLK2_HZ: u64 = 84_000_000;
/// APB1 timer clock (TIM2..TIM5), Hz: APB1 runs at HCLK / 4, and RM0090 §6.2 ("if the APB
/// prescaler is not 1, the timer clocks are twice the APB frequency") doubles it.
pub const TIM_APB1_HZ: u64 = 84_000_000;
/// SDIOCLK (the SDIO adapter's kernel clock: PLL48CK, RM0090 §31.3), Hz.
pub const SDIOCLK_HZ: u64 = 48_000_000;

/// Cycles in `ns` nanoseconds (rounded down).
pub const fn cyc_from_ns(ns: u64) -> Cyc {
    ns * CPU_HZ / 1_000_000_000
}

/// Cycles in `us` microseconds.
pub const fn cyc_from_us(us: u64) -> Cyc {
    us * (CPU_HZ / 1_000_000)
}

/// Cycles in `ms` milliseconds.
pub const fn cyc_from_ms(ms: u64) -> Cyc {
    ms * (CPU_HZ / 1_000)
}

/// Nanoseconds in `c` cycles (rounded down).
pub const fn ns_from_cyc(c: Cyc) -> u64 {
    (c as u128 * 1_000_000_000 / CPU_HZ as u128) as u64
}

/// Seconds in `c` cycles.
pub fn s_from_cyc(c: Cyc) -> f64 {
    c as f64 / CPU_HZ as f64
}

/// Cycles of one period of a clock of `hz` (rounded to the nearest cycle, at least 1).
pub fn cyc_per(hz: f64) -> f64 {
    (CPU_HZ as f64 / hz).max(1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn conversions() {
        assert_eq!(cyc_from_us(1), 168);
        assert_eq!(cyc_from_ms(2), 336_000);
        assert_eq!(ns_from_cyc(168), 1000);
        assert_eq!(cyc_from_ns(1000), 168);
    }
}
