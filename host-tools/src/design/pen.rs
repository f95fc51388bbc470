//! Building from points (FullControl style) with the turtle as the pen: `extrude_to` and
//! `travel_to` absolute points, polylines, and state changes at any point of the path — fan,
//! temperatures (waiting or not), extrusion width/height, speed, retraction, raw G-code and
//! pause marks. Each becomes a [`Step`] in order, so it comes out in the G-code exactly where
//! the script put it.
//!
//! `travel_to` never drives through printed material (it lifts over it, see
//! [`crate::design::travel`]); `travel_straight_to` is FullControl's plain travel for when the
//! designer knows the way is clear.
//!
//! ```
//! use glam::DVec3;
//! use host_tools::design::points::circle_xy;
//! use host_tools::design::profile::Profile;
//! use host_tools::design::turtle::Turtle;
//! use host_tools::design::writer::{GcodeWriter, WriteOptions};
//!
//! let mut t = Turtle::at(DVec3::new(100.0, 100.0, 0.2), 0.08, 20.0);
//! let ring = circle_xy(DVec3::new(110.0, 100.0, 0.2), 5.0, 0.0, 32, false).expect("circle");
//! t.polyline(&ring).expect("ring");
//! t.fan(50.0).expect("fan");
//! t.extrude_to(DVec3::new(120.0, 100.0, 0.2)).expect("line");
//! let p = Profile::ender3();
//! let opts = WriteOptions { bare: true, ..WriteOptions::default() };
//! let (g, _) = GcodeWriter::new(&p, opts).to_string(&t.into_model()).expect("G-code");
//! assert!(g.contains("M106 S128"));
//! ```

use crate::design::model::{StateChange, Step};
use crate::design::profile::{speed_beyond_limit, Primer, Retraction};
use crate::design::turtle::{finite, Turtle, TurtleError};
use crate::gcode::annotation;
use glam::DVec3;
use std::f64::consts::PI;

/// How a line's cross-section follows from its width and height (FullControl's area
/// models; declared in the G-code for the 3D page, [`crate::gcode::bead`]).
pub use crate::gcode::bead::AreaModel;

impl AreaModel {
    /// Parses `"rectangle"` or `"stadium"`.
    pub fn parse(s: &str) -> Result<Self, TurtleError> {
        match s {
            "rectangle" => Ok(AreaModel::Rectangle),
            "stadium" => Ok(AreaModel::Stadium),
            other => Err(TurtleError::BadArgument(format!(
                "area model is \"rectangle\" or \"stadium\", got \"{other}\""
            ))),
        }
    }

    /// Cross-section of a line `width_mm` wide and `height_mm` high, mm².
    pub fn cross_mm2(self, width_mm: f64, height_mm: f64) -> Result<f64, TurtleError> {
        let (w, h) = (finite("width", width_mm)?, finite("height", height_mm)?);
        if !(w > 0.0 && h > 0.0) {
            return Err(TurtleError::BadArgument(format!(
                "width and height must be > 0, got {w} × {h}"
            )));
        }
        Ok(match self {
            AreaModel::Rectangle => w * h,
            AreaModel::Stadium => {
                if h > w {
                    return Err(TurtleError::BadArgument(format!(
                        "stadium: height {h} is more than width {w}"
                    )));
                }
                (w - h) * h + PI * (h / 2.0) * (h / 2.0)
            }
        })
    }
}

fn point(p: DVec3) -> Result<DVec3, TurtleError> {
    if p.is_finite() {
        Ok(p)
    } else {
        Err(TurtleError::BadArgument(format!(
            "point must be finite, got {p:?}"
        )))
    }
}

impl Turtle {
    /// Extrudes a straight string from the current position to `p` (pen up or down).
    pub fn extrude_to(&mut self, p: DVec3) -> Result<(), TurtleError> {
        let p = point(p)?;
        let pen = self.state.pen_down;
        self.state.pen_down = true;
        self.go(p);
        self.state.pen_down = pen;
        Ok(())
    }

