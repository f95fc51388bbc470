//! The last line of defence: every heater off, by raw register writes that work from any
//! context (panic, HardFault) without the HAL's drivers, and whatever state they are in.

use embassy_stm32::pac;

/// Heater MOSFET gates low (HE0 PB3, BED PD7), stepper drivers disabled (EN high), hot-end
/// Idempotent; touches only the BSRR registers, which set or clear
/// single pins atomically. The fans keep their PWM (the hot-end fan runs while the nozzle is
/// hot).
pub fn heaters_off() {
    pac::GPIOB.bsrr().write(|w| w.set_br(3, true));
    pac::GPIOD.bsrr().write(|w| w.set_br(7, true));
    pac::GPIOE.bsrr().write(|w| w.set_bs(3, true));
    pac::GPIOD.bsrr().write(|w| {
        w.set_bs(6, true);
        w.set_bs(1, true);
    });
    pac::GPIOC.bsrr().write(|w| w.set_bs(7, true));
}
