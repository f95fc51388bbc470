//! Heaters and fans on the SKR 2: thermistor sampling on ADC1 every 100 ms, the samples fed to
//! the executive's thermal control (`firmware::thermal` through `Printer`), and the duties it
//! answers applied by software PWM on the heater MOSFETs (HE0 on PB3 and BED on PD7 have no free
//! timer channel: PB3 is TIM2_CH2, and TIM2 is embassy-time's driver). 100 slots of 1 ms make a
//! 10 Hz PWM, like Marlin's soft PWM for heaters. The hot-end fan follows the automatic
//! threshold (50 °C) of the thermal configuration.

use embassy_stm32::gpio::Output;
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

/// Hot-end fan threshold with hysteresis, from the thermal configuration.
pub struct HotendFan {
    pin: Output<'static>,
    on_c: f32,
    on: bool,
}

impl HotendFan {
    /// Wraps the FAN1 pin.
    pub fn new(pin: Output<'static>) -> Self {
        HotendFan {
            pin,
            on_c: ThermalConfig::ENDER3.hotend_fan_c,
            on: false,
        }
    }

    /// Updates from the hot-end temperature.
    pub fn update(&mut self, hotend_c: f32) {
        if hotend_c >= self.on_c || !hotend_c.is_finite() {
            self.on = true;
        } else if hotend_c < self.on_c - 2.0 {
            self.on = false;
        }
        if self.on {
            self.pin.set_high();
        } else {
            self.pin.set_low();
        }
    }
}

/// Converts a raw reading with the configured thermistor of `id` (NaN for an open or shorted
/// sensor, which the thermal control treats as a sensor fault while heating).
pub fn adc_to_c(table: &firmware::thermal::ThermistorTable, raw: u16) -> f32 {
    table.celsius(raw).unwrap_or(f32::NAN)
}

/// The tables of both heaters, built once.
pub fn tables() -> [firmware::thermal::ThermistorTable; 2] {
    let cfg = ThermalConfig::ENDER3;
    [
        firmware::thermal::ThermistorTable::new(&cfg.hotend.thermistor),
        firmware::thermal::ThermistorTable::new(&cfg.bed.thermistor),
    ]
}
