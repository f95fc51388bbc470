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
//! - **travel crosses printed material** at the nozzle's height (stringing), and **travel hits
//!   printed material** standing above the nozzle (a collision: an error);
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
//!
//! Modules: this one walks the design (options, report, the pass over the steps); `below`
//! holds the checks of one point against the material printed before it (support,
//! widening, line width, travels); `grid` the index; `machine` the printer state raw G-code
//! and the design's state changes set (cold extrusion, homing).

mod below;
mod grid;
mod machine;

pub use machine::MIN_EXTRUDE_C;

use crate::design::model::{Model, Step};
use crate::design::profile::Profile;
use below::{bed_width_check, support_check, travel_check, Below, RUN_GAP_MM};
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
    /// A travel drives the nozzle into printed material standing above it (a collision, not
    /// stringing): an error, `compile` writes nothing.
    TravelHitsPrint,
}

/// Number of issue kinds.
const KINDS: usize = 9;

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
            IssueKind::TravelHitsPrint => "travel-hits-print",
        }
    }

    /// True for issues that make the G-code destroy the print or the printer (refused even
    /// without `--strict`).
    pub fn is_error(&self) -> bool {
        matches!(self, IssueKind::TravelHitsPrint)
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

    /// Number of issues that are errors ([`IssueKind::is_error`]).
    pub fn errors(&self) -> usize {
        self.counts[IssueKind::TravelHitsPrint as usize]
    }

    /// Counts an issue of `kind` and lists it while fewer than `max` of its kind are: the
    /// message is written only then (a design with an issue at every point — Kanada's
    /// 0.2 mm² helix at 0.2 mm layers, 44,701 line widths — spent 4× the checks' time
    /// writing messages nobody sees).
    fn add(
        &mut self,
        max: usize,
        kind: IssueKind,
        step: usize,
        at: DVec3,
        msg: impl FnOnce() -> String,
    ) {
        let k = kind as usize;
        self.counts[k] += 1;
        if self.counts[k] <= max {
            self.issues.push(Issue {
                kind,
                step,
                at,
                msg: msg(),
            });
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

/// `1 / sample_mm` when that product is exactly the quotient (a power of two, as the default
/// 0.5 mm): the count is then the same without a division per string.
fn exact_inverse(v: f64) -> Option<f64> {
    let inv = 1.0 / v;
    let power_of_two = v.is_normal() && v.to_bits() & ((1u64 << 52) - 1) == 0;
    (power_of_two && inv.is_normal()).then_some(inv)
}

/// Number of sample points of an extruded string `len_mm` long: one every `sample_mm` (at
/// least one, at most 10,000), the last at its end. `inv`: [`exact_inverse`] of `sample_mm`.
fn sample_count(len_mm: f64, o: &CheckOptions, inv: Option<f64>) -> usize {
    // ceil(x) without the libm call (x86-64 without SSE4.1 has no rounding instruction):
    // the same count for every x, NaN and infinities included.
    let x = match inv {
        Some(inv) => len_mm * inv,
        None => len_mm / o.sample_mm,
    };
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
    let inv_sample = exact_inverse(o.sample_mm);
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
                    let len = s.len_mm();
                    let n = sample_count(len, o, inv_sample);
                    let first = points.len();
                    points.extend(
                        (1..=n).map(|k| s.start.lerp(s.end, k as f64 / n as f64).to_array()),
                    );
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
                        rep.add(o.max_listed, IssueKind::OutsideBed, i, p, || {
                            format!(
                                "({:.2}, {:.2}, {:.2}) is outside the build volume of {}",
                                p.x, p.y, p.z, profile.name
                            )
                        });
                        break;
                    }
                }
                let flow = s.flow_mm3_s();
                if flow > max_flow {
                    rep.add(o.max_listed, IssueKind::FlowTooHigh, i, s.end, || format!(
                                "flow {flow:.1} mm³/s ({:.3} mm² × {:.1} mm/s) exceeds {max_flow} mm³/s",
                                s.cross_mm2, s.speed_mm_s
                            ));
                }
                if s.cross_mm2 > 0.0 {
                    machine.extrusion(i, s, o, &mut rep);
                    let low = s.start.z.min(s.end.z);
                    if low < o.min_z_mm && low >= -1e-9 {
                        let at = if s.start.z <= s.end.z { s.start } else { s.end };
                        rep.add(o.max_listed, IssueKind::OutsideBed, i, at, || format!(
                                    "extruding at z {:.3} mm, below {} mm: the nozzle would press into the bed (a first layer needs z ≈ its height)",
                                    at.z, o.min_z_mm
                                ));
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
                    rep.add(o.max_listed, IssueKind::OutsideBed, i, *to, || {
                        format!(
                            "travel to ({:.2}, {:.2}, {:.2}) leaves the build volume",
                            to.x, to.y, to.z
                        )
                    });
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

#[cfg(test)]
mod scan;
#[cfg(test)]
mod tests;
