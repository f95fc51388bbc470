//! Printability checks before writing, each with the step index and the place:
//! - **outside the bed** (or below 0 / above the build height), and extruding strings below
//!   `min_z_mm` (a first layer at Z0 would press the nozzle into the bed);
//! - **unsupported**: a point of a string (every `sample_mm` along it, not only its ends: a
//!   bridge onto a pillar is caught in the middle) with nothing printed below it within
//!   `support_radius_mm` (the turtle paper's "cannot print in the air");
//! - **widening too fast**: at a string's end, the supporting string (the printed path through
//!   the nearest sample below, not the sample itself) is offset sideways by more than half the
//!   string's width (width ≈ cross-section ÷ vertical gap), so the wall cannot stack (the
//!   paper's collapsing cylinder): an overhang is flagged from `atan(w / 2h)` from the
//!   vertical — 45° for lines twice as wide as high;
//! - **travel crosses printed material** at or above the nozzle's height;
//! - **flow above the profile's maximum** (cross-section × speed);
//! - **line width** (cross-section ÷ the bead's thickness: its distance to the string it
//!   rests on, or its height above the bed) outside `min_width_ratio..=max_width_ratio` × the
//!   nozzle;
//! - **cold extrusion**: extruding while the hot end is set below the firmware's extrusion
//!   minimum (a design's temperature or a raw `M104 S0`), and **homing mid-print** (a raw
//!   `G28` after printing started) — raw G-code is followed, see [`machine`].
//!
//! Printed material is indexed once ([`crate::design::checks::grid`]): every point sampled along
//! the strings, in XY columns of the support radius sorted by height, of which a growing prefix
//! in print order is printed; a query starts from the previous answer's successor and touches
//! a handful of columns, so the checks cost less than building and writing the G-code
//! (`cpu_time` example: 0.96–0.98× on the globe, 0.86–0.89× on a 45,000-segment helix).
//! The answers are those of a plain scan over the printed points (`scan.rs` tests them
//! against one).

mod grid;
mod machine;

pub use machine::MIN_EXTRUDE_C;

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
    /// Narrowest line, × the nozzle diameter (cross-section ÷ the height it is laid at).
    pub min_width_ratio: f64,
    /// Widest line, × the nozzle diameter (SuperSlicer's and FullControl's practice: up to
    /// double the nozzle).
    pub max_width_ratio: f64,
    /// Widest line laid on the bed, × the nozzle diameter: first layers are squashed wider
    /// (Kanada's 0.2 mm² helix starts 1 mm wide at 0.2 mm: 2.5×).
    pub max_first_width_ratio: f64,
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
            min_width_ratio: 0.5,
            max_width_ratio: 2.0,
            max_first_width_ratio: 2.5,
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
    /// A line narrower or wider than the nozzle can lay.
    LineWidth,
    /// Extruding with the hot end set below the firmware's extrusion minimum.
    ColdExtrusion,
    /// Raw G-code homes the axes after printing started.
    HomesMidPrint,
}

/// Number of issue kinds.
const KINDS: usize = 8;

