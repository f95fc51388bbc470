//! One planned move as the consumers see it: its trapezoidal speed profile in time, and where
//! the head is at any moment of it.

use super::MoveKind;
use crate::gcode::read::Pos4;

/// One planned move: where, when, and its trapezoidal speed profile. Distances are along the
/// move's path length (XYZ length, or |ΔE| for extruder-only moves).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Segment {
    /// Start position X Y Z E.
    pub start: Pos4,
    /// End position X Y Z E.
    pub end: Pos4,
    /// Time the move starts, s from the start of the job.
    pub t_start_s: f64,
    /// Path length, mm.
    pub len_mm: f64,
    /// Speed at the start, mm/s.
    pub v_entry_mm_s: f64,
    /// Feed the G-code asked for (its `F`), mm/s; the planner may stay below it.
    pub feed_mm_s: f64,
    /// Highest speed reached, mm/s.
    pub v_peak_mm_s: f64,
    /// Speed at the end, mm/s.
    pub v_exit_mm_s: f64,
    /// Acceleration used for both ramps, mm/s².
    pub accel_mm_s2: f64,
    /// Accelerating time, s.
    pub t_accel_s: f64,
    /// Cruising time, s.
    pub t_cruise_s: f64,
    /// Decelerating time, s.
    pub t_decel_s: f64,
    /// Kind of move.
    pub kind: MoveKind,
    /// Layer index (0 before the first layer mark).
    pub layer: u32,
    /// Source line (1-based).
    pub line: u32,
}

impl Segment {
    /// Duration, s.
    pub fn duration_s(&self) -> f64 {
        self.t_accel_s + self.t_cruise_s + self.t_decel_s
    }

    /// End time, s.
    pub fn t_end_s(&self) -> f64 {
        self.t_start_s + self.duration_s()
    }

    /// Distance travelled `dt` seconds after the start, mm (clamped to the move).
    pub fn distance_at(&self, dt: f64) -> f64 {
        let a = self.accel_mm_s2;
        if dt <= 0.0 {
            return 0.0;
        }
        if dt < self.t_accel_s {
            return self.v_entry_mm_s * dt + 0.5 * a * dt * dt;
        }
        let d_acc = 0.5 * (self.v_entry_mm_s + self.v_peak_mm_s) * self.t_accel_s;
        let dt2 = dt - self.t_accel_s;
        if dt2 < self.t_cruise_s {
            return d_acc + self.v_peak_mm_s * dt2;
        }
        let d_cru = self.v_peak_mm_s * self.t_cruise_s;
        let dt3 = (dt2 - self.t_cruise_s).min(self.t_decel_s);
        (d_acc + d_cru + self.v_peak_mm_s * dt3 - 0.5 * a * dt3 * dt3).min(self.len_mm)
    }

    /// Speed `dt` seconds after the start, mm/s.
    pub fn speed_at(&self, dt: f64) -> f64 {
        let a = self.accel_mm_s2;
        if dt <= 0.0 {
            self.v_entry_mm_s
        } else if dt < self.t_accel_s {
            self.v_entry_mm_s + a * dt
        } else if dt < self.t_accel_s + self.t_cruise_s {
            self.v_peak_mm_s
        } else {
            let d = (dt - self.t_accel_s - self.t_cruise_s).min(self.t_decel_s);
            (self.v_peak_mm_s - a * d).max(self.v_exit_mm_s)
        }
    }

    /// Position at absolute time `t_s` (clamped to the move).
    pub fn position_at(&self, t_s: f64) -> Pos4 {
        let f = if self.len_mm > 0.0 {
            (self.distance_at(t_s - self.t_start_s) / self.len_mm).clamp(0.0, 1.0)
        } else {
            1.0
        };
        let mut p = self.start;
        for (k, v) in p.iter_mut().enumerate() {
            *v += (self.end[k] - self.start[k]) * f;
        }
        p
    }
}
