//! 3D turtle graphics in cylindrical coordinates (Kanada's `turtle.py`): the heading is always
//! horizontal; `forward(r, dz)` moves `r` ahead while rising `dz`, `left`/`right` turn, `up`/
//! `down` move vertically. Each forward with the pen down becomes one extruded string; with the
//! pen up, a travel. `push`/`pop` save and restore the whole turtle state, and `pop` *travels*
//! back to the saved point, so a fractal tree returns to its branch points without extruding
//! (the paper's stringing problem).

use crate::design::model::{MarkerKind, Model, StateChange, Step, Str};
use crate::design::profile::{speed_beyond_limit, Profile};
use crate::design::travel::HeightMap;
use glam::DVec3;

/// Deepest `push` nesting allowed (a runaway recursive script fails cleanly instead of
/// exhausting memory).
pub const MAX_STACK: usize = 10_000;

/// Everything `push` saves.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TurtleState {
    /// Position, mm.
    pub pos: DVec3,
    /// Heading in the XY plane, degrees counter-clockwise from +X.
    pub heading_deg: f64,
    /// Head speed, mm/s.
    pub speed_mm_s: f64,
    /// Cross-section of the extruded string, mm².
    pub cross_mm2: f64,
    /// Extrude on forward (pen down) or travel (pen up).
    pub pen_down: bool,
}

/// Turtle errors.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum TurtleError {
    /// `pop` without a matching `push`.
    #[error("pop without a matching push")]
    EmptyStack,
    /// Too many nested `push`es.
    #[error("push nesting deeper than {MAX_STACK}")]
    StackOverflow,
    /// A non-finite or out-of-range argument.
    #[error("{0}")]
    BadArgument(String),
}

/// The turtle and the model it draws.
#[derive(Clone, Debug)]
pub struct Turtle {
    pub(crate) state: TurtleState,
    stack: Vec<TurtleState>,
    /// Shared until changed (`Rc::make_mut`): a script's final `t` hands the runner a copy of
    /// the turtle, and the model of a 45,000-point design was copied with it.
    model: std::rc::Rc<Model>,
    /// What has been printed so far, for travels that lift over it (filled lazily).
    pub(crate) heights: HeightMap,
    /// The printer's axis speed limit, mm/s: a speed above it is refused as a likely mm/min
    /// value ([`speed_mm_s`]); unbounded for a turtle made without a printer.
    pub(crate) speed_limit_mm_s: f64,
    /// The fastest retraction, mm/s ([`Profile::max_retract_mm_s`]; as `speed_limit_mm_s`).
    pub(crate) retract_limit_mm_s: f64,
}

/// A speed as the design gives it, mm/s: finite, > 0 and at most the printer's axis limit.
/// Every speed entry point of a design uses this, so a FullControl value in mm/min
/// (`set_travel_speed(9000)`) is refused with the conversion instead of being written as
/// `F540000`.
pub fn speed_mm_s(name: &str, v: f64, limit_mm_s: f64) -> Result<f64, TurtleError> {
    if !(v.is_finite() && v > 0.0) {
        return Err(TurtleError::BadArgument(format!(
            "{name} must be > 0 mm/s, got {v}"
        )));
    }
    if v > limit_mm_s {
        return Err(TurtleError::BadArgument(speed_beyond_limit(
            name, v, "axis", limit_mm_s,
        )));
    }
    Ok(v)
}

pub(crate) fn finite(name: &str, v: f64) -> Result<f64, TurtleError> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(TurtleError::BadArgument(format!(
            "{name} must be finite, got {v}"
        )))
    }
}

impl Turtle {
    /// `init(FilamentDiameter, HeadTemperature, BedTemperature, CrossSection, x0, y0, z0)`:
    /// heading +X, pen down, speed 20 mm/s. Emits the filament diameter and the temperatures
    /// (bed ≤ 0 °C means unheated: the bed target is 0, so the start code's `M140`/`M190`
    /// switch it off instead of heating it to the profile's temperature).
    pub fn init(
        filament_diameter_mm: f64,
        head_c: f64,
        bed_c: f64,
        cross_mm2: f64,
        x0: f64,
        y0: f64,
        z0: f64,
    ) -> Result<Turtle, TurtleError> {
        if !(filament_diameter_mm.is_finite() && filament_diameter_mm > 0.0) {
            return Err(TurtleError::BadArgument(format!(
                "filament diameter must be > 0, got {filament_diameter_mm}"
            )));
        }
        if !(cross_mm2.is_finite() && cross_mm2 >= 0.0) {
            return Err(TurtleError::BadArgument(format!(
                "cross-section must be ≥ 0, got {cross_mm2}"
            )));
        }
        let pos = DVec3::new(finite("x0", x0)?, finite("y0", y0)?, finite("z0", z0)?);
        let mut model = Model::new([x0, y0]);
        model.push(Step::State(StateChange::FilamentDiameter(
            filament_diameter_mm,
        )));
        model.push(Step::State(StateChange::BedTemp {
            celsius: finite("bed temperature", bed_c)?.max(0.0),
            wait: true,
        }));
        model.push(Step::State(StateChange::HotendTemp {
            celsius: finite("head temperature", head_c)?,
            wait: true,
        }));
        model.push(Step::Travel {
            to: pos,
            speed_mm_s: None,
        });
        Ok(Turtle {
            state: TurtleState {
                pos,
                heading_deg: 0.0,
                speed_mm_s: 20.0,
                cross_mm2,
                pen_down: true,
            },
            stack: Vec::new(),
            model: std::rc::Rc::new(model),
            heights: HeightMap::new(),
            speed_limit_mm_s: f64::INFINITY,
            retract_limit_mm_s: f64::INFINITY,
        })
    }