impl IssueKind {
    /// Short name.
    pub fn name(&self) -> &'static str {
        match self {
            IssueKind::OutsideBed => "outside-bed",
            IssueKind::Unsupported => "unsupported",
            IssueKind::WideningTooFast => "widening-too-fast",
            IssueKind::TravelCrossesPrint => "travel-crosses-print",
            IssueKind::FlowTooHigh => "flow-too-high",
            IssueKind::LineWidth => "line-width",
            IssueKind::ColdExtrusion => "cold-extrusion",
            IssueKind::HomesMidPrint => "homes-mid-print",
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
    pub counts: [usize; KINDS],
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
    /// The print index of the nearest printed point within `sqrt(r2)` of `q` with
    /// z ≤ `max_z`, ties to the earliest printed.
    fn nearest_below(&mut self, q: [f64; 3], r2: f64, max_z: f64) -> Option<usize>;
    /// True when [`Printed::nearest_below`] would find a point.
    fn any_below(&mut self, q: [f64; 3], r2: f64, max_z: f64) -> bool;
    /// True when a printed point lies in the XY box `lo..=hi` at height `min_z` or above.
    fn any_at_or_above(&self, lo: [f64; 2], hi: [f64; 2], min_z: f64) -> bool;
    /// How many points are printed.
    fn printed(&self) -> usize;
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
    fn nearest_below(&mut self, q: [f64; 3], r2: f64, max_z: f64) -> Option<usize> {
        Grid::nearest_below(self, q, r2, max_z)
    }
    fn any_below(&mut self, q: [f64; 3], r2: f64, max_z: f64) -> bool {
        Grid::any_below(self, q, r2, max_z)
    }
    fn any_at_or_above(&self, lo: [f64; 2], hi: [f64; 2], min_z: f64) -> bool {
        Grid::any_at_or_above(self, lo, hi, min_z)
    }
    fn printed(&self) -> usize {
        Grid::printed(self)
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
    // check asks about and, once their string is checked, printed material. With each, the
    // XY start of the printed piece that ends there (the string's start for its first
    // sample), so the widening check measures against the printed path, not its samples.
    // Also the number of points of each extruded string, in order, and the lowest z of the
    // design (`model.bbox().min.z`, in the same pass: one read of a large model less).
    let mut points = Vec::with_capacity(model.steps.len());
    let mut from_xy: Vec<[f64; 2]> = Vec::with_capacity(model.steps.len());
    // Path length to each point, a new line (after a travel) starting `RUN_GAP_MM` farther:
    // how far back along the line leading into a point another point was printed.
    let mut along_mm: Vec<f64> = Vec::with_capacity(model.steps.len());
    let mut path_mm = 0.0;
    let mut counts = Vec::with_capacity(model.steps.len());
    let mut min_z = f64::INFINITY;
    let mut lower = |z: f64| min_z = if min_z < z { min_z } else { z }; // as `BBox::add`
    let mut last_end: Option<DVec3> = None;
    for step in &model.steps {
        match step {
            Step::String(s) => {
                lower(s.start.z);
                lower(s.end.z);
                if s.cross_mm2 > 0.0 {
                    // A string that does not continue the last one (after a travel) starts
                    // with its start point: material, but not asked about (it is where the
                    // head came down, not something the string lays on something).
                    let lead = usize::from(last_end != Some(s.start));
                    if lead == 1 {
                        points.push(s.start.to_array());
                        from_xy.push([s.start.x, s.start.y]);
                        path_mm += RUN_GAP_MM;
                        along_mm.push(path_mm);
                    }
                    let n = sample_count(s, o);
                    let first = points.len();
                    points.extend(
                        (1..=n).map(|k| s.start.lerp(s.end, k as f64 / n as f64).to_array()),
                    );
                    let len = s.len_mm();
                    along_mm.extend((1..=n).map(|k| path_mm + len * k as f64 / n as f64));
                    path_mm += len;
                    from_xy.push([s.start.x, s.start.y]);
                    from_xy.extend(points[first..points.len() - 1].iter().map(|p| [p[0], p[1]]));
                    counts.push((lead, n));
                    last_end = Some(s.end);
                }
            }
            Step::Travel { to, .. } => {
                lower(to.z);
                last_end = None;
            }
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
    let below = Below {
        from_xy: &from_xy,
        along_mm: &along_mm,
        trail_mm: 2.0 * o.support_radius_mm,
        nozzle_mm: profile.nozzle_diameter_mm,
    };
    let mut machine = machine::Machine::new(&model.steps, profile);
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
                    machine.extrusion(i, s, o, &mut rep);
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
                    // (after the check: it cannot support itself). On the bed, only the
                    // line's width at its end.
                    let (lead, n) = counts.next().unwrap_or((0, 0));
                    printed += lead;
                    for k in 0..n {
                        let qi = printed + k;
                        let q = DVec3::from_array(tree.point(qi));
                        let end = k + 1 == n;
                        if q.z > bed_contact_z {
                            if !support_check(
                                &mut tree,
                                &below,
                                o,
                                r2,
                                i,
                                (qi, q),
                                s.cross_mm2,
                                end,
                                &mut rep,
                            ) {
                                break;
                            }
                        } else if end {
                            bed_width_check(
                                &mut tree,
                                &below,
                                o,
                                r2,
                                i,
                                (qi, q),
                                s.cross_mm2,
                                &mut rep,
                            );
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
            Step::State(sc) => machine.state(i, sc, &mut pos, printed > 0, o, &mut rep),
            _ => {}
        }
    }
    rep
}

/// Path length added between lines (after a travel), so that no point of an earlier line is
/// within a trail's length of a later one, mm.
const RUN_GAP_MM: f64 = 1e3;

/// What the support and width checks need besides the index: where each printed piece
/// starts, how far along the print each point is, and the nozzle.
struct Below<'a> {
    from_xy: &'a [[f64; 2]],
    along_mm: &'a [f64],
    /// A point printed less than this far back along the same line is the bead leading into
    /// the point asked about, not something it rests on, mm.
    trail_mm: f64,
    nozzle_mm: f64,
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

    /// XY distance from `q` to the printed path through sample `k` (the pieces ending at
    /// `k` and, when printed and joined, at `k + 1`).
    fn side_mm<P: Printed>(&self, tree: &P, k: usize, q: DVec3) -> f64 {
        let p = tree.point(k);
        let mut d = seg_dist_xy(q, self.from_xy.get(k).copied().unwrap_or([p[0], p[1]]), p);
        if let Some(next_from) = self.from_xy.get(k + 1) {
            if *next_from == [p[0], p[1]] && k + 1 < tree.printed() {
                d = d.min(seg_dist_xy(q, [p[0], p[1]], tree.point(k + 1)));
            }
        }
        d
    }

    /// Distance from `q` to the printed path through sample `k` (as [`Below::side_mm`], in
    /// 3D): the bead's thickness over the string it rests on. Not the drop to the sample
    /// combined with the side to the path: on a wavy layer below, those are two different
    /// places (the spacer's rings measured 0.32 mm that way, 0.42 mm to the path).
    fn thickness_mm<P: Printed>(&self, tree: &P, k: usize, q: DVec3) -> f64 {
        let p = DVec3::from_array(tree.point(k));
        let joined = |j: usize| {
            // The piece ending at sample `j` starts at sample `j - 1` unless it is a line's
            // first point.
            let prev = j.checked_sub(1).map(|i| tree.point(i));
            match (prev, self.from_xy.get(j)) {
                (Some(a), Some(f)) if [a[0], a[1]] == *f => Some(DVec3::from_array(a)),
                _ => None,
            }
        };
        let mut d = match joined(k) {
            Some(a) => seg_dist(q, a, p),
            None => q.distance(p),
        };
        if k + 1 < tree.printed() && joined(k + 1).is_some() {
            d = d.min(seg_dist(q, p, DVec3::from_array(tree.point(k + 1))));
        }
        d
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
            rep.add(
                o.max_listed,
                Issue {
                    kind: IssueKind::LineWidth,
                    step: i,
                    at: q,
                    msg: format!(
                        "line {w:.2} mm wide ({cross:.3} mm² laid {height:.2} mm thick {over}) is {ratio:.2}× the {} mm nozzle, outside {}–{max}× (set the width and height with set_extrusion)",
                        self.nozzle_mm, o.min_width_ratio
                    ),
                },
            );
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

/// XY distance from `q` to the segment `a`–`b`.
fn seg_dist_xy(q: DVec3, a: [f64; 2], b: [f64; 3]) -> f64 {
    let (a, b, q) = (
        glam::DVec2::from(a),
        glam::DVec2::new(b[0], b[1]),
        q.truncate(),
    );
    let ab = b - a;
    let l2 = ab.length_squared();
    let t = if l2 > 0.0 {
        ((q - a).dot(ab) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    q.distance(a + ab * t)
}

/// The width of a string's end near the bed: over the string below when there is one, else
/// over the bed.
#[allow(clippy::too_many_arguments)]
fn bed_width_check<P: Printed>(
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
fn support_check<P: Printed>(
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
        Some(k) => {
            let drop = q.z - tree.point(k)[2];
            let side = below.side_mm(tree, k, q);
            let width = cross / drop.max(0.05);
            // The bead's thickness is its distance to the string it rests on: the drop on a
            // vertical wall, more on a leaning one (a dish's strings lie nearly side by side);
            // not judged against the line's own trail.
            if !below.is_trail(k, qi) {
                let t = below.thickness_mm(tree, k, q);
                below.width_check(o, i, q, cross, t, false, rep);
            }
            if side > 0.5 * width + 1e-9 {
                rep.add(
                    o.max_listed,
                    Issue {
                        kind: IssueKind::WideningTooFast,
                        step: i,
                        at: q,
                        msg: format!(
                            "offset {side:.2} mm from the string {drop:.2} mm below exceeds half the string width ({:.2} mm): an overhang of {:.0}° from the vertical, beyond atan(w / 2h) = {:.0}°",
                            0.5 * width,
                            side.atan2(drop).to_degrees(),
                            (0.5 * width).atan2(drop).to_degrees()
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
