//! The last line of defence: heaters off, stepper drivers disabled and their power switched
//! off, by raw register writes that work from any context (panic, HardFault) without the HAL's
//! drivers, and a last line on the TFT UART. Best effort: USB cannot be served once the
//! executor has stopped, so a host on USB sees the link go silent (docs/board.md).

use embassy_stm32::pac;

/// Heater MOSFET gates low (HE0 PB3, BED PD7), stepper drivers disabled (EN high: X PE3, Y PD6,
/// Z PD1, E0 PC7) and SAFE_POWER (PC13) low, which cuts the supply of the drivers and of most
/// MOSFETs (Klipper's SKR 2 config). Idempotent; touches only the BSRR registers, which set or
/// clear single pins atomically. The fans keep their PWM where they still have power.
pub fn all_off() {
    pac::GPIOB.bsrr().write(|w| w.set_br(3, true));
    pac::GPIOD.bsrr().write(|w| w.set_br(7, true));
    pac::GPIOE.bsrr().write(|w| w.set_bs(3, true));
    pac::GPIOD.bsrr().write(|w| {
        w.set_bs(6, true);
        w.set_bs(1, true);
    });
    pac::GPIOC.bsrr().write(|w| {
        w.set_bs(7, true);
        w.set_br(13, true);
    });
}

/// Writes `text` on USART1 (the TFT header) by polling its registers, each byte given up after
/// a bounded wait (the UART may not be running).
pub fn uart_say(text: &[u8]) {
    let u = pac::USART1;
    for &b in text {
        let mut spins = 0u32;
        while !u.sr().read().txe() {
            spins += 1;
            if spins > 100_000 {
                return;
            }
        }
        u.dr().write(|w| w.set_dr(u16::from(b)));
    }
}
