//! Machine-safety checks of the executive (issue 16), as Marlin makes them:
//!
//! - **Cold extrusion** (`PREVENT_COLD_EXTRUSION`, `EXTRUDE_MINTEMP 170` in Marlin's Ender-3
//!   example configurations, e.g. `config/examples/Creality/Ender-3/CrealityV427/
//!   Configuration.h` of MarlinFirmware/Configurations at 25e9ab2318): no E motion while the
//!   hotend is below the minimum, unless M302 P1 allows it. A line that would move E while the
//!   hotend is cold and not heating is refused at once; one taken while the hotend heats waits
//!   in the queue, before the planner, until the hotend has reached the minimum (Marlin checks
//!   when it plans the move; M109 blocks its parser, our queue takes lines behind a heater
//!   wait).
//! - **Over-long extrusion** (`PREVENT_LENGTHY_EXTRUDE`, `EXTRUDE_MAXLENGTH 200`, same file):
//!   no single move feeds more than 200 mm of filament (`G92 E9999999` then `G1 X5 E0` would
//!   otherwise unwind 10 km of filament). M302 does not lift it.
//! - **M760 values and the park position** within the machine's limits (park X/Y inside the
//!   travel, lift no higher than the Z travel, park feed no faster than X/Y may move, ...).
//!
//! Marlin drops the E part of a refused move and goes on; here the whole line is refused with
//! an `echo:` line (never `Error:`, which makes OctoPrint end the print) and nothing changes:
//! the machine state is restored, nothing is queued.

use crate::config::MachineConfig;
use crate::gcode::PauseParams;
use crate::motion::Axis;
use core::fmt;

/// Marlin's `EXTRUDE_MINTEMP` in its Ender-3 example configurations, °C.
pub const EXTRUDE_MINTEMP_C: f32 = 170.0;

/// Marlin's `EXTRUDE_MAXLENGTH` in its Ender-3 example configurations, mm.
pub const EXTRUDE_MAXLENGTH_MM: f32 = 200.0;

/// Cold- and long-extrusion protection settings (M302).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ExtrusionGuard {
    /// Lowest hotend temperature at which E may move, °C (M302 S).
    pub min_temp_c: f32,
    /// Cold extrusion allowed (M302 P1).
    pub allow_cold: bool,
    /// Longest E motion of one move, mm (not changeable by G-code, as in Marlin).
    pub max_length_mm: f32,
}

impl ExtrusionGuard {
    /// Marlin's defaults: protection on, 170 °C, 200 mm.
    pub const MARLIN: ExtrusionGuard = ExtrusionGuard {
        min_temp_c: EXTRUDE_MINTEMP_C,
        allow_cold: false,
        max_length_mm: EXTRUDE_MAXLENGTH_MM,
    };

    /// The hotend at `hotend_c` is too cold to move E.
    pub fn too_cold(&self, hotend_c: f32) -> bool {
        // NaN (no reading) counts as cold.
        !self.allow_cold
            && hotend_c
                .partial_cmp(&self.min_temp_c)
                .is_none_or(|o| o.is_lt())
    }

    /// May a move feed `de_mm` of filament (either direction), the hotend at `hotend_c` with
    /// its target `target_c`? Cold with a target at or above the minimum is heating: allowed
    /// here, the queue holds the move until the hotend is hot (the heat part's `waits_for_heat`).
    pub fn check(&self, de_mm: f32, hotend_c: f32, target_c: f32) -> Result<(), Refusal> {
        self.check_length(de_mm)?;
        self.check_cold(de_mm, hotend_c, target_c)
    }

    /// The length half of [`ExtrusionGuard::check`]: one move feeds at most `max_length_mm`.
    pub fn check_length(&self, de_mm: f32) -> Result<(), Refusal> {
        if libm::fabsf(de_mm)
            .partial_cmp(&self.max_length_mm)
            .is_none_or(|o| o.is_gt())
        {
            return Err(Refusal::LongExtrusion {
                e_mm: de_mm,
                max_mm: self.max_length_mm,
            });
        }
        Ok(())
    }

