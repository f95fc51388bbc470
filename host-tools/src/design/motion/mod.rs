//! Acceleration-aware motion model for estimates on the host: a time-parameterised trajectory.
//!
//! Moves are planned like a Marlin-class firmware plans them — per-axis feed and acceleration
//! limits, print/travel/retract accelerations (M204), junction deviation at corners,
//! trapezoidal velocity profiles with forward and backward passes — and emitted as
//! [`Segment`]s, each with its start time, duration and trapezoid, so a consumer can ask where
//! the head is at any time ([`Segment::position_at`], [`Trajectory::position_at`],
//! [`Trajectory::sample`]).
//!
//! This is an *estimator* for host tools (`stats`, the `timebased` resampler, previews), not
//! the firmware's planner: it plans in `f64`, with a look-ahead window of [`WINDOW`] blocks
//! replanned in chunks (exact whenever a stop is reachable within [`OVERLAP`] blocks, which
//! covers every practical print), so its memory stays constant on files of any size.
//!
//! Use: [`Planner::push`] moves and [`Planner::finish`], collecting segments in a closure; or
//! [`Trajectory::from_gcode`] for the whole list in memory.
//!
//! This module holds the limits and move kinds; `planner` plans, `segment` is one planned move
//! in time, `trajectory` drives the planner from G-code and holds a whole job.

mod planner;
mod segment;
mod trajectory;

pub use planner::{PlanMove, Planner, OVERLAP, WINDOW};
pub use segment::Segment;
pub use trajectory::{
    plan_gcode, plan_gcode_with, plan_marks, prelude_marks, LayerMark, PlanTotals, Trajectory,
};

use crate::design::profile::Profile;

/// Motion limits used by the planner.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MotionLimits {
    /// Highest feed per axis X, Y, Z, E, mm/s.
    pub max_feed_mm_s: [f64; 4],
    /// Highest acceleration per axis X, Y, Z, E, mm/s².
    pub max_accel_mm_s2: [f64; 4],
    /// Acceleration of printing moves, mm/s².
    pub accel_print_mm_s2: f64,
    /// Acceleration of travels, mm/s².
    pub accel_travel_mm_s2: f64,
    /// Acceleration of extruder-only moves, mm/s².
    pub accel_retract_mm_s2: f64,
    /// Junction deviation, mm.
    pub junction_deviation_mm: f64,
}

impl MotionLimits {
    /// The limits of a profile.
    pub fn from_profile(p: &Profile) -> Self {
        let l = &p.limits;
        MotionLimits {
            max_feed_mm_s: [
                l.max_feed_xy_mm_s,
                l.max_feed_xy_mm_s,
                l.max_feed_z_mm_s,
                l.max_feed_e_mm_s,
            ],
            max_accel_mm_s2: [
                l.max_accel_x_mm_s2,
                l.max_accel_y_mm_s2,
                l.max_accel_z_mm_s2,
                l.max_accel_e_mm_s2,
            ],
            accel_print_mm_s2: l.accel_print_mm_s2,
            accel_travel_mm_s2: l.accel_travel_mm_s2,
            accel_retract_mm_s2: l.accel_retract_mm_s2,
            junction_deviation_mm: l.junction_deviation_mm,
        }
    }
}

/// How far a layer's first extruding move may climb and still start at the layer's height,
/// mm: a helix turn's first string climbs a fraction of its pitch; a move that climbs more
/// comes onto the layer from below (a time-based file's sample chord out of the rise).
pub const LAYER_CLIMB_MM: f64 = 0.05;

/// The height a layer prints at, from its first extruding move (start and end Z): where it
/// starts, or where it ends when it comes onto the layer — down from above (a time-based
/// sample chord out of a lift's descent) or climbing more than [`LAYER_CLIMB_MM`].
pub fn layer_height_of(start_z_mm: f64, end_z_mm: f64) -> f64 {
    if end_z_mm < start_z_mm - 1e-6 || end_z_mm - start_z_mm > LAYER_CLIMB_MM {
        end_z_mm
    } else {
        start_z_mm
    }
}

/// The height each layer prints at ([`layer_height_of`] its first extruding move) — never a
/// travel's lift, whatever Z a marker or the first move after it names. The one notion of a
/// layer's height for `stats`, the 3D page, `timebased` and the cure check (the design's own
/// `;Z:` is written the same way). Layer index as [`Segment::layer`] (0 before the first mark).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PrintHeights {
    z_mm: Vec<Option<f64>>,
}