    /// Travels to `p` lifting over everything printed on the way.
    pub fn travel_to(&mut self, p: DVec3) -> Result<(), TurtleError> {
        let p = point(p)?;
        self.travel_safely(p);
        Ok(())
    }

    /// Travels straight to `p` (FullControl's travel: the designer vouches for the way).
    pub fn travel_straight_to(&mut self, p: DVec3) -> Result<(), TurtleError> {
        let p = point(p)?;
        self.goto(p.x, p.y, p.z)
    }

    /// Extrudes a true arc (written as G2/G3) about `centre_xy` through `sweep_rad` radians
    /// (counter-clockwise when positive, a full circle at ±2π), rising `dz` mm on the way (a
    /// helical arc). The radius is the pen's distance from the centre.
    pub fn extrude_arc(
        &mut self,
        centre_xy: [f64; 2],
        sweep_rad: f64,
        dz: f64,
    ) -> Result<(), TurtleError> {
        let c = glam::DVec2::new(
            finite("centre x", centre_xy[0])?,
            finite("centre y", centre_xy[1])?,
        );
        let (sweep, dz) = (finite("sweep", sweep_rad)?, finite("dz", dz)?);
        let from = self.state.pos;
        let r = (from.truncate() - c).length();
        if r.is_nan() || r <= 1e-6 || sweep == 0.0 || sweep.abs() > std::f64::consts::TAU + 1e-12 {
            return Err(TurtleError::BadArgument(format!(
                "arc: the pen must be off the centre and 0 < |sweep| ≤ 2π, got radius {r}, sweep {sweep}"
            )));
        }
        let a = (from.truncate() - c).to_angle() + sweep;
        let end = if (sweep.abs() - std::f64::consts::TAU).abs() < 1e-12 {
            from.truncate() // a full circle ends where it started
        } else {
            c + glam::DVec2::from_angle(a) * r
        };
        let to = end.extend(from.z + dz);
        self.push_step(Step::String(crate::design::model::Str {
            start: from,
            end: to,
            cross_mm2: self.state.cross_mm2,
            speed_mm_s: self.state.speed_mm_s,
            arc: Some(crate::design::model::Arc {
                center_xy: [c.x, c.y],
                ccw: sweep > 0.0,
            }),
        }));
        self.state.pos = to;
        Ok(())
    }

    /// Extrudes through every point in turn, starting from the current position.
    pub fn extrude_path(&mut self, points: &[DVec3]) -> Result<(), TurtleError> {
        for p in points {
            self.extrude_to(*p)?;
        }
        Ok(())
    }

    /// Draws a polyline: travels (lifting) to its first point, extrudes through the rest.
    pub fn polyline(&mut self, points: &[DVec3]) -> Result<(), TurtleError> {
        let Some((first, rest)) = points.split_first() else {
            return Ok(());
        };
        if point(*first)? != self.state.pos {
            self.travel_to(*first)?;
        }
        self.extrude_path(rest)
    }

    fn state_change(&mut self, sc: StateChange) {
        self.push_step(Step::State(sc));
    }

    /// Part-cooling fan, percent of full speed (0..=100).
    pub fn fan(&mut self, percent: f64) -> Result<(), TurtleError> {
        let p = finite("fan", percent)?;
        if !(0.0..=100.0).contains(&p) {
            return Err(TurtleError::BadArgument(format!(
                "fan: percent 0..100, got {p}"
            )));
        }
        self.state_change(StateChange::Fan(p / 100.0));
        Ok(())
    }

    fn temp(what: &str, c: f64) -> Result<f64, TurtleError> {
        let c = finite(what, c)?;
        if !(0.0..=400.0).contains(&c) {
            return Err(TurtleError::BadArgument(format!(
                "{what}: 0..400 °C, got {c}"
            )));
        }
        Ok(c)
    }

    /// Hot-end target, °C; `wait` waits until it is reached (M109 instead of M104).
    pub fn hotend(&mut self, celsius: f64, wait: bool) -> Result<(), TurtleError> {
        let celsius = Self::temp("hotend", celsius)?;
        self.state_change(StateChange::HotendTemp { celsius, wait });
        Ok(())
    }