    /// The temperature half of [`ExtrusionGuard::check`].
    pub fn check_cold(&self, de_mm: f32, hotend_c: f32, target_c: f32) -> Result<(), Refusal> {
        if de_mm == 0.0 {
            return Ok(());
        }
        if self.too_cold(hotend_c) && self.too_cold(target_c) {
            return Err(Refusal::ColdExtrusion {
                hotend_c,
                min_c: self.min_temp_c,
            });
        }
        Ok(())
    }
}

impl Default for ExtrusionGuard {
    fn default() -> Self {
        Self::MARLIN
    }
}

/// Why a line was refused. Shown after `echo:`; the first words are Marlin's messages.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Refusal {
    /// E would move with the hotend below the minimum and not heating.
    ColdExtrusion {
        /// Hotend temperature, °C.
        hotend_c: f32,
        /// The minimum, °C.
        min_c: f32,
    },
    /// One move would feed more filament than allowed.
    LongExtrusion {
        /// The move's E motion, mm.
        e_mm: f32,
        /// The limit, mm.
        max_mm: f32,
    },
    /// An M760 value outside the machine's limits.
    PauseValue {
        /// The M760 letter.
        letter: char,
        /// The value given.
        value: f32,
        /// Lowest allowed.
        min: f32,
        /// Highest allowed.
        max: f32,
    },
}

impl fmt::Display for Refusal {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Self::ColdExtrusion { hotend_c, min_c } => write!(
                f,
                "cold extrusion prevented: hotend {hotend_c:.0} C, below {min_c:.0} C (M104/M109 to heat, M302 P1 to allow)"
            ),
            Self::LongExtrusion { e_mm, max_mm } => write!(
                f,
                "too long extrusion prevented: E {e_mm:.2} mm in one move, at most {max_mm:.0} mm"
            ),
            Self::PauseValue {
                letter,
                value,
                min,
                max,
            } => write!(
                f,
                "M760 {letter}{value:.2} outside {min:.2}..{max:.2}, nothing changed"
            ),
        }
    }
}

/// Check every M760 value against the ranges table ([`crate::ranges`], what M500 saves) and
/// the machine (park inside the travel, lift within the Z travel, park feed within the X/Y
/// limits); all or nothing. The settings loaded from flash are checked the same way.
pub fn check_pause_params(p: &PauseParams, cfg: &MachineConfig) -> Result<(), Refusal> {
    use crate::ranges::{
        NOZZLE_TIMEOUT, PARK_FEED, PARK_XY, PAUSE_LIFT, PAUSE_RETRACT, SEGMENT, SPEEDUP, VOLUMETRIC,
    };
    let x = cfg.axis(Axis::X);
    let y = cfg.axis(Axis::Y);
    let z = cfg.axis(Axis::Z);
    let xy_feed_mm_min = x.max_feed_mm_s.min(y.max_feed_mm_s) * 60.0;
    // (letter, value, its range in the table (in M760's unit), the machine's own limits).
    let per_min = |b: crate::ranges::Bound| crate::ranges::Bound {
        min: b.min * 60.0,
        max: b.max * 60.0,
        ..b
    };
    let checks: [(char, Option<f32>, crate::ranges::Bound, f32, f32); 9] = [
        ('R', p.retract_mm, PAUSE_RETRACT, f32::MIN, f32::MAX),
        ('Z', p.lift_z_mm, PAUSE_LIFT, f32::MIN, z.max_mm - z.min_mm),
        ('X', p.park_x_mm, PARK_XY, x.min_mm, x.max_mm),
        ('Y', p.park_y_mm, PARK_XY, y.min_mm, y.max_mm),
        (
            'F',
            p.park_feed_mm_min,
            per_min(PARK_FEED),
            f32::MIN,
            xy_feed_mm_min,
        ),
        ('S', p.speedup_factor, SPEEDUP, f32::MIN, f32::MAX),
        ('V', p.max_volumetric_mm3_s, VOLUMETRIC, f32::MIN, f32::MAX),
        ('L', p.segment_len_mm, SEGMENT, f32::MIN, f32::MAX),
        ('T', p.nozzle_timeout_s, NOZZLE_TIMEOUT, f32::MIN, f32::MAX),
    ];
    for (letter, value, bound, lo, hi) in checks {
        if let Some(v) = value {
            // `!(..)` so NaN is refused too.
            if !(bound.contains(v) && v >= lo && v <= hi) {
                return Err(Refusal::PauseValue {
                    letter,
                    value: v,
                    min: bound.min.max(lo),
                    max: bound.max.min(hi),
                });
            }
        }
    }
    Ok(())
}