impl PrintHeights {
    /// Heights of every layer of `segments`.
    pub fn of(segments: &[Segment]) -> PrintHeights {
        let mut h = PrintHeights::default();
        for s in segments {
            h.note(s);
        }
        h
    }

    /// Notes one segment (in job order).
    pub fn note(&mut self, s: &Segment) {
        if s.kind != MoveKind::Print {
            return;
        }
        let l = s.layer as usize;
        if self.z_mm.len() <= l {
            self.z_mm.resize(l + 1, None);
        }
        if self.z_mm[l].is_none() {
            // To 0.1 µm: the reader's f32 noise (0.4000000059604645) is not a height.
            self.z_mm[l] = Some((layer_height_of(s.start[2], s.end[2]) * 1e4).round() / 1e4);
        }
    }

    /// The height layer index `layer` prints at; `None` when nothing in it prints.
    pub fn get(&self, layer: u32) -> Option<f64> {
        self.z_mm.get(layer as usize).copied().flatten()
    }
}

/// What a move does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MoveKind {
    /// Moves X/Y/Z while extruding.
    Print,
    /// Moves X/Y/Z without extruding (or while retracting).
    Travel,
    /// Moves only E (retract/prime).
    Extruder,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn limits() -> MotionLimits {
        MotionLimits {
            max_feed_mm_s: [500.0, 500.0, 5.0, 25.0],
            max_accel_mm_s2: [500.0, 500.0, 100.0, 5000.0],
            accel_print_mm_s2: 500.0,
            accel_travel_mm_s2: 500.0,
            accel_retract_mm_s2: 500.0,
            junction_deviation_mm: 0.013,
        }
    }

    #[test]
    fn single_move_trapezoid_time() {
        // 100 mm at 50 mm/s, a = 500: ramps 0.1 s each covering 2.5 mm, cruise 95 mm = 1.9 s.
        let t = Trajectory::from_gcode(b"G1 X100 F3000\n", limits()).expect("plan");
        assert!((t.duration_s - 2.1).abs() < 1e-9, "{}", t.duration_s);
        let p = t.position_at(1.05).expect("pos");
        assert!((p[0] - 50.0).abs() < 1e-9);
    }

    #[test]
    fn triangle_when_short() {
        // 1 mm at 100 mm/s, a = 500: peak sqrt(500) ≈ 22.36, t = 2·22.36/500.
        let t = Trajectory::from_gcode(b"G1 X1 F6000\n", limits()).expect("plan");
        let expect = 2.0 * 500f64.sqrt() / 500.0;
        assert!((t.duration_s - expect).abs() < 1e-9);
    }

    #[test]
    fn straight_line_split_keeps_speed() {
        // Collinear pieces join at full speed: same time as one move.
        let mut g = String::new();
        for i in 1..=1000 {
            g.push_str(&format!("G1 X{} F3000\n", i as f64 * 0.1));
        }
        let t = Trajectory::from_gcode(g.as_bytes(), limits()).expect("plan");
        assert!((t.duration_s - 2.1).abs() < 1e-6, "{}", t.duration_s);
        // Speed continuity across segments.
        for w in t.segments.windows(2) {
            assert!((w[0].v_exit_mm_s - w[1].v_entry_mm_s).abs() < 1e-9);
        }
        // sampling is monotone in time and ends at the end
        let samples: Vec<_> = t.sample(0.1).collect();
        assert!((21..=22).contains(&samples.len()));
        assert!(samples.windows(2).all(|w| w[1].1[0] >= w[0].1[0]));
    }

    #[test]
    fn square_corner_slows_down() {
        let t = Trajectory::from_gcode(b"G1 X50 F6000\nG1 Y50\n", limits()).expect("plan");
        let v = t.segments[0].v_exit_mm_s;
        // 90°: v = sqrt(a·jd·s/(1−s)), s = sin 45°
        let s = (0.5f64).sqrt();
        let expect = (500.0 * 0.013 * s / (1.0 - s)).sqrt();
        assert!((v - expect).abs() < 1e-9, "{v} vs {expect}");
    }
}
