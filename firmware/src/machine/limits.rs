//! The limits a commanded value must respect (build volume, override range, dwell time) and
//! the conversion of absolute millimetres to absolute steps.

use super::MachineError;
use crate::config::MachineConfig;
use crate::motion::{round_i32, Axis, StepPos, AXES};

/// Lowest and highest M220/M221 override, percent.
pub const OVERRIDE_RANGE_PCT: core::ops::RangeInclusive<f32> = 10.0..=999.0;

/// Slowest feed accepted, mm/min (0.1 mm/s; G20 inches converted first): the longest move of
/// the Ender-3 (its 416 mm diagonal) then takes 69 min. `G1 X13 F0.0001` was an 83-day move
/// (issue 31). Marlin refuses no feed but never steps slower than `MINIMAL_STEP_RATE` (120
/// steps/s: 1.5 mm/s on the Ender-3's X and Y); no slicer file in the corpus goes below F200.
pub const MIN_FEED_MM_MIN: f64 = 6.0;

/// How far (mm) a target may lie outside the build volume and still count as inside: absorbs
/// the rounding of decimal text, nothing more.
pub const BOUNDS_TOLERANCE_MM: f64 = 1e-4;

pub(super) fn check_override(pct: f32) -> Result<f32, MachineError> {
    if OVERRIDE_RANGE_PCT.contains(&pct) {
        Ok(pct)
    } else {
        Err(MachineError::OverrideOutOfRange)
    }
}

/// G4/M0 time in whole milliseconds (P wins over S, as in Marlin).
pub fn dwell_ms(ms: Option<f32>, s: Option<f32>) -> Result<u32, MachineError> {
    let ms = match (ms, s) {
        (Some(p), _) => f64::from(p),
        (None, Some(s)) => f64::from(s) * 1000.0,
        (None, None) => 0.0,
    };
    if ms < 0.0 {
        return Err(MachineError::NegativeTime);
    }
    // The parser bounds values to 1e7, so this fits a u32.
    Ok(libm::round(ms).min(f64::from(u32::MAX)) as u32)
}

/// X Y Z within the build volume (E has no limits unless the configuration gives some).
pub(super) fn check_bounds(pos: &[f64; AXES], cfg: &MachineConfig) -> Result<(), MachineError> {
    for axis in [Axis::X, Axis::Y, Axis::Z] {
        check_axis(axis, pos[axis.index()], cfg)?;
    }
    Ok(())
}

pub(super) fn check_axis(axis: Axis, v: f64, cfg: &MachineConfig) -> Result<(), MachineError> {
    let a = cfg.axis(axis);
    if v < f64::from(a.min_mm) - BOUNDS_TOLERANCE_MM
        || v > f64::from(a.max_mm) + BOUNDS_TOLERANCE_MM
    {
        return Err(MachineError::OutOfBounds(axis));
    }
    Ok(())
}

/// Absolute mm → absolute steps, rounding half away from zero.
pub(crate) fn to_steps(pos: &[f64; AXES], cfg: &MachineConfig) -> Result<StepPos, MachineError> {
    let mut out = [0i32; AXES];
    for axis in Axis::ALL {
        let i = axis.index();
        out[i] = round_i32(pos[i] * f64::from(cfg.axis(axis).steps_per_mm))
            .ok_or(MachineError::StepOverflow(axis))?;
    }
    Ok(out)
}
