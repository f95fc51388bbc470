//! The streaming look-ahead planner: junction speeds at corners, forward and backward passes
//! over a window of blocks replanned in chunks, and the trapezoid of each block.

use super::{MotionLimits, MoveKind, Segment};
use crate::gcode::read::Pos4;
use std::collections::VecDeque;

/// Blocks planned together.
pub const WINDOW: usize = 512;

/// Blocks kept back for replanning with the next chunk.
pub const OVERLAP: usize = 96;

/// A move as given to the planner.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlanMove {
    /// Start X Y Z E.
    pub from: Pos4,
    /// End X Y Z E.
    pub to: Pos4,
    /// Requested feed, mm/s.
    pub feed_mm_s: f64,
    /// Layer index.
    pub layer: u32,
    /// Source line.
    pub line: u32,
}

#[derive(Clone, Copy, Debug)]
struct Block {
    mv: PlanMove,
    len: f64,
    kind: MoveKind,
    nominal: f64,
    accel: f64,
    /// Highest entry speed (junction limit), squared, (mm/s)².
    max_entry_sq: f64,
    /// Planned entry speed, squared: the passes work on squares, so they need no sqrt.
    entry_sq: f64,
}

/// Streaming look-ahead planner (see module docs).
#[derive(Clone, Debug)]
pub struct Planner {
    limits: MotionLimits,
    accel_print: f64,
    accel_travel: f64,
    window: VecDeque<Block>,
    t_s: f64,
    prev_unit: Option<[f64; 3]>,
    prev_nominal: f64,
    /// The entry speed of the window's first block is fixed (the previous chunk's exit).
    fixed_entry: f64,
    /// `fixed_entry` squared.
    fixed_entry_sq: f64,
}

impl Planner {
    /// A planner starting at rest at time 0.
    pub fn new(limits: MotionLimits) -> Self {
        Planner {
            accel_print: limits.accel_print_mm_s2,
            accel_travel: limits.accel_travel_mm_s2,
            limits,
            window: VecDeque::with_capacity(WINDOW + 1),
            t_s: 0.0,
            prev_unit: None,
            prev_nominal: 0.0,
            fixed_entry: 0.0,
            fixed_entry_sq: 0.0,
        }
    }

    /// Changes the print/travel accelerations (M204).
    pub fn set_accel(&mut self, print: Option<f64>, travel: Option<f64>) {
        if let Some(a) = print.filter(|a| a.is_finite() && *a > 0.0) {
            self.accel_print = a;
        }
        if let Some(a) = travel.filter(|a| a.is_finite() && *a > 0.0) {
            self.accel_travel = a;
        }
    }

    /// Waits `s` seconds at rest (G4): plans everything queued to a stop first.
    pub fn dwell(&mut self, s: f64, out: &mut dyn FnMut(Segment)) {
        self.finish(out);
        if s.is_finite() && s > 0.0 {
            self.t_s += s;
        }
    }

    /// Time planned so far (the end of the last emitted segment), s.
    pub fn time_s(&self) -> f64 {
        self.t_s
    }

    /// Adds a move; emits segments whose speeds are final.
    pub fn push(&mut self, mv: PlanMove, out: &mut dyn FnMut(Segment)) {
        let l = &self.limits;
        let d = [
            mv.to[0] - mv.from[0],
            mv.to[1] - mv.from[1],
            mv.to[2] - mv.from[2],
            mv.to[3] - mv.from[3],
        ];
        let xyz = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        let (len, kind) = if xyz > 1e-9 {
            (
                xyz,
                if d[3] > 1e-12 {
                    MoveKind::Print
                } else {
                    MoveKind::Travel
                },
            )
        } else if d[3].abs() > 1e-9 {
            (d[3].abs(), MoveKind::Extruder)
        } else {
            return;
        };
        if !(len.is_finite() && mv.feed_mm_s.is_finite() && mv.feed_mm_s > 0.0) {
            return;
        }
        let mut nominal = mv.feed_mm_s;
        let mut accel = match kind {
            MoveKind::Print => self.accel_print,
            MoveKind::Travel => self.accel_travel,
            MoveKind::Extruder => l.accel_retract_mm_s2,
        };
        let inv_len = 1.0 / len;
        for (k, dk) in d.iter().enumerate() {
            let u = dk.abs() * inv_len;
            // Divide only when the axis limit binds (most moves stay within every limit).
            if u > 1e-12 {
                if nominal * u > l.max_feed_mm_s[k] {
                    nominal = l.max_feed_mm_s[k] / u;
                }
                if accel * u > l.max_accel_mm_s2[k] {
                    accel = l.max_accel_mm_s2[k] / u;
                }
            }
        }
        let unit_xyz = if kind == MoveKind::Extruder {
            [0.0; 3]
        } else {
            [d[0] * inv_len, d[1] * inv_len, d[2] * inv_len]
        };
        // Junction speed (Marlin's junction deviation), squared: the planner works on v².
        let max_entry_sq = match (self.prev_unit, kind) {
            (Some(p), MoveKind::Print | MoveKind::Travel) if self.prev_nominal > 0.0 => {
                let cos_theta = -(p[0] * unit_xyz[0] + p[1] * unit_xyz[1] + p[2] * unit_xyz[2]);
                let v_sq = if cos_theta < -0.999_999 {
                    f64::INFINITY
                } else if cos_theta > 0.999_999 {
                    0.0
                } else {
                    let sin_half = (0.5 * (1.0 - cos_theta)).sqrt();
                    accel * l.junction_deviation_mm * sin_half / (1.0 - sin_half)
                };
                let v = nominal.min(self.prev_nominal);
                v_sq.min(v * v)
            }
            _ => 0.0,
        };
        if kind == MoveKind::Extruder {
            self.prev_unit = None;
            self.prev_nominal = 0.0;
        } else {
            self.prev_unit = Some(unit_xyz);
            self.prev_nominal = nominal;
        }
        self.window.push_back(Block {
            mv,
            len,
            kind,
            nominal,
            accel,
            max_entry_sq,
            entry_sq: 0.0,
        });
        if self.window.len() >= WINDOW {
            self.plan_window();
            self.emit(WINDOW - OVERLAP, out);
        }
    }

