//! Printability checks before writing, each with the step index and the place:
//! - **outside the bed** (or below 0 / above the build height), and extruding strings below
//!   `min_z_mm` (a first layer at Z0 would press the nozzle into the bed);
//! - **unsupported**: a point of a string (every `sample_mm` along it, not only its ends: a
//!   bridge onto a pillar is caught in the middle) with nothing printed below it within
//!   `support_radius_mm` (the turtle paper's "cannot print in the air");
//! - **widening too fast**: at a string's end, the supporting material is offset sideways by
//!   more than half the string's width (width ≈ cross-section ÷ vertical gap) plus half the
//!   sample spacing (the nearest sample may lie that far from the supporting string's
//!   nearest point), so the wall cannot stack (the paper's collapsing cylinder);
//! - **travel crosses printed material** at or above the nozzle's height;
//! - **flow above the profile's maximum** (cross-section × speed).
//!
//! Printed material is indexed in a uniform grid ([`crate::design::checks::grid`]): points sampled
//! along the strings in cubic cells of the support radius, with the highest point per XY
//! column for the travel check; every query touches a fixed handful of cells, so the checks
//! cost about as much as writing the G-code.

mod grid;

use crate::design::model::{Model, Step, Str};
use crate::design::profile::Profile;
use glam::DVec3;
use grid::Grid;

/// Check parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CheckOptions {
    /// Strings whose end lies at most this far above the design's lowest point rest on the
    /// bed, mm.
    pub bed_contact_mm: f64,
    /// A point below must be at least this much lower to count as support, mm.
    pub min_drop_mm: f64,
    /// Farthest distance to a supporting point, mm.
    pub support_radius_mm: f64,
    /// Spacing of the sample points of printed strings, mm.
    pub sample_mm: f64,
    /// Half-width of the nozzle for travel checks, mm.
    pub nozzle_radius_mm: f64,
    /// Material lower than the travel by more than this is not hit, mm.
    pub travel_clearance_mm: f64,
    /// Issues listed per kind (all are counted).
    pub max_listed: usize,
    /// Lowest height of an extruding string, mm: below it the nozzle presses into the bed.
    pub min_z_mm: f64,
}

impl Default for CheckOptions {
    fn default() -> Self {
        CheckOptions {
            bed_contact_mm: 0.6,
            min_drop_mm: 0.05,
            support_radius_mm: 1.2,
            sample_mm: 0.5,
            nozzle_radius_mm: 0.3,
            travel_clearance_mm: 0.1,
            max_listed: 10,
            min_z_mm: 0.05,
        }
    }
}

/// Kind of printability issue.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum IssueKind {
    /// Outside the build volume.
    OutsideBed,
    /// Nothing below to rest on.
    Unsupported,
    /// Offset from the string below beyond half the string's width.
    WideningTooFast,
    /// A travel passes through printed material.
    TravelCrossesPrint,
    /// Volumetric flow above the profile's maximum.
    FlowTooHigh,
}

impl IssueKind {
    /// Short name.
    pub fn name(&self) -> &'static str {
        match self {
            IssueKind::OutsideBed => "outside-bed",
            IssueKind::Unsupported => "unsupported",
            IssueKind::WideningTooFast => "widening-too-fast",
            IssueKind::TravelCrossesPrint => "travel-crosses-print",
            IssueKind::FlowTooHigh => "flow-too-high",
        }
    }
}

/// One issue.
#[derive(Clone, Debug, PartialEq)]
pub struct Issue {
    /// Kind.
    pub kind: IssueKind,
    /// Index in `model.steps`.
    pub step: usize,
    /// Where, mm.
    pub at: DVec3,
    /// Explanation.
    pub msg: String,
}

/// All issues found.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CheckReport {
    /// The first `max_listed` issues of each kind.
    pub issues: Vec<Issue>,
    /// Total per kind, in [`IssueKind`] order.
    pub counts: [usize; 5],
}

impl CheckReport {
    /// True when nothing was found.
    pub fn is_clean(&self) -> bool {
        self.counts.iter().all(|c| *c == 0)
    }

    /// Total number of issues.
    pub fn total(&self) -> usize {
        self.counts.iter().sum()
    }

    /// Count of one kind.
    pub fn count(&self, kind: IssueKind) -> usize {
        self.counts[kind as usize]
    }

    fn add(&mut self, max: usize, issue: Issue) {
        let k = issue.kind as usize;
        self.counts[k] += 1;
        if self.counts[k] <= max {
            self.issues.push(issue);
        }
    }
}

/// Runs every check on `model` for `profile`.
pub fn check(model: &Model, profile: &Profile, o: &CheckOptions) -> CheckReport {
    check_with::<Grid>(model, profile, o)
}

