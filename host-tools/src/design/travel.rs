//! Travel that never drives through printed material: a coarse height map of what has been
//! printed so far and a route that lifts (Z-hop) straight up, crosses above everything printed
//! under the way, and descends straight onto the target.
//!
//! The map holds, per square cell of [`CELL_MM`], the highest Z of any string passing within
//! one cell of it, so a route's corridor is at least one cell (2 mm) wide on each side: wider
//! than any nozzle tip. Filling is lazy and incremental (a [`HeightMap`] remembers how many
//! steps of a model it has seen), so designs that never travel pay nothing.
//!
//! Used by the turtle's `pop` and the script's `travel_to` (and, with the same rule over the
//! whole model, by [`crate::design::model::Model::assemble`] and the additive job's approach).
//! The one case it cannot help: a target that lies *under* printed material (then the descent
//! passes through it); the designer's order decides that.

use crate::design::model::{Model, Step};
use glam::DVec3;
use std::collections::HashMap;

/// Side of a height-map cell, mm.
pub const CELL_MM: f64 = 2.0;
/// How far above printed material (and above both ends) a travel crosses, mm.
pub const TRAVEL_CLEARANCE_MM: f64 = 1.0;
/// A straight travel must pass this far above printed material, mm (the printability
/// check's `travel_clearance_mm`).
pub const STRAIGHT_CLEARANCE_MM: f64 = 0.1;
/// Length at each end of a travel where printed material does not count, mm (the check's).
pub const END_SKIP_MM: f64 = 1.0;
/// Cells a single segment may mark or probe; longer segments are probed at coarser steps
/// bounded by this (a travel across a 300 mm bed needs 150).
const MAX_SAMPLES: usize = 100_000;

/// Highest printed Z per XY cell.
#[derive(Clone, Debug, Default)]
pub struct HeightMap {
    cells: HashMap<(i64, i64), f64>,
    /// Steps of the model already entered.
    seen: usize,
}

fn cell_of(x: f64, y: f64) -> (i64, i64) {
    // Saturating casts: a point at 1e300 lands in an edge cell, never overflows.
    ((x / CELL_MM).floor() as i64, (y / CELL_MM).floor() as i64)
}

/// Points every half cell along `a`→`b` (ends included), at most [`MAX_SAMPLES`].
fn samples(a: DVec3, b: DVec3) -> impl Iterator<Item = DVec3> {
    let len = a.truncate().distance(b.truncate());
    let n = ((len / (CELL_MM / 2.0)).ceil() as usize).clamp(1, MAX_SAMPLES);
    (0..=n).map(move |k| a.lerp(b, k as f64 / n as f64))
}

impl HeightMap {
    /// An empty map.
    pub fn new() -> Self {
        Self::default()
    }

    /// Marks the cells within one cell of the segment `a`→`b` with its highest Z.
    pub fn add_segment(&mut self, a: DVec3, b: DVec3) {
        if !(a.is_finite() && b.is_finite()) {
            return;
        }
        let top = a.z.max(b.z);
        for p in samples(a, b) {
            let (cx, cy) = cell_of(p.x, p.y);
            for dx in -1..=1 {
                for dy in -1..=1 {
                    let h = self
                        .cells
                        .entry((cx.saturating_add(dx), cy.saturating_add(dy)))
                        .or_insert(f64::NEG_INFINITY);
                    *h = h.max(top);
                }
            }
        }
    }

    /// Enters the strings of `model.steps[seen..]` (arcs as chords within half a millimetre
    /// of the arc).
    pub fn catch_up(&mut self, model: &Model) {
        for s in model.steps.iter().skip(self.seen) {
            if let Step::String(s) = s {
                match s.arc {
                    None => self.add_segment(s.start, s.end),
                    Some(_) => {
                        for piece in crate::design::model::arc_to_lines(s, CELL_MM / 4.0) {
                            self.add_segment(piece.start, piece.end);
                        }
                    }
                }
            }
        }
        self.seen = model.steps.len();
    }

    /// Highest printed Z in the corridor along `a`→`b` (XY only), or `None` when nothing
    /// was printed there.
    pub fn max_along(&self, a: DVec3, b: DVec3) -> Option<f64> {
        samples(a, b)
            .filter_map(|p| {
                let c = cell_of(p.x, p.y);
                self.cells.get(&c).copied()
            })
            .reduce(f64::max)
    }

