//! The independent watchdog's (IWDG) prescaler and reload, chosen from the **fastest** LSI the
//! chip may have, so the timeout is never shorter than asked for.
//!
//! The IWDG counts the LSI oscillator, divided by a prescaler of 4…256 (PR = 0…6), down from a
//! 12-bit reload value; it resets the chip when the count reaches zero, so the timeout is
//! `(RL + 1) × prescaler / f_LSI` (RM0090 §21.3, table 107 "Min/max IWDG timeout period at
//! 32 kHz (LSI)": 0.125 ms–512 ms at /4 … 32 ms–32 768 ms at /256). The LSI is an RC
//! oscillator: the STM32F405/407 datasheet (DS8626, "LSI oscillator characteristics") gives
//! f_LSI 17 kHz min, 32 kHz typical, 47 kHz max, and the F429's (DS9405) the same. A setting
//! computed for 32 kHz (what embassy-stm32's `IndependentWatchdog::new` assumes) times out
//! after `32/47` of the intended time on a fast part: 2 s becomes 1.36 s.
//!
//! [`IwdgTiming::for_min_timeout`] takes the shortest timeout the firmware needs (the longest
//! stretch it may go without feeding, plus a margin) and the fastest LSI, and gives the
//! smallest prescaler that reaches it; [`IwdgTiming::timeout_us`] gives the timeout at any LSI
//! frequency, so the documentation can state both ends.

/// LSI frequency range, Hz (DS8626 / DS9405 "LSI oscillator characteristics").
pub const LSI_MIN_HZ: u32 = 17_000;
/// Typical LSI frequency, Hz.
pub const LSI_TYP_HZ: u32 = 32_000;
/// Fastest LSI, Hz: the one that gives the shortest timeout.
pub const LSI_MAX_HZ: u32 = 47_000;

/// Largest reload value (12 bits).
pub const RELOAD_MAX: u16 = 0x0FFF;

/// An IWDG setting: the PR register value (prescaler 4 << pr) and the RLR reload value.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct IwdgTiming {
    /// IWDG_PR.PR: 0 = /4, 1 = /8, … 6 = /256.
    pub pr: u8,
    /// IWDG_RLR.RL (0…0xFFF).
    pub reload: u16,
}

impl IwdgTiming {
    /// The prescaler this setting divides the LSI by.
    pub const fn prescaler(self) -> u32 {
        4 << self.pr
    }

    /// The timeout at an LSI of `lsi_hz`, µs (rounded down).
    pub const fn timeout_us(self, lsi_hz: u32) -> u64 {
        (self.reload as u64 + 1) * self.prescaler() as u64 * 1_000_000 / lsi_hz as u64
    }

    /// The setting with the smallest prescaler whose timeout at `lsi_max_hz` is at least
    /// `min_timeout_us`; None if even /256 with the largest reload is too short (over 22 s at
    /// 47 kHz) or an argument is zero.
    pub const fn for_min_timeout(min_timeout_us: u32, lsi_max_hz: u32) -> Option<Self> {
        if min_timeout_us == 0 || lsi_max_hz == 0 {
            return None;
        }
        // LSI periods needed, rounded up.
        let periods = (min_timeout_us as u64 * lsi_max_hz as u64).div_ceil(1_000_000);
        let mut pr = 0u8;
        while pr <= 6 {
            let presc = 4u64 << pr;
            let counts = periods.div_ceil(presc);
            if counts >= 1 && counts <= RELOAD_MAX as u64 + 1 {
                return Some(IwdgTiming {
                    pr,
                    reload: (counts - 1) as u16,
                });
            }
            pr += 1;
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_reference_manual_table_at_32_khz() {
        // RM0090 table 107: /4 with RL 0 → 0.125 ms, RL 0xFFF → 512 ms; /256, 0xFFF → 32.768 s.
        let t = |pr, reload| IwdgTiming { pr, reload }.timeout_us(LSI_TYP_HZ);
        assert_eq!(t(0, 0), 125);
        assert_eq!(t(0, 0xFFF), 512_000);
        assert_eq!(t(6, 0), 8_000);
        assert_eq!(t(6, 0xFFF), 32_768_000);
    }

    #[test]
    fn never_shorter_than_asked_at_the_fastest_lsi() {
        for min_us in [
            1_000u32, 125_000, 1_000_000, 1_360_000, 2_000_000, 2_500_000, 20_000_000,
        ] {
            let s = IwdgTiming::for_min_timeout(min_us, LSI_MAX_HZ).unwrap();
            let at_max = s.timeout_us(LSI_MAX_HZ);
            assert!(at_max >= u64::from(min_us), "{min_us}: {at_max}");
            // Tight: one count less would be too short (within one prescaled LSI period).
            let period_us = u64::from(s.prescaler()) * 1_000_000 / u64::from(LSI_MAX_HZ);
            assert!(
                at_max < u64::from(min_us) + period_us + 1,
                "{min_us}: {s:?}"
            );
            // Slower LSIs only lengthen it.
            assert!(s.timeout_us(LSI_TYP_HZ) > at_max);
            assert!(s.timeout_us(LSI_MIN_HZ) > s.timeout_us(LSI_TYP_HZ));
        }
    }

    #[test]
    fn the_board_setting() {
        // 2.5 s at 47 kHz (the longest flash sector erase, 2 s, plus a margin: docs/board.md).
        let s = IwdgTiming::for_min_timeout(2_500_000, LSI_MAX_HZ).unwrap();
        assert_eq!(
            s,
            IwdgTiming {
                pr: 3,
                reload: 3671
            }
        );
        assert_eq!(s.timeout_us(LSI_MAX_HZ), 2_500_085);
        assert_eq!(s.timeout_us(LSI_TYP_HZ), 3_672_000);
        assert_eq!(s.timeout_us(LSI_MIN_HZ), 6_912_000);
        // What a 32 kHz computation of "2 s" gives on a fast part: the 1.36 s.
        let naive = IwdgTiming::for_min_timeout(2_000_000, LSI_TYP_HZ).unwrap();
        assert_eq!(naive.timeout_us(LSI_MAX_HZ), 1_361_702);
    }

    #[test]
    fn out_of_range_is_none() {
        assert_eq!(IwdgTiming::for_min_timeout(0, LSI_MAX_HZ), None);
        assert_eq!(IwdgTiming::for_min_timeout(1_000_000, 0), None);
        assert_eq!(IwdgTiming::for_min_timeout(30_000_000, LSI_MAX_HZ), None);
    }
}
