//! A design's named initialisation — FullControl's `initialization_data` dictionary as an
//! options map (`init(#{ nozzle_temp: 210, extrusion_width: 0.5, primer: "none" })`) instead of
//! Kanada's seven positional numbers (which stay: `init(fd, head, bed, cross, x, y, z)`).
//!
//! Every option is the design's choice and final; an option left out is the printer profile's
//! default (temperatures, fan, travel speed, filament, primer), so the named form emits a state
//! change only for what it names. Speeds are mm/s as everywhere in this API — FullControl's
//! `print_speed`/`travel_speed` are mm/min — and a speed beyond the printer's axis limit is an
//! error that says so, since it is almost always a value in mm/min.

use crate::design::model::{StateChange, Step};
use crate::design::pen::AreaModel;
use crate::design::profile::{Primer, Profile};
use crate::design::turtle::{speed_mm_s, Turtle, TurtleError};
use glam::DVec3;

/// Head speed of a turtle that sets none, mm/s.
pub const DEFAULT_SPEED_MM_S: f64 = 20.0;
/// Extrusion height of the named `init` when it sets none, mm (FullControl's default).
pub const DEFAULT_HEIGHT_MM: f64 = 0.2;

/// The options of the named `init`; `None` = the profile's default (or the turtle's).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct InitOptions {
    /// Where the pen starts; `None`: the bed centre at the extrusion height, no travel.
    pub start: Option<DVec3>,
    /// Hot-end target, °C (`nozzle_temp`).
    pub nozzle_temp_c: Option<f64>,
    /// Bed target, °C (`bed_temp`; ≤ 0 = unheated: the start code switches it off).
    pub bed_temp_c: Option<f64>,
    /// Part fan, percent (`fan_percent`).
    pub fan_percent: Option<f64>,
    /// Head speed, mm/s (`print_speed`; default [`DEFAULT_SPEED_MM_S`]).
    pub print_speed_mm_s: Option<f64>,
    /// Travel speed, mm/s (`travel_speed`).
    pub travel_speed_mm_s: Option<f64>,
    /// Line width, mm (`extrusion_width`; default the profile's nozzle diameter).
    pub width_mm: Option<f64>,
    /// Line height, mm (`extrusion_height`; default [`DEFAULT_HEIGHT_MM`]).
    pub height_mm: Option<f64>,
    /// How width and height give the cross-section (`area_model`).
    pub area_model: AreaModel,
    /// Cross-section, mm² (`cross_section`: instead of width and height).
    pub cross_mm2: Option<f64>,
    /// Filament diameter, mm (`dia_feed`).
    pub filament_mm: Option<f64>,
    /// The profile's purge line or none (`primer`).
    pub primer: Option<Primer>,
}

fn positive(name: &str, v: Option<f64>) -> Result<Option<f64>, TurtleError> {
    match v {
        Some(x) if !(x.is_finite() && x > 0.0) => Err(TurtleError::BadArgument(format!(
            "init: {name} must be > 0, got {x}"
        ))),
        other => Ok(other),
    }
}

fn speed_within(name: &str, v: Option<f64>, max: f64) -> Result<Option<f64>, TurtleError> {
    v.map(|x| speed_mm_s(&format!("init: {name}"), x, max))
        .transpose()
}

impl Turtle {
    /// The named initialisation for `profile` (see the module docs).
    pub fn init_with(o: &InitOptions, profile: &Profile) -> Result<Turtle, TurtleError> {
        let max_xy = profile.limits.max_feed_xy_mm_s;
        let speed =
            speed_within("print_speed", o.print_speed_mm_s, max_xy)?.unwrap_or(DEFAULT_SPEED_MM_S);
        let travel = speed_within("travel_speed", o.travel_speed_mm_s, max_xy)?;
        let filament = positive("dia_feed", o.filament_mm)?;
        let cross = match (o.cross_mm2, o.width_mm, o.height_mm) {
            (Some(_), Some(_), _) | (Some(_), _, Some(_)) => {
                return Err(TurtleError::BadArgument(
                    "init: give cross_section or extrusion_width/extrusion_height, not both".into(),
                ))
            }
            (Some(c), None, None) => {
                if !(c.is_finite() && c >= 0.0) {
                    return Err(TurtleError::BadArgument(format!(
                        "init: cross_section must be ≥ 0, got {c}"
                    )));
                }
                c
            }
            (None, w, h) => o.area_model.cross_mm2(
                w.unwrap_or(profile.nozzle_diameter_mm),
                h.unwrap_or(DEFAULT_HEIGHT_MM),
            )?,
        };
        let c = profile.bed_center();
        let at = o.start.unwrap_or(DVec3::new(
            c[0],
            c[1],
            o.height_mm.unwrap_or(DEFAULT_HEIGHT_MM),
        ));
        if !at.is_finite() {
            return Err(TurtleError::BadArgument(format!(
                "init: start must be finite, got {at:?}"
            )));
        }
        let mut t = Turtle::at(at, cross, speed).with_speed_limit(profile);
        if let Some(p) = o.primer {
            t.set_primer(p)?;
        }
        if let Some(d) = filament {
            t.push_step(Step::State(StateChange::FilamentDiameter(d)));
        }
        if o.area_model != AreaModel::Rectangle {
            t.push_step(Step::State(StateChange::Bead(o.area_model)));
        }
        if let Some(b) = o.bed_temp_c {
            t.bed(b.max(0.0), true)?;
        }
        if let Some(h) = o.nozzle_temp_c {
            t.hotend(h, true)?;
        }
        if let Some(f) = o.fan_percent {
            t.fan(f)?;
        }
        if let Some(v) = travel {
            t.set_travel_speed(v)?;
        }
        if o.start.is_some() {
            t.push_step(Step::Travel {
                to: at,
                speed_mm_s: None,
            });
        }
        Ok(t)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn named_init_emits_only_what_it_names() {
        let p = Profile::ender3();
        let t = Turtle::init_with(&InitOptions::default(), &p).expect("defaults");
        assert!(t.model().steps.is_empty());
        assert!((t.state().cross_mm2 - 0.4 * 0.2).abs() < 1e-12);
        assert_eq!(t.state().speed_mm_s, DEFAULT_SPEED_MM_S);
        let o = InitOptions {
            nozzle_temp_c: Some(240.0),
            fan_percent: Some(30.0),
            primer: Some(Primer::None),
            start: Some(DVec3::new(50.0, 50.0, 0.3)),
            ..InitOptions::default()
        };
        let t = Turtle::init_with(&o, &p).expect("named");
        let s = &t.model().steps;
        assert!(matches!(
            s[0],
            Step::State(StateChange::Primer(Primer::None))
        ));
        assert!(s.contains(&Step::State(StateChange::Fan(0.3))));
        assert!(matches!(s.last(), Some(Step::Travel { .. })));
        // FullControl's mm/min: refused with the conversion.
        let e = Turtle::init_with(
            &InitOptions {
                travel_speed_mm_s: Some(8000.0),
                ..InitOptions::default()
            },
            &p,
        )
        .err()
        .map(|e| e.to_string())
        .unwrap_or_default();
        assert!(e.contains("mm/min") && e.contains("133.3"), "{e}");
        assert!(Turtle::init_with(
            &InitOptions {
                cross_mm2: Some(0.1),
                width_mm: Some(0.4),
                ..InitOptions::default()
            },
            &p
        )
        .is_err());
    }
}
