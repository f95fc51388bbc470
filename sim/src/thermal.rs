//! Wiring between the heater models (the plant, `crate::heater`, written by the board
//! engineer) and the firmware's thermal control: every `sample_period_us` the sim reads each
//! model's temperature, hands it to the firmware as a sensor sample, and applies the duty the
//! firmware answers to the model for the next period.

use crate::port::Executive;

/// A heater as a physical plant: duty in, temperature out.
pub trait HeaterPlant {
    /// Advance the plant by `dt_s` seconds with heater duty `duty` (0..=1); returns the
    /// temperature the sensor reads afterwards, °C.
    fn advance(&mut self, duty: f32, dt_s: f32) -> f32;
    /// Temperature the sensor reads now, °C.
    fn temperature_c(&self) -> f32;
}

impl HeaterPlant for crate::heater::HeaterModel {
    fn advance(&mut self, duty: f32, dt_s: f32) -> f32 {
        self.step(duty, dt_s);
        self.sensor_c()
    }

    fn temperature_c(&self) -> f32 {
        self.sensor_c()
    }
}

/// Hotend and bed plants plus the duties last asked for.
pub struct Heaters {
    hotend: Box<dyn HeaterPlant + Send>,
    bed: Box<dyn HeaterPlant + Send>,
    duty: [f32; 2],
    /// Sampling period, µs (the firmware's thermal loop period).
    pub sample_period_us: u64,
    last_us: Option<u64>,
}

impl Heaters {
    /// Wire two plants.
    pub fn new(hotend: Box<dyn HeaterPlant + Send>, bed: Box<dyn HeaterPlant + Send>) -> Self {
        Self {
            hotend,
            bed,
            duty: [0.0; 2],
            sample_period_us: 100_000,
            last_us: None,
        }
    }

    /// The Ender-3-class hot end and bed of [`crate::heater::HeaterParams`], at ambient.
    pub fn ender3() -> Self {
        use crate::heater::{HeaterModel, HeaterParams};
        Self::new(
            Box::new(HeaterModel::new(HeaterParams::ENDER3_HOTEND)),
            Box::new(HeaterModel::new(HeaterParams::ENDER3_BED)),
        )
    }

    /// A heater is on (time must keep passing for it).
    pub fn active(&self) -> bool {
        self.duty.iter().any(|d| *d > 0.0)
    }

    /// Hotend and bed temperatures, °C.
    pub fn temperatures_c(&self) -> (f32, f32) {
        (self.hotend.temperature_c(), self.bed.temperature_c())
    }

    /// Called on every main-loop tick; samples when a period has passed.
    pub fn tick<E: Executive>(&mut self, fw: &mut E, now_us: u64) {
        let last = match self.last_us {
            Some(l) => l,
            None => {
                self.last_us = Some(now_us);
                let t_h = self.hotend.temperature_c();
                let t_b = self.bed.temperature_c();
                self.duty[0] = fw.thermal(false, t_h, now_us);
                self.duty[1] = fw.thermal(true, t_b, now_us);
                return;
            }
        };
        if now_us < last + self.sample_period_us {
            return;
        }
        let dt_s = (now_us - last) as f32 * 1e-6;
        self.last_us = Some(now_us);
        let t_h = self.hotend.advance(self.duty[0], dt_s);
        let t_b = self.bed.advance(self.duty[1], dt_s);
        self.duty[0] = fw.thermal(false, t_h, now_us).clamp(0.0, 1.0);
        self.duty[1] = fw.thermal(true, t_b, now_us).clamp(0.0, 1.0);
    }
}