    /// True when the straight way from `from` to `to` passes over nothing printed that
    /// reaches within [`STRAIGHT_CLEARANCE_MM`] of the lower end's height, away from the ends
    /// ([`END_SKIP_MM`] along the way: the ends touch the strings they leave and join) — the
    /// rule the printability check applies to travels. A step to the next layer, a short hop
    /// between neighbouring points and a crossing above lower material go straight.
    pub fn clear_straight(&self, from: DVec3, to: DVec3) -> bool {
        let len = from.distance(to);
        if len <= 2.0 * END_SKIP_MM {
            return true;
        }
        let inner = len - 2.0 * END_SKIP_MM;
        let n = ((inner / (CELL_MM / 2.0)).ceil() as usize).clamp(1, MAX_SAMPLES);
        let min_z = from.z.min(to.z) - STRAIGHT_CLEARANCE_MM;
        (0..=n).all(|k| {
            let p = from.lerp(to, (END_SKIP_MM + inner * k as f64 / n as f64) / len);
            self.cells
                .get(&cell_of(p.x, p.y))
                .is_none_or(|h| *h < min_z)
        })
    }

    /// The route from `from` to `to`: straight when nothing printed is in the way
    /// ([`HeightMap::clear_straight`]), else up to [`TRAVEL_CLEARANCE_MM`] above the higher end
    /// and above everything printed in the corridor, across, down onto `to`. Returns the
    /// points to travel to, `to` last; empty when `from == to`.
    pub fn route(&self, from: DVec3, to: DVec3) -> Vec<DVec3> {
        if from == to {
            return Vec::new();
        }
        if self.clear_straight(from, to) {
            return vec![to];
        }
        let top = self.max_along(from, to).unwrap_or(f64::NEG_INFINITY);
        let safe_z = top.max(from.z).max(to.z) + TRAVEL_CLEARANCE_MM;
        let mut out = Vec::with_capacity(3);
        for p in [
            DVec3::new(from.x, from.y, safe_z),
            DVec3::new(to.x, to.y, safe_z),
            to,
        ] {
            if out.last() != Some(&p) && p != from {
                out.push(p);
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::design::model::Str;

    #[test]
    fn route_clears_printed_strings_in_the_corridor_only() {
        let mut m = Model::new([0.0, 0.0]);
        // A 5 mm wall at x = 10, y = −5..5.
        for k in 1..=25 {
            let z = 0.2 * k as f64;
            m.push(Step::String(Str::line(
                DVec3::new(10.0, -5.0, z),
                DVec3::new(10.0, 5.0, z),
                0.2,
                20.0,
            )));
        }
        let mut map = HeightMap::new();
        map.catch_up(&m);
        let r = map.route(DVec3::new(0.0, 0.0, 0.2), DVec3::new(20.0, 0.0, 0.2));
        assert_eq!(r.len(), 3);
        assert!((r[0].z - 6.0).abs() < 1e-9, "{r:?}");
        // A travel that passes far from the wall goes straight (it used to hop 1 mm).
        let r = map.route(DVec3::new(0.0, 20.0, 0.2), DVec3::new(20.0, 20.0, 0.2));
        assert_eq!(r, [DVec3::new(20.0, 20.0, 0.2)]);
        // The step from the wall's top to the next layer above it: straight.
        let top = DVec3::new(10.0, 5.0, 5.0);
        assert_eq!(map.route(top, top + DVec3::Z * 0.2), [top + DVec3::Z * 0.2]);
        // Along the wall's top at its own height: over printed material, so it lifts.
        let r = map.route(DVec3::new(10.0, -5.0, 5.0), DVec3::new(10.0, 5.0, 5.0));
        assert_eq!(r.len(), 3, "{r:?}");
        // Across the wall one layer above it: clear by the layer height, straight.
        let r = map.route(DVec3::new(0.0, 0.0, 5.2), DVec3::new(20.0, 0.0, 5.2));
        assert_eq!(r.len(), 1, "{r:?}");
        assert!(map.route(DVec3::ONE, DVec3::ONE).is_empty());
        // Non-finite strings are ignored, huge ones saturate.
        map.add_segment(DVec3::splat(f64::NAN), DVec3::ZERO);
        map.add_segment(DVec3::splat(-1e300), DVec3::splat(1e300));
    }
}
