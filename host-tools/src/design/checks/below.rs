//! The checks made at each point of the print against the material printed before it:
//! support, widening, line width (the bead's thickness over what it rests on) and travels
//! over printed material. [`super::check_with`] walks the design and asks these.

use super::{CheckOptions, CheckReport, IssueKind, Printed};
use glam::DVec3;

/// Path length added between lines (after a travel), so that no point of an earlier line is
/// within a trail's length of a later one, mm.
pub(super) const RUN_GAP_MM: f64 = 1e3;

/// What the support and width checks need besides the index: where each printed piece
/// starts, how far along the print each point is, and the nozzle.
pub(super) struct Below<'a> {
    pub(super) from_xy: &'a [[f64; 2]],
    pub(super) along_mm: &'a [f64],
    /// A point printed less than this far back along the same line is the bead leading into
    /// the point asked about, not something it rests on, mm.
    pub(super) trail_mm: f64,
    pub(super) nozzle_mm: f64,
}

impl Below<'_> {
    /// True when printed point `k` is the line leading into point `qi` (the last `trail_mm`
    /// of it): on a ramp that rises more than `min_drop_mm` within the support radius, the
    /// nearest point below is the line's own trail, a fraction of a millimetre behind and
    /// below — a distance that says nothing of the bead's thickness (FullControl's
    /// nonplanar spacer, whose rings climb their waves, was flagged 2–3× too wide on
    /// ≈ 1,100 strings by it).
    fn is_trail(&self, k: usize, qi: usize) -> bool {
        match (self.along_mm.get(k), self.along_mm.get(qi)) {
            (Some(a), Some(b)) => b - a < self.trail_mm,
            _ => false,
        }
    }

    /// Distances from `q` to the printed path through sample `k` (the pieces ending at `k`
    /// and, when printed and joined, at `k + 1`): `(side, thickness)` — in XY (the widening's
    /// offset) and in 3D (the bead's thickness over the string it rests on; not the drop to
    /// the sample combined with the side to the path: on a wavy layer below, those are two
    /// different places, the spacer's rings measured 0.32 mm that way, 0.42 mm to the path).
    /// One pass over the same pieces for both.
    fn side_and_thickness<P: Printed>(&self, tree: &P, k: usize, q: DVec3) -> (f64, f64) {
        let p = tree.point(k);
        let pv = DVec3::from_array(p);
        let from = self.from_xy.get(k).copied().unwrap_or([p[0], p[1]]);
        let mut side = seg_dist_xy(q, from, p);
        // The piece ending at `k` starts at sample `k - 1` unless `k` is a line's first point.
        let prev = k.checked_sub(1).map(|i| tree.point(i));
        let mut thick = match prev {
            Some(a) if [a[0], a[1]] == from => seg_dist(q, DVec3::from_array(a), pv),
            _ => q.distance(pv),
        };
        if let Some(next_from) = self.from_xy.get(k + 1) {
            if *next_from == [p[0], p[1]] && k + 1 < tree.printed() {
                let n = tree.point(k + 1);
                side = side.min(seg_dist_xy(q, [p[0], p[1]], n));
                thick = thick.min(seg_dist(q, pv, DVec3::from_array(n)));
            }
        }
        (side, thick)
    }

    /// [`Below::side_and_thickness`]'s thickness alone.
    fn thickness_mm<P: Printed>(&self, tree: &P, k: usize, q: DVec3) -> f64 {
        self.side_and_thickness(tree, k, q).1
    }

    /// Flags a line laid `height` mm thick whose width is outside the sane range.
    #[allow(clippy::too_many_arguments)]
    fn width_check(
        &self,
        o: &CheckOptions,
        i: usize,
        q: DVec3,
        cross: f64,
        height: f64,
        on_bed: bool,
        rep: &mut CheckReport,
    ) {
        let over = if on_bed {
            "above the bed"
        } else {
            "over the string below"
        };
        let w = cross / height.max(1e-3);
        let ratio = w / self.nozzle_mm;
        // A bead farther than a nozzle from the string it rests on does not touch it: its
        // width is unknown there (the support check judges it), so only "too wide" is asked.
        let narrow_known = on_bed || height <= self.nozzle_mm;
        let max = if on_bed {
            o.max_first_width_ratio
        } else {
            o.max_width_ratio
        };
        if ratio > max + 1e-9 || (narrow_known && ratio < o.min_width_ratio - 1e-9) {
            rep.add(o.max_listed, IssueKind::LineWidth, i, q, || format!(
                        "line {w:.2} mm wide ({cross:.3} mm² laid {height:.2} mm thick {over}) is {ratio:.2}× the {} mm nozzle, outside {}–{max}× (set the width and height with set_extrusion)",
                        self.nozzle_mm, o.min_width_ratio
                    ));
        }
    }
}

