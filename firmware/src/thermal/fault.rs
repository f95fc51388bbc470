//! Latched thermal faults and refused requests, with Marlin's wording for the host.

use core::fmt;

use super::HeaterId;

/// What went wrong.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FaultKind {
    /// The temperature fell away from a held target (runaway protection).
    Runaway,
    /// The heater did not heat fast enough (watch protection).
    HeatingFailed,
    /// Below the minimum temperature while heating.
    MinTemp,
    /// Above the maximum temperature.
    MaxTemp,
    /// Thermistor open circuit.
    SensorOpen,
    /// Thermistor short circuit.
    SensorShort,
    /// Heaters shut down by the executive (M112 / kill).
    Killed,
}

/// A latched thermal fault: every heater is off until reset.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fault {
    /// The heater that tripped.
    pub heater: HeaterId,
    /// Why.
    pub kind: FaultKind,
    /// When, µs.
    pub at_us: u64,
    /// The last valid measurement of that heater, °C.
    pub measured_c: f32,
}

impl fmt::Display for Fault {
    /// Marlin's wording, e.g. `Thermal Runaway, system stopped! Heater_ID: 0`; print it after
    /// `Error:`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let what = match self.kind {
            FaultKind::Runaway => "Thermal Runaway",
            FaultKind::HeatingFailed => "Heating failed",
            FaultKind::MinTemp => "MINTEMP triggered",
            FaultKind::MaxTemp => "MAXTEMP triggered",
            FaultKind::SensorOpen => "Thermistor open circuit",
            FaultKind::SensorShort => "Thermistor short circuit",
            FaultKind::Killed => "Heaters off (killed)",
        };
        write!(
            f,
            "{what}, system stopped! Heater_ID: {}",
            self.heater.marlin_id()
        )
    }
}

/// Why a request was refused.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ThermalError {
    /// A fault is latched: nothing heats until reset.
    Faulted(Fault),
    /// Target above the heater's limit (`max_c − 15`).
    TooHot {
        /// Highest allowed target, °C.
        max_c: f32,
    },
    /// NaN, infinite or negative temperature, or invalid gains.
    Invalid,
    /// M303 on a heater whose control is bang-bang, or a tune already running elsewhere.
    Busy,
}

impl fmt::Display for ThermalError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ThermalError::Faulted(fault) => write!(f, "heaters off after fault: {fault}"),
            ThermalError::TooHot { max_c } => write!(f, "target above limit {max_c:.0}C"),
            ThermalError::Invalid => f.write_str("invalid temperature or gains"),
            ThermalError::Busy => f.write_str("heater busy (autotune)"),
        }
    }
}
