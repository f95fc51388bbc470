//! The independent watchdog (IWDG) with its prescaler and reload chosen from the fastest LSI
//! (`firmware::drivers::watchdog`), programmed through its registers (RM0090 §21.4: IWDG_KR
//! 0x5555 unlocks PR/RLR, 0xCCCC starts, 0xAAAA reloads; PR/RLR updates are done when
//! IWDG_SR.PVU/RVU clear). embassy-stm32's `IndependentWatchdog` computes for a 32 kHz LSI,
//! which on a 47 kHz part cuts the timeout to 68 %.

use embassy_stm32::pac;
use firmware::drivers::watchdog::{IwdgTiming, LSI_MAX_HZ, LSI_MIN_HZ};

/// The shortest timeout the image needs, µs: the longest stretch without feeding is one flash
/// sector erase (128 KiB: 2 s at most, DS8626 "Flash memory programming", x32), fed right
/// before it (`board::flash`); 0.5 s of margin. Everything else feeds every 50 ms.
pub const MIN_TIMEOUT_US: u32 = 2_500_000;

/// The setting: 2.5 s at the fastest LSI (47 kHz), 3.67 s at 32 kHz, 6.91 s at the slowest
/// (17 kHz); `drivers::watchdog` tests these figures.
pub const TIMING: Option<IwdgTiming> = IwdgTiming::for_min_timeout(MIN_TIMEOUT_US, LSI_MAX_HZ);

/// The longest timeout the setting can give (slowest LSI), µs.
pub fn max_timeout_us() -> u64 {
    TIMING.map_or(0, |t| t.timeout_us(LSI_MIN_HZ))
}

/// Starts the watchdog (it cannot be stopped again until reset) with [`TIMING`].
pub fn start(_iwdg: embassy_stm32::Peri<'static, embassy_stm32::peripherals::IWDG>) {
    let Some(t) = TIMING else {
        defmt::error!("watchdog timing out of range: not started");
        return;
    };
    let w = pac::IWDG;
    // 0x5555: PR and RLR writable.
    w.kr().write(|k| k.set_key(pac::iwdg::vals::Key::ENABLE));
    w.pr()
        .write(|p| p.set_pr(pac::iwdg::vals::Pr::from_bits(t.pr)));
    w.rlr().write(|r| r.set_rl(t.reload));
    // Wait for the values to reach the LSI domain (bounded: a few LSI periods).
    let mut spins = 0u32;
    while (w.sr().read().pvu() || w.sr().read().rvu()) && spins < 1_000_000 {
        spins += 1;
    }
    // 0xCCCC: start counting down (from the reload value).
    w.kr().write(|k| k.set_key(pac::iwdg::vals::Key::START));
    feed();
}

/// Reloads the counter (IWDG_KR = 0xAAAA). Safe from any context.
#[inline]
pub fn feed() {
    pac::IWDG
        .kr()
        .write(|k| k.set_key(pac::iwdg::vals::Key::RESET));
}