    /// Bed target, °C; `wait` waits until it is reached (M190 instead of M140).
    pub fn bed(&mut self, celsius: f64, wait: bool) -> Result<(), TurtleError> {
        let celsius = Self::temp("bed", celsius)?;
        self.state_change(StateChange::BedTemp { celsius, wait });
        Ok(())
    }

    /// Sets the cross-section from a line width and height, mm.
    pub fn set_extrusion(
        &mut self,
        width_mm: f64,
        height_mm: f64,
        model: AreaModel,
    ) -> Result<(), TurtleError> {
        let c = model.cross_mm2(width_mm, height_mm)?;
        self.set_cross_section(c)?;
        // The 3D page draws the beads from here on with this model.
        self.state_change(StateChange::Bead(model));
        Ok(())
    }

    /// Retraction for the travels from here on.
    pub fn set_retraction(&mut self, r: Retraction) -> Result<(), TurtleError> {
        let ok = |v: f64| v.is_finite() && v >= 0.0;
        if !(ok(r.length_mm) && ok(r.min_travel_mm) && r.speed_mm_s.is_finite())
            || r.speed_mm_s <= 0.0
        {
            return Err(TurtleError::BadArgument(format!(
                "retraction: length ≥ 0, speed > 0, min travel ≥ 0, got {r:?}"
            )));
        }
        if r.speed_mm_s > self.retract_limit_mm_s {
            return Err(TurtleError::BadArgument(speed_beyond_limit(
                "retraction speed",
                r.speed_mm_s,
                "extruder",
                self.retract_limit_mm_s,
            )));
        }
        self.state_change(StateChange::Retraction(r));
        Ok(())
    }

    /// Raw G-code lines, written as they are (printable ASCII only). Each line must parse
    /// with the printer's own parser and keep the frame the writer relies on
    /// ([`crate::design::raw::check_text`]); what the lines do (moves, homing, heaters, fan,
    /// E) is seen by the checks and the writer.
    pub fn gcode(&mut self, text: &str) -> Result<(), TurtleError> {
        if text
            .chars()
            .any(|c| !(c.is_ascii_graphic() || c == ' ' || c == '\n'))
        {
            return Err(TurtleError::BadArgument(format!(
                "gcode: printable ASCII lines only, got {text:?}"
            )));
        }
        crate::design::raw::check_text(text)
            .map_err(|e| TurtleError::BadArgument(e.to_string()))?;
        self.state_change(StateChange::Gcode(text.to_string()));
        Ok(())
    }

    /// Speed of the travels from here on, mm/s (> 0; replaces the profile's).
    pub fn set_travel_speed(&mut self, mm_s: f64) -> Result<(), TurtleError> {
        let v = crate::design::turtle::speed_mm_s("travel speed", mm_s, self.speed_limit_mm_s)?;
        self.state_change(StateChange::TravelSpeed(v));
        Ok(())
    }

    /// The profile's primer (its purge line) or none; only before the first move.
    pub fn set_primer(&mut self, primer: Primer) -> Result<(), TurtleError> {
        if self
            .model()
            .steps
            .iter()
            .any(|s| matches!(s, Step::String(_) | Step::Travel { .. }))
        {
            return Err(TurtleError::BadArgument(
                "set_primer: the primer is part of the start code; choose it before the first move"
                    .into(),
            ));
        }
        self.state_change(StateChange::Primer(primer));
        Ok(())
    }

    /// An annotation for viewers (FullControl's `PlotAnnotation`), written as the comment
    /// `; ANNOTATION X<x> Y<y> Z<z>: <label>` ([`crate::gcode::annotation`]: mm, at most three
    /// decimals, the label on one line) at `at`, the pen's position when `None`; the 3D
    /// preview shows it there.
    pub fn annotate(&mut self, at: Option<DVec3>, label: &str) -> Result<(), TurtleError> {
        let p = point(at.unwrap_or(self.state.pos))?;
        let text = annotation::comment(Some(p.to_array()), label)
            .ok_or_else(|| TurtleError::BadArgument(format!("point must be finite, got {p:?}")))?;
        self.push_step(Step::Comment(text));
        Ok(())
    }

