//! A first-order heater model for the simulator and the thermal tests: one lumped heat capacity
//! (the heater block or the bed plate) heated by the heater and losing heat to ambient in
//! proportion to the temperature difference, and a thermistor that follows the block with its
//! own small lag. The model produces what the board would sample: 12-bit ADC readings through
//! the firmware's own thermistor curve and the SKR 2 divider, so the firmware's conversion,
//! control and protection all run on the simulated heater exactly as on the printer.
//!
//! Faults can be injected to prove the protection catches them: an open or shorted sensor, a
//! thermistor that fell out of the block, a dead heater, a MOSFET stuck on.
//!
//! ```
//! use sim::heater::{HeaterModel, HeaterParams};
//! let mut hotend = HeaterModel::new(HeaterParams::ENDER3_HOTEND);
//! hotend.step(1.0, 10.0); // full power for 10 s
//! assert!(hotend.temperature_c() > 40.0);
//! ```

use firmware::thermal::thermistor::ADC_MAX;
use firmware::thermal::Thermistor;

/// Physical parameters of one heater.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HeaterParams {
    /// Heat capacity of the block or plate, J/K.
    pub heat_capacity_j_k: f32,
    /// Loss to ambient, W/K (convection, radiation and conduction lumped together).
    pub loss_w_k: f32,
    /// Heater power at duty 1, W.
    pub power_w: f32,
    /// Ambient temperature, °C.
    pub ambient_c: f32,
    /// Time constant of the thermistor following the block, s (0 = no lag).
    pub sensor_lag_s: f32,
    /// The thermistor fitted (sets the ADC readings).
    pub thermistor: Thermistor,
}

impl HeaterParams {
    /// An Ender-3-class hot end: 40 W cartridge, 15 J/K block, 0.08 W/K loss (about 80 s from
    /// 25 °C to 200 °C at full power, about 35 % duty to hold 200 °C), 1.5 s sensor lag.
    pub const ENDER3_HOTEND: HeaterParams = HeaterParams {
        heat_capacity_j_k: 15.0,
        loss_w_k: 0.08,
        power_w: 40.0,
        ambient_c: 25.0,
        sensor_lag_s: 1.5,
        thermistor: Thermistor::MARLIN_1,
    };
    /// An Ender-3-class 24 V bed: 220 W, 700 J/K, 1.6 W/K (about 2 minutes to 60 °C).
    pub const ENDER3_BED: HeaterParams = HeaterParams {
        heat_capacity_j_k: 700.0,
        loss_w_k: 1.6,
        power_w: 220.0,
        ambient_c: 25.0,
        sensor_lag_s: 4.0,
        thermistor: Thermistor::MARLIN_1,
    };
}

/// A fault injected into the model.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HeaterFault {
    /// Thermistor wire broken: the ADC reads full scale.
    SensorOpen,
    /// Thermistor shorted: the ADC reads zero.
    SensorShort,
    /// The thermistor fell out of the block: it now follows ambient (the classic runaway).
    SensorDetached,
    /// The heater cartridge or its wiring died: no power whatever the duty.
    HeaterDead,
    /// The MOSFET failed short: full power whatever the duty.
    MosfetStuckOn,
}

/// Integration step, s: well below the smallest time constant (sensor lag).
const MAX_DT_S: f32 = 0.02;

/// The simulated heater.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HeaterModel {
    params: HeaterParams,
    block_c: f32,
    sensor_c: f32,
    fault: Option<HeaterFault>,
}

impl HeaterModel {
    /// A cold heater at ambient.
    pub fn new(params: HeaterParams) -> Self {
        HeaterModel {
            params,
            block_c: params.ambient_c,
            sensor_c: params.ambient_c,
            fault: None,
        }
    }

    /// The parameters.
    pub fn params(&self) -> &HeaterParams {
        &self.params
    }

    /// Injects a fault (None clears it).
    pub fn set_fault(&mut self, fault: Option<HeaterFault>) {
        self.fault = fault;
    }

    /// The injected fault.
    pub fn fault(&self) -> Option<HeaterFault> {
        self.fault
    }

    /// Advances the model by `dt_s` seconds with the heater at `duty` (clamped to 0..=1).
    pub fn step(&mut self, duty: f32, dt_s: f32) {
        if !dt_s.is_finite() || dt_s <= 0.0 {
            return;
        }
        let duty = if duty.is_finite() {
            duty.clamp(0.0, 1.0)
        } else {
            0.0
        };
        let duty = match self.fault {
            Some(HeaterFault::HeaterDead) => 0.0,
            Some(HeaterFault::MosfetStuckOn) => 1.0,
            _ => duty,
        };
        let p = self.params;
        let mut left = dt_s;
        while left > 0.0 {
            let h = left.min(MAX_DT_S);
            left -= h;
            let power_in = duty * p.power_w;
            let loss = p.loss_w_k * (self.block_c - p.ambient_c);
            self.block_c += (power_in - loss) / p.heat_capacity_j_k * h;
            let follow = if self.fault == Some(HeaterFault::SensorDetached) {
                p.ambient_c
            } else {
                self.block_c
            };
            if p.sensor_lag_s > 0.0 {
                self.sensor_c += (follow - self.sensor_c) * (h / p.sensor_lag_s).min(1.0);
            } else {
                self.sensor_c = follow;
            }
        }
    }

    /// True temperature of the block or plate, °C.
    pub fn temperature_c(&self) -> f32 {
        self.block_c
    }

    /// Temperature of the thermistor itself, °C.
    pub fn sensor_c(&self) -> f32 {
        self.sensor_c
    }

    /// What the firmware would be told in °C (`Printer::thermal_sample` / `Thermal::update`):
    /// the thermistor's temperature, or the sensor-fault markers −∞ (open) and +∞ (short).
    pub fn reading_c(&self) -> f32 {
        match self.fault {
            Some(HeaterFault::SensorOpen) => f32::NEG_INFINITY,
            Some(HeaterFault::SensorShort) => f32::INFINITY,
            _ => self.sensor_c,
        }
    }

    /// The 12-bit reading the board's ADC would take now.
    pub fn adc(&self) -> u16 {
        match self.fault {
            Some(HeaterFault::SensorOpen) => ADC_MAX,
            Some(HeaterFault::SensorShort) => 0,
            _ => self.params.thermistor.adc_at(self.sensor_c),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn approaches_steady_state() {
        let mut m = HeaterModel::new(HeaterParams::ENDER3_HOTEND);
        m.step(0.5, 3000.0);
        // Steady state: ambient + P·duty / loss = 25 + 20 / 0.08 = 275 °C.
        assert!(
            (m.temperature_c() - 275.0).abs() < 1.0,
            "{}",
            m.temperature_c()
        );
        m.step(0.0, 5000.0);
        assert!((m.temperature_c() - 25.0).abs() < 0.5);
    }

    #[test]
    fn faults_change_readings() {
        let mut m = HeaterModel::new(HeaterParams::ENDER3_HOTEND);
        m.set_fault(Some(HeaterFault::SensorOpen));
        assert_eq!(m.adc(), ADC_MAX);
        assert_eq!(m.reading_c(), f32::NEG_INFINITY);
        m.set_fault(Some(HeaterFault::SensorShort));
        assert_eq!(m.adc(), 0);
        assert_eq!(m.reading_c(), f32::INFINITY);
        m.set_fault(Some(HeaterFault::HeaterDead));
        m.step(1.0, 60.0);
        assert!((m.temperature_c() - 25.0).abs() < 1e-3);
    }
}