    /// A turtle at `pos` that emits no state changes (for parts inside larger designs).
    pub fn at(pos: DVec3, cross_mm2: f64, speed_mm_s: f64) -> Turtle {
        Turtle {
            state: TurtleState {
                pos,
                heading_deg: 0.0,
                speed_mm_s,
                cross_mm2,
                pen_down: true,
            },
            stack: Vec::new(),
            model: std::rc::Rc::new(Model::new([pos.x, pos.y])),
            heights: HeightMap::new(),
            speed_limit_mm_s: f64::INFINITY,
            retract_limit_mm_s: f64::INFINITY,
        }
    }

    /// Refuses speeds above the printer's limits from here on: its X/Y axis limit for print
    /// and travel speeds, [`Profile::max_retract_mm_s`] for retraction speeds (see
    /// [`speed_mm_s`]).
    pub fn with_speed_limit(mut self, profile: &Profile) -> Turtle {
        self.speed_limit_mm_s = profile.limits.max_feed_xy_mm_s;
        self.retract_limit_mm_s = profile.max_retract_mm_s();
        self
    }

    /// Moves `r` mm along the heading while rising `dz` mm: a string (pen down) or a travel.
    pub fn forward(&mut self, r: f64, dz: f64) -> Result<(), TurtleError> {
        let (r, dz) = (finite("forward distance", r)?, finite("dz", dz)?);
        let h = self.state.heading_deg.to_radians();
        let to = self.state.pos + DVec3::new(r * h.cos(), r * h.sin(), dz);
        self.go(to);
        Ok(())
    }

    pub(crate) fn go(&mut self, to: DVec3) {
        let from = self.state.pos;
        if self.state.pen_down {
            self.push_step(Step::String(Str::line(
                from,
                to,
                self.state.cross_mm2,
                self.state.speed_mm_s,
            )));
        } else {
            self.push_step(Step::Travel {
                to,
                speed_mm_s: None,
            });
        }
        self.state.pos = to;
    }

    /// Turns left (counter-clockwise seen from above) by `deg`.
    pub fn left(&mut self, deg: f64) -> Result<(), TurtleError> {
        self.state.heading_deg = (self.state.heading_deg + finite("angle", deg)?) % 360.0;
        Ok(())
    }

    /// Turns right by `deg`.
    pub fn right(&mut self, deg: f64) -> Result<(), TurtleError> {
        self.left(-deg)
    }

    /// Moves straight up by `dz` mm (a vertical string with the pen down).
    pub fn up(&mut self, dz: f64) -> Result<(), TurtleError> {
        self.forward(0.0, dz)
    }

    /// Moves straight down by `dz` mm.
    pub fn down(&mut self, dz: f64) -> Result<(), TurtleError> {
        self.forward(0.0, -dz)
    }

    /// Sets the head speed, mm/s (> 0, at most the printer's axis limit).
    pub fn set_velocity(&mut self, v: f64) -> Result<(), TurtleError> {
        self.state.speed_mm_s = speed_mm_s("velocity", v, self.speed_limit_mm_s)?;
        Ok(())
    }

    /// Sets the cross-section of the extruded string, mm² (≥ 0).
    pub fn set_cross_section(&mut self, c: f64) -> Result<(), TurtleError> {
        if !(c.is_finite() && c >= 0.0) {
            return Err(TurtleError::BadArgument(format!(
                "cross-section must be ≥ 0, got {c}"
            )));
        }
        self.state.cross_mm2 = c;
        Ok(())
    }