    /// A pause mark: `M601` (the firmware stops at the next layer boundary) or, with `now`,
    /// `M601 S1` (it stops here).
    pub fn pause(&mut self, now: bool) {
        self.state_change(StateChange::Pause { now });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn area_models_match_fullcontrol() {
        let r = AreaModel::Rectangle.cross_mm2(0.4, 0.2);
        assert!(r.is_ok_and(|c| (c - 0.08).abs() < 1e-12));
        let s = AreaModel::Stadium.cross_mm2(0.4, 0.2);
        let want = 0.2 * 0.2 + PI * 0.01;
        assert!(s.is_ok_and(|c| (c - want).abs() < 1e-12));
        assert!(AreaModel::Stadium.cross_mm2(0.2, 0.4).is_err());
        assert!(AreaModel::Rectangle.cross_mm2(0.0, 0.2).is_err());
        assert!(AreaModel::parse("circle").is_err());
    }

    /// A polyline starting one layer above where the last one closed steps straight up
    /// (it hopped 1 mm before issue 23); one crossing printed material at its height lifts.
    #[test]
    fn polyline_hops_only_when_printed_material_is_in_the_way() {
        let travels = |t: &Turtle| -> Vec<DVec3> {
            t.model()
                .steps
                .iter()
                .filter_map(|s| match s {
                    Step::Travel { to, .. } => Some(*to),
                    _ => None,
                })
                .collect()
        };
        let mut t = Turtle::at(DVec3::new(110.0, 100.0, 0.2), 0.08, 20.0);
        for z in [0.2, 0.4] {
            let ring =
                crate::design::points::circle_xy(DVec3::new(100.0, 100.0, z), 10.0, 0.0, 64, false)
                    .expect("circle");
            t.polyline(&ring).expect("ring");
        }
        assert_eq!(travels(&t), [DVec3::new(110.0, 100.0, 0.4)]);
        // Across the ring at its own height: up, across, down.
        t.polyline(&[DVec3::new(90.0, 100.0, 0.4), DVec3::new(89.0, 100.0, 0.4)])
            .expect("across");
        let tr = travels(&t);
        assert_eq!(tr.len(), 4, "{tr:?}");
        assert!(tr[1].z > 1.0 && tr[2].z > 1.0);
    }

    #[test]
    fn extrude_to_keeps_the_pen_and_travel_to_lifts() {
        let mut t = Turtle::at(DVec3::new(0.0, 0.0, 0.2), 0.1, 20.0);
        t.pen_up();
        assert!(t.extrude_to(DVec3::new(10.0, 0.0, 0.2)).is_ok());
        assert!(!t.state().pen_down);
        assert_eq!(t.model().string_count(), 1);
        assert!(t.travel_to(DVec3::new(0.0, 0.0, 0.2)).is_ok());
        let zs: Vec<f64> = t
            .model()
            .steps
            .iter()
            .filter_map(|s| match s {
                Step::Travel { to, .. } => Some(to.z),
                _ => None,
            })
            .collect();
        assert_eq!(zs.len(), 3);
        assert!(zs[0] > 1.0 && zs[1] > 1.0 && (zs[2] - 0.2).abs() < 1e-12);
        assert!(t.extrude_to(DVec3::splat(f64::NAN)).is_err());
        assert!(t.fan(101.0).is_err());
        assert!(t.hotend(500.0, true).is_err());
        assert!(t.gcode("M42 P1\u{7}").is_err());
        t.annotate(None, "seam\nhere").expect("annotate");
        t.annotate(Some(DVec3::new(1.5, -2.0, 0.25)), "corner")
            .expect("annotate");
        let n = t.model().steps.len();
        assert_eq!(
            t.model().steps[n - 2..],
            [
                Step::Comment("ANNOTATION X0 Y0 Z0.2: seam here".into()),
                Step::Comment("ANNOTATION X1.5 Y-2 Z0.25: corner".into())
            ]
        );
    }
}
