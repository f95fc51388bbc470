//! G2/G3 arcs cut into straight moves, without allocation.
//!
//! Number of segments: the fewest whose chord deviates from the arc by at most
//! [`ARC_CHORD_TOLERANCE_MM`], but no segment shorter than [`ARC_MIN_SEGMENT_MM`] (small arcs
//! stay a few moves) and never more than [`ARC_MAX_SEGMENTS`] (a huge arc then deviates more, by
//! `r·(1 − cos(sweep / 2n))`). Every segment end is computed from the arc parameters and rounded
//! to steps on its own, and the last one is exactly the commanded end point, so nothing drifts.
//! Z (helix) and E move linearly with the angle. An end point slightly off the circle (text
//! rounding) is absorbed by letting the radius change linearly along the arc.
//!
//! `P<n>` (Marlin's `ARC_P_CIRCLES`, `Marlin/src/gcode/motion/G2_G3.cpp`): n complete circles
//! before the arc, so the sweep gains n·360° in the arc's direction (a full circle, end = start,
//! is 360° and becomes (n + 1)·360°); Z and E are shared out in proportion to the angle, as
//! Marlin's per-circle share `360° / total` does. n ≤ [`ARC_MAX_CIRCLES`], Marlin's bound. The
//! segment cap stays [`ARC_MAX_SEGMENTS`] for the whole sweep, so neither the work per arc nor
//! its bounds check grows with n (many turns of a large circle then deviate more, by the
//! formula above).

use super::{check_axis, MachineError};
use crate::config::MachineConfig;
use crate::motion::{Axis, MoveRequest, AXES};
use core::f64::consts::{PI, TAU};

/// Largest distance, mm, between the true arc and the straight segments that replace it.
pub const ARC_CHORD_TOLERANCE_MM: f64 = 0.005;

/// Shortest segment, mm (unless the whole arc is shorter).
pub const ARC_MIN_SEGMENT_MM: f64 = 0.1;

/// Most segments per arc.
pub const ARC_MAX_SEGMENTS: u32 = 2048;

/// Most extra circles of `G2`/`G3 P<n>`: the bound the G-code reader enforces.
pub use crate::gcode::ARC_MAX_CIRCLES;

/// How far, mm, the end point's distance from the centre may differ from the start point's
/// before the arc is refused (plus 2 % of the radius).
const RADIUS_MISMATCH_MM: f64 = 0.05;

/// How the centre was given.
#[derive(Clone, Copy, Debug)]
pub(super) enum Centre {
    /// I/J: offset from the start point, mm.
    Offset([f64; 2]),
    /// R: radius, mm; negative = the arc longer than half a circle.
    Radius(f64),
}

/// A validated arc in the XY plane.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Plan {
    centre: [f64; 2],
    a0: f64,
    sweep: f64,
    r0: f64,
    r1: f64,
    n: u32,
}

/// Work out centre, angles and segment count; refuse impossible arcs.
pub(super) fn plan(
    start: &[f64; AXES],
    end: &[f64; AXES],
    centre: Centre,
    clockwise: bool,
    circles: u8,
) -> Result<Plan, MachineError> {
    let (sx, sy, ex, ey) = (start[0], start[1], end[0], end[1]);
    let c = match centre {
        Centre::Offset([i, j]) => [sx + i, sy + j],
        Centre::Radius(r) => {
            let (dx, dy) = (ex - sx, ey - sy);
            let d = libm::sqrt(dx * dx + dy * dy);
            if d < 1e-9 || r.abs() < 1e-9 {
                return Err(MachineError::ArcDegenerate);
            }
            let h2 = r * r - d * d / 4.0;
            let h = if h2 >= 0.0 {
                libm::sqrt(h2)
            } else if -h2 <= (RADIUS_MISMATCH_MM * r.abs()).max(1e-9) {
                0.0
            } else {
                return Err(MachineError::ArcEndNotOnCircle);
            };
            // Counter-clockwise with R > 0 (the short arc): centre left of start→end.
            let left = !clockwise ^ (r < 0.0);
            let s = if left { h / d } else { -h / d };
            [(sx + ex) / 2.0 - dy * s, (sy + ey) / 2.0 + dx * s]
        }
    };
    let r0 = libm::hypot(sx - c[0], sy - c[1]);
    let r1 = libm::hypot(ex - c[0], ey - c[1]);
    if r0 < 1e-6 {
        return Err(MachineError::ArcDegenerate);
    }
    if (r1 - r0).abs() > RADIUS_MISMATCH_MM + 0.02 * r0 {
        return Err(MachineError::ArcEndNotOnCircle);
    }
    let a0 = libm::atan2(sy - c[1], sx - c[0]);
    let a1 = libm::atan2(ey - c[1], ex - c[0]);
    let mut sweep = a1 - a0;
    // Equal angles mean a full circle (only possible with I/J).
    if clockwise {
        if sweep >= -1e-12 {
            sweep -= TAU;
        }
    } else if sweep <= 1e-12 {
        sweep += TAU;
    }
    // P: whole turns more, the same way round.
    sweep += sweep.signum() * TAU * f64::from(circles);
    let rmax = r0.max(r1);
    let len = sweep.abs() * rmax;
    let per_seg = if rmax > ARC_CHORD_TOLERANCE_MM {
        2.0 * libm::acos(1.0 - ARC_CHORD_TOLERANCE_MM / rmax)
    } else {
        PI
    };
    let by_tolerance = libm::ceil(sweep.abs() / per_seg);
    let by_length = libm::floor(len / ARC_MIN_SEGMENT_MM).max(1.0);
    let n = by_tolerance
        .min(by_length)
        .clamp(1.0, f64::from(ARC_MAX_SEGMENTS)) as u32;
    Ok(Plan {
        centre: c,
        a0,
        sweep,
        r0,
        r1,
        n,
    })
}