    /// Plans the rest to a stop and emits it.
    pub fn finish(&mut self, out: &mut dyn FnMut(Segment)) {
        self.plan_window();
        let n = self.window.len();
        self.emit(n, out);
        self.prev_unit = None;
        self.prev_nominal = 0.0;
        self.fixed_entry = 0.0;
        self.fixed_entry_sq = 0.0;
    }

    fn plan_window(&mut self) {
        let n = self.window.len();
        if n == 0 {
            return;
        }
        // Backward pass: the window ends at rest. Speeds squared: v² = v_next² + 2·a·len.
        let mut next_sq = 0.0f64;
        for b in self.window.iter_mut().rev() {
            let reach_sq = next_sq + 2.0 * b.accel * b.len;
            b.entry_sq = b.max_entry_sq.min(reach_sq);
            next_sq = b.entry_sq;
        }
        // Forward pass from the fixed entry of the first block.
        let mut entry_sq = self.fixed_entry_sq;
        let mut it = self.window.iter_mut().peekable();
        while let Some(b) = it.next() {
            b.entry_sq = entry_sq.min(b.nominal * b.nominal);
            let reach_sq = b.entry_sq + 2.0 * b.accel * b.len;
            entry_sq = match it.peek() {
                Some(next) => next.entry_sq.min(reach_sq),
                None => 0.0,
            };
        }
    }

    fn emit(&mut self, count: usize, out: &mut dyn FnMut(Segment)) {
        for _ in 0..count {
            let Some(b) = self.window.pop_front() else {
                break;
            };
            // The entry is usually the previous block's exit: reuse its square root.
            let entry = if b.entry_sq == self.fixed_entry_sq {
                self.fixed_entry
            } else {
                b.entry_sq.sqrt()
            };
            let exit_sq = self.window.front().map_or(0.0, |n| n.entry_sq);
            let exit = exit_sq.sqrt();
            let seg = trapezoid(&b, entry, exit, self.t_s);
            self.t_s += seg.duration_s();
            self.fixed_entry = exit;
            self.fixed_entry_sq = exit_sq;
            out(seg);
        }
    }
}

fn trapezoid(b: &Block, v0: f64, v1: f64, t0: f64) -> Segment {
    let a = b.accel;
    let l = b.len;
    let inv_a = 1.0 / a;
    let vmax = b.nominal.max(v0).max(v1);
    let d_acc = (vmax * vmax - v0 * v0) * 0.5 * inv_a;
    let d_dec = (vmax * vmax - v1 * v1) * 0.5 * inv_a;
    let (vp, t_acc, t_cru, t_dec) = if d_acc + d_dec <= l {
        (
            vmax,
            (vmax - v0) * inv_a,
            (l - d_acc - d_dec) / vmax,
            (vmax - v1) * inv_a,
        )
    } else {
        // Triangle: peak where the ramps meet (never below the ends).
        let vp = ((2.0 * a * l + v0 * v0 + v1 * v1) / 2.0)
            .sqrt()
            .max(v0)
            .max(v1);
        let t_acc = ((vp - v0) / a).max(0.0);
        let t_dec = ((vp - v1) / a).max(0.0);
        // If the ends differ by more than one ramp allows (chunk boundary), cover the
        // distance at the mean speed of the ramps.
        let d = 0.5 * (v0 + vp) * t_acc + 0.5 * (vp + v1) * t_dec;
        if d > l * (1.0 + 1e-6) && vp > 0.0 {
            let t = 2.0 * l / (v0 + v1).max(1e-9);
            (vp, t, 0.0, 0.0)
        } else {
            (vp, t_acc, 0.0, t_dec)
        }
    };
    Segment {
        start: b.mv.from,
        end: b.mv.to,
        t_start_s: t0,
        len_mm: l,
        v_entry_mm_s: v0,
        feed_mm_s: b.mv.feed_mm_s,
        v_peak_mm_s: vp,
        v_exit_mm_s: v1,
        accel_mm_s2: a,
        t_accel_s: t_acc,
        t_cruise_s: t_cru,
        t_decel_s: t_dec,
        kind: b.kind,
        layer: b.mv.layer,
        line: b.mv.line,
    }
}