/// What the checks ask of the printed material: the design's sample points in print order,
/// of which a growing prefix is printed ([`Grid`]; in the tests also a plain scan, the
/// reference the grid must agree with).
pub(crate) trait Printed {
    /// The index over `points` (every sample point, in print order), none printed yet;
    /// `cell_mm` is a size hint.
    fn build(cell_mm: f64, points: Vec<[f64; 3]>) -> Self;
    /// Point `i` in print order.
    fn point(&self, i: usize) -> [f64; 3];
    /// Marks the points before `end` as printed.
    fn print_through(&mut self, end: usize);
    /// The nearest printed point within `sqrt(r2)` of `q` with z ≤ `max_z`, ties to the
    /// earliest printed.
    fn nearest_below(&mut self, q: [f64; 3], r2: f64, max_z: f64) -> Option<[f64; 3]>;
    /// True when [`Printed::nearest_below`] would find a point.
    fn any_below(&mut self, q: [f64; 3], r2: f64, max_z: f64) -> bool;
    /// True when a printed point lies in the XY box `lo..=hi` at height `min_z` or above.
    fn any_at_or_above(&self, lo: [f64; 2], hi: [f64; 2], min_z: f64) -> bool;
}

impl Printed for Grid {
    fn build(cell_mm: f64, points: Vec<[f64; 3]>) -> Self {
        Grid::build(cell_mm, points)
    }
    fn point(&self, i: usize) -> [f64; 3] {
        Grid::point(self, i)
    }
    fn print_through(&mut self, end: usize) {
        Grid::print_through(self, end)
    }
    fn nearest_below(&mut self, q: [f64; 3], r2: f64, max_z: f64) -> Option<[f64; 3]> {
        Grid::nearest_below(self, q, r2, max_z)
    }
    fn any_below(&mut self, q: [f64; 3], r2: f64, max_z: f64) -> bool {
        Grid::any_below(self, q, r2, max_z)
    }
    fn any_at_or_above(&self, lo: [f64; 2], hi: [f64; 2], min_z: f64) -> bool {
        Grid::any_at_or_above(self, lo, hi, min_z)
    }
}

/// Number of sample points of an extruded string: one every `sample_mm` (at least one, at
/// most 10,000), the last at its end.
fn sample_count(s: &Str, o: &CheckOptions) -> usize {
    // ceil(x) without the libm call (x86-64 without SSE4.1 has no rounding instruction):
    // the same count for every x, NaN and infinities included.
    let x = s.len_mm() / o.sample_mm;
    let t = x as usize;
    let n = if (t as f64) < x {
        t.saturating_add(1)
    } else {
        t
    };
    n.clamp(1, 10_000)
}

/// [`check`] with the printed material in `P`.
pub(crate) fn check_with<P: Printed>(
    model: &Model,
    profile: &Profile,
    o: &CheckOptions,
) -> CheckReport {
    let mut rep = CheckReport::default();
    let b = &profile.bed;
    let max_flow = profile.limits.max_volumetric_mm3_s;
    let inside = |p: DVec3| {
        p.x >= b.x_min_mm - 1e-9
            && p.x <= b.x_max_mm + 1e-9
            && p.y >= b.y_min_mm - 1e-9
            && p.y <= b.y_max_mm + 1e-9
            && p.z >= -1e-9
            && p.z <= b.z_max_mm + 1e-9
    };
    // Every sample point of every extruded string, in print order: the points the support
    // check asks about and, once their string is checked, printed material.
    // Also the number of points of each extruded string, in order, and the lowest z of the
    // design (`model.bbox().min.z`, in the same pass: one read of a large model less).
    let mut points = Vec::with_capacity(model.steps.len());
    let mut counts = Vec::with_capacity(model.steps.len());
    let mut min_z = f64::INFINITY;
    let mut lower = |z: f64| min_z = if min_z < z { min_z } else { z }; // as `BBox::add`
    for step in &model.steps {
        match step {
            Step::String(s) => {
                lower(s.start.z);
                lower(s.end.z);
                if s.cross_mm2 > 0.0 {
                    let n = sample_count(s, o);
                    points.extend(
                        (1..=n).map(|k| s.start.lerp(s.end, k as f64 / n as f64).to_array()),
                    );
                    counts.push(n);
                }
            }
            Step::Travel { to, .. } => lower(to.z),
            _ => {}
        }
    }
    let bed_contact_z = if min_z.is_finite() {
        min_z.max(0.0) + o.bed_contact_mm
    } else {
        o.bed_contact_mm
    };
    // Columns as wide as the support radius: measured fastest on the globe (1.2 mm: 8.7 ms,
    // 0.6 mm: 9.4 ms, 0.4 mm: 12.9 ms; narrower columns mean more of them per query).
    let mut tree = P::build(o.support_radius_mm.max(o.nozzle_radius_mm).max(0.1), points);
    let mut counts = counts.into_iter();
    let mut printed = 0;
    let mut pos: Option<DVec3> = None;
    let r2 = o.support_radius_mm * o.support_radius_mm;
    for (i, step) in model.steps.iter().enumerate() {
        match step {
            Step::String(s) => {
                if let Some(p) = pos {
                    if p.distance_squared(s.start) > 1e-12 {
                        travel_check(&tree, o, i, p, s.start, &mut rep);
                    }
                }
                for p in [s.start, s.end] {
                    if !inside(p) {
                        rep.add(
                            o.max_listed,
                            Issue {
                                kind: IssueKind::OutsideBed,
                                step: i,
                                at: p,
                                msg: format!(
                                    "({:.2}, {:.2}, {:.2}) is outside the build volume of {}",
                                    p.x, p.y, p.z, profile.name
                                ),
                            },
                        );
                        break;
                    }
                }
                let flow = s.flow_mm3_s();
                if flow > max_flow {
                    rep.add(
                        o.max_listed,
                        Issue {
                            kind: IssueKind::FlowTooHigh,
                            step: i,
                            at: s.end,
                            msg: format!(
                                "flow {flow:.1} mm³/s ({:.3} mm² × {:.1} mm/s) exceeds {max_flow} mm³/s",
                                s.cross_mm2, s.speed_mm_s
                            ),
                        },
                    );
                }
                if s.cross_mm2 > 0.0 {
                    let low = s.start.z.min(s.end.z);
                    if low < o.min_z_mm && low >= -1e-9 {
                        let at = if s.start.z <= s.end.z { s.start } else { s.end };
                        rep.add(
                            o.max_listed,
                            Issue {
                                kind: IssueKind::OutsideBed,
                                step: i,
                                at,
                                msg: format!(
                                    "extruding at z {:.3} mm, below {} mm: the nozzle would press into the bed (a first layer needs z ≈ its height)",
                                    at.z, o.min_z_mm
                                ),
                            },
                        );
                    }
                    // Support at every sample point along the string (its start is the
                    // previous string's end, already checked), then the string is printed
                    // (after the check: it cannot support itself).
                    let n = counts.next().unwrap_or(0);
                    for k in 0..n {
                        let q = DVec3::from_array(tree.point(printed + k));
                        if q.z > bed_contact_z
                            && !support_check(
                                &mut tree,
                                o,
                                r2,
                                i,
                                q,
                                s.cross_mm2,
                                k + 1 == n,
                                &mut rep,
                            )
                        {
                            break;
                        }
                    }
                    printed += n;
                    tree.print_through(printed);
                }
                pos = Some(s.end);
            }
            Step::Travel { to, .. } => {
                if !inside(*to) {
                    rep.add(
                        o.max_listed,
                        Issue {
                            kind: IssueKind::OutsideBed,
                            step: i,
                            at: *to,
                            msg: format!(
                                "travel to ({:.2}, {:.2}, {:.2}) leaves the build volume",
                                to.x, to.y, to.z
                            ),
                        },
                    );
                }
                if let Some(p) = pos {
                    travel_check(&tree, o, i, p, *to, &mut rep);
                }
                pos = Some(*to);
            }
            _ => {}
        }
    }
    rep
}