    /// Sets the heading, degrees from +X.
    pub fn set_heading(&mut self, deg: f64) -> Result<(), TurtleError> {
        self.state.heading_deg = finite("heading", deg)? % 360.0;
        Ok(())
    }

    /// Travels (never extrudes) to an absolute point.
    pub fn goto(&mut self, x: f64, y: f64, z: f64) -> Result<(), TurtleError> {
        let to = DVec3::new(finite("x", x)?, finite("y", y)?, finite("z", z)?);
        self.push_step(Step::Travel {
            to,
            speed_mm_s: None,
        });
        self.state.pos = to;
        Ok(())
    }

    /// Writes a comment into the G-code.
    pub fn comment(&mut self, text: &str) {
        self.push_step(Step::Comment(text.to_string()));
    }

    /// Marks the start of a helix turn (a layer change for layer-based tools).
    pub fn mark_turn(&mut self, pitch_mm: f64) {
        self.push_step(Step::Marker {
            kind: MarkerKind::Turn,
            z_mm: self.state.pos.z,
            height_mm: pitch_mm,
        });
    }

    /// Marks the start of a layer.
    pub fn mark_layer(&mut self, height_mm: f64) {
        self.push_step(Step::Marker {
            kind: MarkerKind::Layer,
            z_mm: self.state.pos.z,
            height_mm,
        });
    }

    /// Pen up: forward travels.
    pub fn pen_up(&mut self) {
        self.state.pen_down = false;
    }

    /// Pen down: forward extrudes.
    pub fn pen_down(&mut self) {
        self.state.pen_down = true;
    }

    /// Saves the whole state (position, heading, speed, cross-section, pen).
    pub fn push(&mut self) -> Result<(), TurtleError> {
        if self.stack.len() >= MAX_STACK {
            return Err(TurtleError::StackOverflow);
        }
        self.stack.push(self.state);
        Ok(())
    }

    /// Restores the last saved state, travelling (not extruding) back to its position: up
    /// above what was printed on the way, across, and down ([`HeightMap::route`]), never
    /// straight back along the branch just printed.
    pub fn pop(&mut self) -> Result<(), TurtleError> {
        let s = self.stack.pop().ok_or(TurtleError::EmptyStack)?;
        self.travel_safely(s.pos);
        self.state = s;
        Ok(())
    }

    /// Travels to `to` over everything printed so far (see [`HeightMap::route`]).
    pub fn travel_safely(&mut self, to: DVec3) {
        self.heights.catch_up(&self.model);
        for p in self.heights.route(self.state.pos, to) {
            self.push_step(Step::Travel {
                to: p,
                speed_mm_s: None,
            });
        }
        self.state.pos = to;
    }

    /// The current state.
    pub fn state(&self) -> TurtleState {
        self.state
    }

    /// The model drawn so far.
    pub fn model(&self) -> &Model {
        &self.model
    }

    /// Appends a step to the model (copied first when a copy of the turtle shares it).
    pub(crate) fn push_step(&mut self, step: Step) {
        std::rc::Rc::make_mut(&mut self.model).push(step);
    }

    /// Finishes: the model drawn (without a copy when no other turtle shares it).
    pub fn into_model(self) -> Model {
        std::rc::Rc::try_unwrap(self.model).unwrap_or_else(|m| (*m).clone())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn square_returns_home() {
        let mut t = Turtle::at(DVec3::new(10.0, 10.0, 0.2), 0.2, 20.0);
        for _ in 0..4 {
            t.forward(10.0, 0.0).ok();
            t.left(90.0).ok();
        }
        let p = t.state().pos;
        assert!((p - DVec3::new(10.0, 10.0, 0.2)).length() < 1e-9);
        assert_eq!(t.model().string_count(), 4);
    }

    #[test]
    fn pop_travels_back_without_extruding() {
        let mut t = Turtle::at(DVec3::new(0.0, 0.0, 0.2), 0.2, 20.0);
        t.push().ok();
        t.forward(5.0, 0.0).ok();
        assert_eq!(t.pop(), Ok(()));
        let last = t.model().steps.last().cloned();
        assert!(
            matches!(last, Some(Step::Travel { to, .. }) if (to - DVec3::new(0.0, 0.0, 0.2)).length() < 1e-12)
        );
        assert_eq!(t.pop(), Err(TurtleError::EmptyStack));
    }

    #[test]
    fn bad_arguments_are_errors() {
        let mut t = Turtle::at(DVec3::ZERO, 0.2, 20.0);
        assert!(t.forward(f64::NAN, 0.0).is_err());
        assert!(t.set_velocity(0.0).is_err());
        assert!(Turtle::init(0.0, 200.0, 0.0, 0.2, 0.0, 0.0, 0.0).is_err());
    }
}
