//! Heaters and fans on the SKR 2: thermistor sampling on ADC1 every 100 ms, the samples fed to
//! the executive's thermal control (`firmware::thermal` through `Printer`), and the duties it
//! answers applied by software PWM on the heater MOSFETs (HE0 on PB3 and BED on PD7 have no free
//! timer channel: PB3 is TIM2_CH2, and TIM2 is embassy-time's driver). 100 slots of 1 ms make a
//! 10 Hz PWM, like Marlin's soft PWM for heaters. The hot-end fan follows the automatic
//! threshold (50 °C) of the thermal control; the part fan follows M106/M107.

use embassy_stm32::gpio::{Output, OutputType};
use embassy_stm32::time::Hertz;
use embassy_stm32::timer::low_level::CountingMode;
use embassy_stm32::timer::simple_pwm::{PwmPin, SimplePwm};
use embassy_stm32::{peripherals, Peri};
use firmware::thermal::ThermalConfig;

/// Soft-PWM slots per period (1 ms each).
pub const PWM_SLOTS: u32 = 100;

/// One soft-PWM output.
pub struct SoftPwm {
    pin: Output<'static>,
    on_slots: u32,
}

impl SoftPwm {
    /// Wraps a pin (off).
    pub fn new(mut pin: Output<'static>) -> Self {
        pin.set_low();
        SoftPwm { pin, on_slots: 0 }
    }

    /// Sets the duty 0..=1 for the next periods (NaN = off).
    pub fn set_duty(&mut self, duty: f32) {
        let d = if duty.is_finite() {
            duty.clamp(0.0, 1.0)
        } else {
            0.0
        };
        self.on_slots = libm::roundf(d * PWM_SLOTS as f32) as u32;
    }

    /// Called every slot (1 ms) with the slot number 0..PWM_SLOTS.
    pub fn tick(&mut self, slot: u32) {
        if slot < self.on_slots {
            self.pin.set_high();
        } else {
            self.pin.set_low();
        }
    }

    /// Off now and for the following periods.
    pub fn off(&mut self) {
        self.on_slots = 0;
        self.pin.set_low();
    }
}

/// Both fans on TIM4 hardware PWM at 1 kHz: FAN1 (hot-end fan, on/off from the thermal
/// control's automatic threshold) and FAN0 (part fan, M106/M107 duty).
pub struct Fans {
    pwm: SimplePwm<'static, peripherals::TIM4>,
}

impl Fans {
    /// Starts TIM4 with both fans off.
    pub fn new(
        tim: Peri<'static, peripherals::TIM4>,
        hotend: Peri<'static, peripherals::PB6>,
        part: Peri<'static, peripherals::PB7>,
    ) -> Self {
        let mut pwm = SimplePwm::new(
            tim,
            Some(PwmPin::new(hotend, OutputType::PushPull)),
            Some(PwmPin::new(part, OutputType::PushPull)),
            None,
            None,
            Hertz(1_000),
            CountingMode::EdgeAlignedUp,
        );
        pwm.ch1().set_duty_cycle_fully_off();
        pwm.ch2().set_duty_cycle_fully_off();
        pwm.ch1().enable();
        pwm.ch2().enable();
        Fans { pwm }
    }

    /// Hot-end fan on or off.
    pub fn set_hotend(&mut self, on: bool) {
        if on {
            self.pwm.ch1().set_duty_cycle_fully_on();
        } else {
            self.pwm.ch1().set_duty_cycle_fully_off();
        }
    }

    /// Part fan duty in Marlin's 0..=255 (M106 S).
    pub fn set_part(&mut self, pwm_255: u8) {
        self.pwm
            .ch2()
            .set_duty_cycle_fraction(u32::from(pwm_255), 255);
    }
}

/// The tables of both heaters, built once.
pub fn tables() -> [firmware::thermal::ThermistorTable; 2] {
    let cfg = ThermalConfig::ENDER3;
    [
        firmware::thermal::ThermistorTable::new(&cfg.hotend.thermistor),
        firmware::thermal::ThermistorTable::new(&cfg.bed.thermistor),
    ]
}
