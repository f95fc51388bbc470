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

use crate::design::profile::Profile;
use crate::job::read::{default_reader, Event, GcodeReader, LayerSource, Pos4, ReadError};
use std::collections::VecDeque;

/// Blocks planned together.
pub const WINDOW: usize = 512;
/// Blocks kept back for replanning with the next chunk.
pub const OVERLAP: usize = 96;

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

/// Drives a planner from G-code: reads `input` with the default reader and calls `out` with
/// every segment, `layer` with every layer start (the firmware's layer number, height if known,
/// time). Segments carry the count of layer starts before them ([`Segment::layer`]).
pub fn plan_gcode(
    input: &[u8],
    limits: MotionLimits,
    out: &mut dyn FnMut(Segment),
    layer: &mut dyn FnMut(u32, Option<f64>, f64),
) -> Result<PlanTotals, ReadError> {
    plan_gcode_with(&mut default_reader(), input, limits, out, layer)
}

/// [`plan_gcode`] with a given reader (e.g. one that skips rejected lines).
pub fn plan_gcode_with(
    reader: &mut crate::job::read::FirmwareReader,
    input: &[u8],
    limits: MotionLimits,
    out: &mut dyn FnMut(Segment),
    layer: &mut dyn FnMut(u32, Option<f64>, f64),
) -> Result<PlanTotals, ReadError> {
    let mut planner = Planner::new(limits);
    let mut cur_layer = 0u32;
    let mut moves = 0u64;
    let mut dwell_s = 0.0;
    let mut explicit_layers = false;
    let counts = reader.read(input, &mut |ev| match ev {
        Event::Move {
            from,
            to,
            feed_mm_s,
            line,
        } => {
            moves += 1;
            planner.push(
                PlanMove {
                    from,
                    to,
                    feed_mm_s,
                    layer: cur_layer,
                    line,
                },
                out,
            );
        }
        Event::Layer {
            z_mm,
            source,
            number,
            ..
        } => {
            cur_layer += 1;
            explicit_layers |= source != LayerSource::ZRise;
            layer(number, z_mm, planner.time_s());
        }
        Event::Dwell(s) => {
            dwell_s += s;
            planner.dwell(s, out);
        }
        Event::Accel {
            print_mm_s2,
            travel_mm_s2,
        } => planner.set_accel(print_mm_s2, travel_mm_s2),
    })?;
    planner.finish(out);
    Ok(PlanTotals {
        time_s: planner.time_s(),
        moves,
        layer_marks: cur_layer,
        explicit_layers,
        lines: counts.lines,
        skipped: counts.skipped,
        bad_lines: counts.bad,
        dwell_s,
    })
}

/// Totals of one planning run.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PlanTotals {
    /// Total time including dwells, s.
    pub time_s: f64,
    /// Moves read.
    pub moves: u64,
    /// Layer marks found by the firmware's layer detector (slicer markers, or Z rises in a
    /// file without any).
    pub layer_marks: u32,
    /// At least one mark came from an explicit marker (comment or command), not a Z rise.
    pub explicit_layers: bool,
    /// Lines read.
    pub lines: u64,
    /// Commands skipped as not affecting motion.
    pub skipped: u64,
    /// Lines the firmware would reject, skipped (only with a skipping reader).
    pub bad_lines: u64,
    /// Time spent in dwells, s.
    pub dwell_s: f64,
}

/// A whole job as a time-parameterised trajectory (for the time-based resampler and tests).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Trajectory {
    /// Segments in time order (dwells are gaps between them).
    pub segments: Vec<Segment>,
    /// Total time, s.
    pub duration_s: f64,
}

impl Trajectory {
    /// Plans a G-code job.
    pub fn from_gcode(input: &[u8], limits: MotionLimits) -> Result<Trajectory, ReadError> {
        let mut segments = Vec::new();
        let totals = plan_gcode(input, limits, &mut |s| segments.push(s), &mut |_, _, _| {})?;
        Ok(Trajectory {
            segments,
            duration_s: totals.time_s,
        })
    }

    /// Index of the segment active at `t_s` (the last one starting at or before it).
    pub fn segment_at(&self, t_s: f64) -> Option<usize> {
        if self.segments.is_empty() {
            return None;
        }
        let i = self.segments.partition_point(|s| s.t_start_s <= t_s);
        Some(i.saturating_sub(1))
    }

    /// Position at `t_s` (start before 0, end after the end).
    pub fn position_at(&self, t_s: f64) -> Option<Pos4> {
        let i = self.segment_at(t_s)?;
        self.segments.get(i).map(|s| s.position_at(t_s))
    }

    /// Samples every `period_s` from 0 to the end: (time, position, segment index).
    pub fn sample(&self, period_s: f64) -> impl Iterator<Item = (f64, Pos4, usize)> + '_ {
        let period = if period_s.is_finite() && period_s > 0.0 {
            period_s
        } else {
            0.1
        };
        let n = (self.duration_s / period).floor() as usize + 1;
        let mut idx = 0usize;
        (0..n).filter_map(move |k| {
            let t = k as f64 * period;
            while idx + 1 < self.segments.len() && self.segments[idx + 1].t_start_s <= t {
                idx += 1;
            }
            self.segments.get(idx).map(|s| (t, s.position_at(t), idx))
        })
    }
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