/// Distance from `q` to the segment `a`–`b`.
fn seg_dist(q: DVec3, a: DVec3, b: DVec3) -> f64 {
    let ab = b - a;
    let l2 = ab.length_squared();
    let t = if l2 > 0.0 {
        ((q - a).dot(ab) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    q.distance(a + ab * t)
}

/// XY distance from `q` to the segment `a`–`b`: [`seg_dist`] with all three at Z 0 (a zero
/// Z adds exactly nothing to any sum, so this is the 2D distance to the bit).
fn seg_dist_xy(q: DVec3, a: [f64; 2], b: [f64; 3]) -> f64 {
    seg_dist(
        q.with_z(0.0),
        DVec3::new(a[0], a[1], 0.0),
        DVec3::new(b[0], b[1], 0.0),
    )
}

/// The width of a string's end near the bed: over the string below when there is one, else
/// over the bed.
#[allow(clippy::too_many_arguments)]
pub(super) fn bed_width_check<P: Printed>(
    tree: &mut P,
    below: &Below,
    o: &CheckOptions,
    r2: f64,
    i: usize,
    (qi, q): (usize, DVec3),
    cross: f64,
    rep: &mut CheckReport,
) {
    match tree.nearest_below(q.to_array(), r2, q.z - o.min_drop_mm) {
        Some(k) if below.is_trail(k, qi) => {} // resting on what, unknown: not judged
        Some(k) => {
            let t = below.thickness_mm(tree, k, q);
            below.width_check(o, i, q, cross, t, false, rep)
        }
        None => below.width_check(o, i, q, cross, q.z, true, rep),
    }
}

/// Checks that `q` rests on printed material (and, at a string's `end`, that it does not
/// widen too fast and its width is sane); false when an issue was reported (the rest of the
/// string is not checked).
#[allow(clippy::too_many_arguments)]
pub(super) fn support_check<P: Printed>(
    tree: &mut P,
    below: &Below,
    o: &CheckOptions,
    r2: f64,
    i: usize,
    (qi, q): (usize, DVec3),
    cross: f64,
    end: bool,
    rep: &mut CheckReport,
) -> bool {
    let (qa, max_z) = (q.to_array(), q.z - o.min_drop_mm);
    let found = if end {
        tree.nearest_below(qa, r2, max_z)
    } else if tree.any_below(qa, r2, max_z) {
        return true; // only the end's nearest point matters (widening)
    } else {
        None
    };
    match found {
        None => {
            rep.add(o.max_listed, IssueKind::Unsupported, i, q, || {
                format!(
                    "nothing printed within {} mm below ({:.2}, {:.2}, {:.2}): printing in the air",
                    o.support_radius_mm, q.x, q.y, q.z
                )
            });
            false
        }
        Some(_) if !end => true,
        Some(k) => {
            let drop = q.z - tree.point(k)[2];
            let (side, t) = below.side_and_thickness(tree, k, q);
            let width = cross / drop.max(0.05);
            // The bead's thickness is its distance to the string it rests on: the drop on a
            // vertical wall, more on a leaning one (a dish's strings lie nearly side by side);
            // not judged against the line's own trail.
            if !below.is_trail(k, qi) {
                below.width_check(o, i, q, cross, t, false, rep);
            }
            if side > 0.5 * width + 1e-9 {
                rep.add(o.max_listed, IssueKind::WideningTooFast, i, q, || format!(
                            "offset {side:.2} mm from the string {drop:.2} mm below exceeds half the string width ({:.2} mm): an overhang of {:.0}° from the vertical, beyond atan(w / 2h) = {:.0}°",
                            0.5 * width,
                            side.atan2(drop).to_degrees(),
                            (0.5 * width).atan2(drop).to_degrees()
                        ));
                return false;
            }
            true
        }
    }
}

pub(super) fn travel_check<P: Printed>(
    tree: &P,
    o: &CheckOptions,
    i: usize,
    from: DVec3,
    to: DVec3,
    rep: &mut CheckReport,
) {
    let len = from.distance(to);
    let skip = 1.0; // the ends touch the strings they leave and join
    if len <= 2.0 * skip {
        return;
    }
    let n = ((len - 2.0 * skip) / o.sample_mm).ceil() as usize;
    let r = o.nozzle_radius_mm;
    // Material within the clearance of the nozzle's height is stringing; material standing
    // higher than that is in the nozzle's way: a collision.
    let mut grazes: Option<DVec3> = None;
    for k in 0..=n.min(100_000) {
        let d = skip + (len - 2.0 * skip) * k as f64 / n.max(1) as f64;
        let p = from.lerp(to, d / len);
        let (lo, hi) = ([p.x - r, p.y - r], [p.x + r, p.y + r]);
        if !tree.any_at_or_above(lo, hi, p.z - o.travel_clearance_mm) {
            continue;
        }
        if tree.any_at_or_above(lo, hi, p.z + o.travel_clearance_mm) {
            rep.add(o.max_listed, IssueKind::TravelHitsPrint, i, p, || {
                format!(
                "travel from ({:.2}, {:.2}, {:.2}) to ({:.2}, {:.2}, {:.2}) drives the nozzle into \
                 printed material standing above it at ({:.2}, {:.2}, {:.2}): use travel_to (it \
                 lifts over what is printed) or print in another order",
                from.x, from.y, from.z, to.x, to.y, to.z, p.x, p.y, p.z
            )
            });
            return;
        }
        grazes.get_or_insert(p);
    }
    if let Some(p) = grazes {
        rep.add(o.max_listed, IssueKind::TravelCrossesPrint, i, p, || format!(
            "travel from ({:.2}, {:.2}) to ({:.2}, {:.2}) at z {:.2} passes over printed material (stringing)",
            from.x, from.y, to.x, to.y, p.z
        ));
    }
}