/// Checks that `q` rests on printed material (and, at a string's `end`, that it does not
/// widen too fast); false when an issue was reported (the rest of the string is not checked).
#[allow(clippy::too_many_arguments)]
fn support_check<P: Printed>(
    tree: &mut P,
    o: &CheckOptions,
    r2: f64,
    i: usize,
    q: DVec3,
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
            rep.add(
            o.max_listed,
            Issue {
                kind: IssueKind::Unsupported,
                step: i,
                at: q,
                        msg: format!(
                            "nothing printed within {} mm below ({:.2}, {:.2}, {:.2}): printing in the air",
                            o.support_radius_mm, q.x, q.y, q.z
                        ),
                    },
            );
            false
        }
        Some(_) if !end => true,
        Some(p) => {
            let drop = q.z - p[2];
            let side = ((q.x - p[0]).powi(2) + (q.y - p[1]).powi(2)).sqrt();
            let width = cross / drop.max(0.05);
            let allowance = o.sample_mm * 0.5;
            if side > 0.5 * width + allowance {
                rep.add(
                    o.max_listed,
                    Issue {
                        kind: IssueKind::WideningTooFast,
                        step: i,
                        at: q,
                        msg: format!(
                            "offset {side:.2} mm from the string {drop:.2} mm below exceeds half the string width ({:.2} mm) plus the {allowance:.2} mm sampling allowance",
                            0.5 * width
                        ),
                    },
                );
                return false;
            }
            true
        }
    }
}

fn travel_check<P: Printed>(
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
    for k in 0..=n.min(100_000) {
        let d = skip + (len - 2.0 * skip) * k as f64 / n.max(1) as f64;
        let p = from.lerp(to, d / len);
        if tree.any_at_or_above(
            [p.x - r, p.y - r],
            [p.x + r, p.y + r],
            p.z - o.travel_clearance_mm,
        ) {
            rep.add(
                o.max_listed,
                Issue {
                    kind: IssueKind::TravelCrossesPrint,
                    step: i,
                    at: p,
                    msg: format!(
                        "travel from ({:.2}, {:.2}) to ({:.2}, {:.2}) at z {:.2} passes over printed material (stringing)",
                        from.x, from.y, to.x, to.y, p.z
                    ),
                },
            );
            return;
        }
    }
}

#[cfg(test)]
mod scan;
#[cfg(test)]
mod tests;
