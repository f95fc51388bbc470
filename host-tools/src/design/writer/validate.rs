//! Checking a model before writing: values that cannot become G-code are refused with the
//! index of their step.

use super::WriteError;
use crate::design::model::{Model, StateChange, Step};
use crate::design::profile::{speed_beyond_limit, Profile};

/// Rejects speeds above the printer's limits (strings, travels and travel speeds of parts,
/// `map_strings`, `scale_speed` as much as the turtle's against the X/Y axis limit; a design's
/// retraction speed against [`Profile::max_retract_mm_s`]): speeds are mm/s everywhere, and a value above
/// the limit is almost always one in mm/min.
pub fn speeds(model: &Model, profile: &Profile) -> Result<(), WriteError> {
    let xy = profile.limits.max_feed_xy_mm_s;
    for (index, s) in model.steps.iter().enumerate() {
        let (what, v, axis, max_mm_s) = match s {
            Step::String(s) => ("string speed", s.speed_mm_s, "axis", xy),
            Step::Travel {
                speed_mm_s: Some(v),
                ..
            } => ("travel speed", *v, "axis", xy),
            Step::State(StateChange::TravelSpeed(v)) => ("travel speed", *v, "axis", xy),
            Step::State(StateChange::Retraction(r)) => (
                "retraction speed",
                r.speed_mm_s,
                "extruder",
                profile.max_retract_mm_s(),
            ),
            _ => continue,
        };
        if v > max_mm_s {
            return Err(WriteError::BadStep {
                index,
                msg: speed_beyond_limit(what, v, axis, max_mm_s),
            });
        }
    }
    Ok(())
}

/// Rejects values that cannot become G-code (non-finite points, non-positive speeds, negative
/// cross-sections or filament diameters).
pub fn validate(model: &Model) -> Result<(), WriteError> {
    let bad = |index: usize, msg: String| Err(WriteError::BadStep { index, msg });
    let mut moved = false;
    for (i, s) in model.steps.iter().enumerate() {
        moved |= matches!(s, Step::String(_) | Step::Travel { .. });
        match s {
            Step::String(s) => {
                if !(s.start.is_finite() && s.end.is_finite()) {
                    return bad(i, format!("non-finite point {:?} → {:?}", s.start, s.end));
                }
                if !(s.cross_mm2.is_finite() && s.cross_mm2 >= 0.0) {
                    return bad(i, format!("cross-section {} mm² is invalid", s.cross_mm2));
                }
                if !(s.speed_mm_s.is_finite() && s.speed_mm_s > 0.0) {
                    return bad(i, format!("speed {} mm/s is invalid", s.speed_mm_s));
                }
                if let Some(a) = s.arc {
                    if !(a.center_xy[0].is_finite() && a.center_xy[1].is_finite()) {
                        return bad(i, "non-finite arc centre".into());
                    }
                }
            }
            Step::Travel { to, speed_mm_s } => {
                if !to.is_finite() {
                    return bad(i, format!("non-finite travel target {to:?}"));
                }
                if let Some(v) = speed_mm_s {
                    if !(v.is_finite() && *v > 0.0) {
                        return bad(i, format!("travel speed {v} mm/s is invalid"));
                    }
                }
            }
            Step::Marker {
                z_mm, height_mm, ..
            } => {
                if !(z_mm.is_finite() && height_mm.is_finite()) {
                    return bad(i, "non-finite marker height".into());
                }
            }
            Step::State(StateChange::FilamentDiameter(d)) => {
                if !(d.is_finite() && *d > 0.0) {
                    return bad(i, format!("filament diameter {d} mm is invalid"));
                }
            }
            Step::State(StateChange::HotendTemp { celsius, .. })
            | Step::State(StateChange::BedTemp { celsius, .. }) => {
                if !(celsius.is_finite() && (0.0..=400.0).contains(celsius)) {
                    return bad(i, format!("temperature {celsius} °C is out of range"));
                }
            }
            Step::State(StateChange::Fan(d)) => {
                if !d.is_finite() {
                    return bad(i, "non-finite fan duty".into());
                }
            }
            Step::State(StateChange::Retraction(r)) => {
                let ok = |v: f64| v.is_finite() && v >= 0.0;
                if !(ok(r.length_mm) && ok(r.min_travel_mm) && r.speed_mm_s.is_finite())
                    || r.speed_mm_s <= 0.0
                {
                    return bad(i, format!("retraction {r:?} is invalid"));
                }
            }
            Step::State(StateChange::Gcode(g)) => {
                if g.chars()
                    .any(|c| !(c.is_ascii_graphic() || c == ' ' || c == '\n'))
                {
                    return bad(i, format!("raw G-code {g:?}: only printable ASCII lines"));
                }
                if let Err(e) = crate::design::raw::check_text(g) {
                    return bad(i, e.to_string());
                }
            }
            Step::State(StateChange::TravelSpeed(v)) => {
                if !(v.is_finite() && *v > 0.0) {
                    return bad(i, format!("travel speed {v} mm/s is invalid"));
                }
            }
            Step::State(StateChange::Primer(_)) => {
                if moved {
                    return bad(
                        i,
                        "the primer is chosen before the design's first move (it is part of the start code)".into(),
                    );
                }
            }
            Step::State(StateChange::Pause { .. } | StateChange::Bead(_)) => {}
            Step::Comment(_) | Step::Type(_) => {}
        }
    }
    Ok(())
}