/// The saved pause values against the same checks as M760's (park inside this machine's
/// travel and so on): settings loaded from flash run as if set by M760.
pub fn check_pause_config(
    p: &crate::config::PauseConfig,
    cfg: &MachineConfig,
) -> Result<(), Refusal> {
    // No nozzle timeout: not saved by M500 (Marlin's configuration, set per session).
    check_pause_params(&PauseParams::from_config(p, None), cfg)
}

/// `mm` on `axis`, moved inside the axis's travel (for positions from the configuration,
/// such as the park, which code can set without M760's checks).
pub fn within_travel(cfg: &MachineConfig, axis: Axis, mm: f32) -> f32 {
    let a = cfg.axis(axis);
    if mm.is_nan() {
        return a.min_mm;
    }
    mm.clamp(a.min_mm, a.max_mm)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cold_long_and_heating() {
        let g = ExtrusionGuard::MARLIN;
        assert!(matches!(
            g.check(50.0, 25.0, 0.0),
            Err(Refusal::ColdExtrusion { .. })
        ));
        assert!(g.check(-2.0, f32::NAN, 0.0).is_err());
        assert_eq!(g.check(0.0, 25.0, 0.0), Ok(()));
        // Heating: taken (the queue waits for the temperature).
        assert_eq!(g.check(5.0, 25.0, 200.0), Ok(()));
        assert_eq!(g.check(5.0, 170.0, 0.0), Ok(()));
        assert!(matches!(
            g.check(200.5, 210.0, 210.0),
            Err(Refusal::LongExtrusion { .. })
        ));
        assert!(g.check(-9_999_999.0, 210.0, 210.0).is_err());
        let allowed = ExtrusionGuard {
            allow_cold: true,
            ..g
        };
        assert_eq!(allowed.check(50.0, 25.0, 0.0), Ok(()));
        // M302 P1 does not lift the length limit.
        assert!(allowed.check(91_335.0, 25.0, 0.0).is_err());
    }

    #[test]
    fn pause_values_within_the_machine() {
        let cfg = MachineConfig::ENDER3;
        let p = |f: fn(&mut PauseParams)| {
            let mut p = PauseParams::default();
            f(&mut p);
            check_pause_params(&p, &cfg)
        };
        assert!(p(|p| p.park_x_mm = Some(1000.0)).is_err());
        assert!(p(|p| p.park_x_mm = Some(235.0)).is_ok());
        assert!(p(|p| p.park_y_mm = Some(-1.0)).is_err());
        assert!(p(|p| p.lift_z_mm = Some(251.0)).is_err());
        assert!(p(|p| p.retract_mm = Some(21.0)).is_err());
        assert!(p(|p| p.park_feed_mm_min = Some(0.0)).is_err());
        assert!(p(|p| p.park_feed_mm_min = Some(30_001.0)).is_err());
        assert!(p(|p| p.speedup_factor = Some(0.5)).is_err());
        assert!(p(|p| p.segment_len_mm = Some(0.01)).is_err());
        assert!(p(|p| p.segment_len_mm = Some(0.0)).is_ok());
        assert_eq!(within_travel(&cfg, Axis::X, 1000.0), 235.0);
        assert_eq!(within_travel(&cfg, Axis::Y, f32::NAN), 0.0);
    }
}
