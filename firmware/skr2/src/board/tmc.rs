//! The SKR 2's TMC2209 UART lines: one single-wire line per driver socket (X PE0, Y PD3, Z PD0,
//! E0 PC6; Marlin `pins_BTT_SKR_V2_0_common.h` `*_SERIAL_TX_PIN` = `*_SERIAL_RX_PIN`, Klipper
//! `generic-bigtreetech-skr-2.cfg` `uart_pin`), bit-banged at 19200 Bd like Marlin's software
//! serial (`TMC_BAUD_RATE 19200`) by the portable `firmware::drivers::tmc2209::SoftUart`. This
//! file only supplies the pin (push-pull while sending, pulled-up input while listening) and a
//! busy-wait delay on the TIM5 time base (250 ns ticks; `cortex_m::asm::delay` is not accurate
//! enough with flash wait states for a 52 µs bit).
//!
//! Talking to the drivers blocks the executor (about 120 ms per driver to configure, 25 ms to
//! read for M122): it happens before motion is enabled at start-up, and later only while
//! nothing moves.

use embassy_stm32::gpio::{Flex, Pull, Speed};
use firmware::drivers::tmc2209::{Direction, SoftUart, Tmc2209, BIT_NS_19200};

use super::clock;

/// One driver's line.
pub struct TmcPin(pub Flex<'static>);

impl embedded_hal::digital::ErrorType for TmcPin {
    type Error = core::convert::Infallible;
}

impl embedded_hal::digital::OutputPin for TmcPin {
    fn set_low(&mut self) -> Result<(), Self::Error> {
        self.0.set_low();
        Ok(())
    }
    fn set_high(&mut self) -> Result<(), Self::Error> {
        self.0.set_high();
        Ok(())
    }
}

impl embedded_hal::digital::InputPin for TmcPin {
    fn is_high(&mut self) -> Result<bool, Self::Error> {
        Ok(self.0.is_high())
    }
    fn is_low(&mut self) -> Result<bool, Self::Error> {
        Ok(!self.0.is_high())
    }
}

impl Direction for TmcPin {
    fn set_output(&mut self, output: bool) {
        if output {
            self.0.set_as_output(Speed::Low);
        } else {
            self.0.set_as_input(Pull::Up);
        }
    }
}

/// Busy-wait on TIM5.
pub struct TimDelay;

impl embedded_hal::delay::DelayNs for TimDelay {
    fn delay_ns(&mut self, ns: u32) {
        let ticks = ns.div_ceil(clock::NS_PER_TICK as u32);
        let start = clock::counter();
        while clock::counter().wrapping_sub(start) < ticks {}
    }
}

/// How long to wait for each reply byte, ns (the driver answers after 8 bit times by default;
/// 4 ms is ample and keeps a silent driver's check short).
pub const REPLY_TIMEOUT_NS: u32 = 4_000_000;

/// A driver at address 0 on its own line.
pub type Driver = Tmc2209<SoftUart<TmcPin, TimDelay>>;

/// The driver on `pin`.
pub fn driver(pin: Flex<'static>) -> Driver {
    Tmc2209::new(
        SoftUart::new(TmcPin(pin), TimDelay, BIT_NS_19200, REPLY_TIMEOUT_NS),
        0,
    )
}
