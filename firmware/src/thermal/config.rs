//! The thermal configuration: which heaters exist and how each is sensed, controlled and
//! protected (the Ender-3 defaults included).

use super::{PidGains, ProtectionConfig, Thermistor};

/// Number of heaters.
pub const HEATERS: usize = 2;

/// One heater.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum HeaterId {
    /// The hot end (`T` in M105, Marlin heater 0).
    Hotend = 0,
    /// The heated bed (`B` in M105).
    Bed = 1,
}

impl HeaterId {
    /// Both heaters in index order.
    pub const ALL: [HeaterId; HEATERS] = [HeaterId::Hotend, HeaterId::Bed];

    /// Index into per-heater arrays.
    pub const fn index(self) -> usize {
        self as usize
    }

    /// Marlin's `Heater_ID` spelling in error messages (`0`, `bed`).
    pub const fn marlin_id(self) -> &'static str {
        match self {
            HeaterId::Hotend => "0",
            HeaterId::Bed => "bed",
        }
    }
}

/// How a heater is controlled.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Control {
    /// PID (M301 for the hot end, M304 for the bed).
    Pid(PidGains),
    /// Full on below `target − hysteresis`, off above `target + hysteresis`, unchanged between.
    BangBang {
        /// Half-width of the dead band, °C.
        hysteresis_c: f32,
    },
}

/// Everything about one heater.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HeaterConfig {
    /// Its thermistor.
    pub thermistor: Thermistor,
    /// Its controller.
    pub control: Control,
    /// Runaway and heating watchdogs.
    pub protection: ProtectionConfig,
    /// Below this a heating heater faults (MINTEMP: usually an open sensor), °C.
    pub min_c: f32,
    /// Above this the heater faults (MAXTEMP), °C. Targets are limited to `max_c − 15`.
    pub max_c: f32,
    /// Highest duty 0..=1 (Marlin's `MAX_BED_POWER`/`PID_MAX` as a fraction).
    pub max_duty: f32,
    /// M109/M190 wait until the temperature is within this of the target, °C.
    pub window_c: f32,
    /// ... continuously for this long, seconds (Marlin's `TEMP_RESIDENCY_TIME`).
    pub residency_s: f32,
}

/// The pause's nozzle timeout: while parked, after `timeout_s` the nozzle target is lowered to
/// `nozzle_c` so filament does not cook in the hot end; on resume the old target comes back and
/// the executive waits for it before the head moves back. The bed is never touched (the part
/// must stay stuck to it). Marlin's pause does the same with `PAUSE_PARK_NOZZLE_TIMEOUT`
/// (`feature/pause.cpp`, `wait_for_confirmation`: the hot ends' idle timers only; `resume_print`:
/// re-heat and wait before the moves back). Set with `M760 T<s>` (`T0`: off).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IdleConfig {
    /// Seconds paused before the nozzle is lowered.
    pub timeout_s: u32,
    /// Nozzle target while idle, °C (0 = off).
    pub nozzle_c: f32,
}

impl IdleConfig {
    /// Marlin's default: the nozzle heater off after 45 s parked (`PAUSE_PARK_NOZZLE_TIMEOUT`,
    /// `Configuration_adv.h`), the bed kept.
    pub const MARLIN: IdleConfig = IdleConfig {
        timeout_s: 45,
        nozzle_c: 0.0,
    };
}

/// The whole thermal configuration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ThermalConfig {
    /// The hot end.
    pub hotend: HeaterConfig,
    /// The bed.
    pub bed: HeaterConfig,
    /// The hot-end fan runs while the nozzle is at or above this, °C (Marlin's
    /// `EXTRUDER_AUTO_FAN_TEMPERATURE`); it stops 2 °C below.
    pub hotend_fan_c: f32,
    /// Consecutive out-of-range samples before a min/max/sensor fault (filters single glitches;
    /// at 10 Hz, 3 samples = 0.3 s).
    pub range_fault_samples: u8,
    /// The pause's nozzle timeout (None = off).
    pub idle: Option<IdleConfig>,
}

impl ThermalConfig {
    /// Ender-3 class: Marlin thermistor table 1 (EPCOS 100k) on both heaters (see [`Thermistor::MARLIN_1`]), the PID gains of Marlin's Creality Ender-3
    /// example configurations (hot end 21.73/1.54/76.55, bed 462.10/85.47/624.59 — run M303 on
    /// your own printer), MAXTEMP 275 °C / 125 °C, MINTEMP 5 °C,
    /// Marlin's protection periods, fan at 50 °C, residency 10 s within 1 °C.
    pub const ENDER3: ThermalConfig = ThermalConfig {
        hotend: HeaterConfig {
            thermistor: Thermistor::MARLIN_1,
            control: Control::Pid(PidGains {
                kp: 21.73,
                ki: 1.54,
                kd: 76.55,
            }),
            protection: ProtectionConfig::HOTEND,
            min_c: 5.0,
            max_c: 275.0,
            max_duty: 1.0,
            window_c: 1.0,
            residency_s: 10.0,
        },
        bed: HeaterConfig {
            thermistor: Thermistor::MARLIN_1,
            control: Control::Pid(PidGains {
                kp: 462.1,
                ki: 85.47,
                kd: 624.59,
            }),
            protection: ProtectionConfig::BED,
            min_c: 5.0,
            max_c: 125.0,
            max_duty: 1.0,
            window_c: 1.0,
            residency_s: 10.0,
        },
        hotend_fan_c: 50.0,
        range_fault_samples: 3,
        idle: Some(IdleConfig::MARLIN),
    };
}

impl Default for ThermalConfig {
    fn default() -> Self {
        Self::ENDER3
    }
}

/// Margin between MAXTEMP and the highest target (Marlin's `HOTEND_OVERSHOOT`).
pub const TARGET_MARGIN_C: f32 = 15.0;