/// The straight moves of one arc, in order: an iterator of [`MoveRequest`] (no allocation).
/// Each segment has its own sequence number; the last ends exactly at the commanded end point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ArcMoves {
    plan: Plan,
    start: [f64; AXES],
    end: [f64; AXES],
    steps_per_mm: [f64; AXES],
    feed_mm_s: f32,
    seq0: u32,
    next: u32,
}

impl ArcMoves {
    pub(super) fn new(
        plan: Plan,
        start: [f64; AXES],
        end: [f64; AXES],
        seq0: u32,
        feed_mm_s: f32,
        cfg: &MachineConfig,
    ) -> Self {
        let mut spm = [0.0; AXES];
        for axis in Axis::ALL {
            spm[axis.index()] = f64::from(cfg.axis(axis).steps_per_mm);
        }
        ArcMoves {
            plan,
            start,
            end,
            steps_per_mm: spm,
            feed_mm_s,
            seq0,
            next: 1,
        }
    }

    /// Number of segments in total.
    pub fn segments(&self) -> u32 {
        self.plan.n
    }

    /// Every point the arc runs through lies in the build volume: each segment end, as
    /// [`Iterator::next`] computes it (the segments between them are straight, and the volume
    /// is a box, so they stay inside too). Checking only the circle's extremes is not enough:
    /// the radius changes along the arc when the end point is slightly off the circle, and the
    /// points between two inside ends can bulge out (issue 16: `G20`, `G3 X3 J200 I4`). Costs
    /// one `sincos` per segment (at most [`ARC_MAX_SEGMENTS`]), once per arc.
    pub(super) fn check_bounds(&self, cfg: &MachineConfig) -> Result<(), MachineError> {
        for k in 1..=self.plan.n {
            let p = self.point(k);
            for axis in [Axis::X, Axis::Y, Axis::Z] {
                check_axis(axis, p[axis.index()], cfg)
                    .map_err(|_| MachineError::ArcOutOfBounds(axis))?;
            }
        }
        Ok(())
    }

    /// Segments not yet returned.
    pub fn remaining(&self) -> u32 {
        (self.plan.n + 1).saturating_sub(self.next)
    }

    /// Position (mm) at the end of segment `k` (1..=n).
    fn point(&self, k: u32) -> [f64; AXES] {
        if k >= self.plan.n {
            return self.end;
        }
        let t = f64::from(k) / f64::from(self.plan.n);
        let p = &self.plan;
        let a = p.a0 + p.sweep * t;
        let r = p.r0 + (p.r1 - p.r0) * t;
        let (s, c) = libm::sincos(a);
        [
            p.centre[0] + r * c,
            p.centre[1] + r * s,
            self.start[2] + (self.end[2] - self.start[2]) * t,
            self.start[3] + (self.end[3] - self.start[3]) * t,
        ]
    }
}

impl Iterator for ArcMoves {
    type Item = MoveRequest;

    fn next(&mut self) -> Option<MoveRequest> {
        if self.next > self.plan.n {
            return None;
        }
        let k = self.next;
        self.next += 1;
        let p = self.point(k);
        let mut target = [0i32; AXES];
        for ((t, mm), spm) in target.iter_mut().zip(p).zip(self.steps_per_mm) {
            // Validated: the end point fits i32 steps and every point lies in the build
            // volume's box, so the cast cannot saturate in practice; `as` saturates anyway.
            *t = libm::round(mm * spm) as i32;
        }
        Some(MoveRequest {
            target,
            feed_mm_s: self.feed_mm_s,
            seq: self.seq0.saturating_add(k - 1),
        })
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        let r = self.remaining() as usize;
        (r, Some(r))
    }
}
