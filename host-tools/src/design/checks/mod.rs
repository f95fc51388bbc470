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

use crate::design::model::{Model, Step};
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
    let mut rep = CheckReport::default();
    let b = &profile.bed;
    let max_flow = profile.limits.max_volumetric_mm3_s;
    let min_z = model.bbox().min.z;
    let bed_contact_z = if min_z.is_finite() {
        min_z.max(0.0) + o.bed_contact_mm
    } else {
        o.bed_contact_mm
    };
    let inside = |p: DVec3| {
        p.x >= b.x_min_mm - 1e-9
            && p.x <= b.x_max_mm + 1e-9
            && p.y >= b.y_min_mm - 1e-9
            && p.y <= b.y_max_mm + 1e-9
            && p.z >= -1e-9
            && p.z <= b.z_max_mm + 1e-9
    };
    let mut tree = Grid::new(o.support_radius_mm.max(o.nozzle_radius_mm).max(0.1));
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
                    // previous string's end, already checked), then the string goes into the
                    // index (after the check: it cannot support itself).
                    let n = ((s.len_mm() / o.sample_mm).ceil() as usize).clamp(1, 10_000);
                    for k in 1..=n {
                        let q = s.start.lerp(s.end, k as f64 / n as f64);
                        if q.z > bed_contact_z
                            && !support_check(&tree, o, r2, i, q, s.cross_mm2, k == n, &mut rep)
                        {
                            break;
                        }
                    }
                    for k in 1..=n {
                        let p = s.start.lerp(s.end, k as f64 / n as f64);
                        tree.insert([p.x, p.y, p.z]);
                    }
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
fn support_check(
    tree: &Grid,
    o: &CheckOptions,
    r2: f64,
    i: usize,
    q: DVec3,
    cross: f64,
    end: bool,
    rep: &mut CheckReport,
) -> bool {
    match tree.nearest_below([q.x, q.y, q.z], r2, q.z - o.min_drop_mm) {
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

fn travel_check(
    tree: &Grid,
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
mod tests {
    use super::*;
    use crate::design::deform;
    use crate::design::parts::Helix;

    fn helix(radius_growth: f64) -> Model {
        let h = Helix {
            turns: 10.0,
            ..Helix::default()
        }
        .build()
        .expect("helix");
        deform::deform_cylinder(
            h,
            |c| DVec3::new(c.x + radius_growth * c.z, c.y, c.z),
            |c, _| c,
            |v, _| v,
            None,
        )
        .expect("deform")
    }

    #[test]
    fn plain_helix_is_clean() {
        let r = check(&helix(0.0), &Profile::ender3(), &CheckOptions::default());
        assert!(r.is_clean(), "{:?}", r.issues);
    }

    #[test]
    fn fast_widening_is_flagged() {
        // 0.4 mm pitch, 0.2 mm² ⇒ width 0.5: offsets > 0.25 mm/turn cannot stack.
        let r = check(&helix(2.0), &Profile::ender3(), &CheckOptions::default());
        assert!(r.count(IssueKind::WideningTooFast) > 0, "{:?}", r.counts);
        let slow = check(&helix(0.2), &Profile::ender3(), &CheckOptions::default());
        assert_eq!(slow.count(IssueKind::WideningTooFast), 0);
    }

    #[test]
    fn air_outside_and_flow() {
        let mut m = Model::new([0.0, 0.0]);
        use crate::design::model::Str;
        m.push(Step::String(Str::line(
            DVec3::new(10.0, 10.0, 0.2),
            DVec3::new(20.0, 10.0, 0.2),
            0.2,
            20.0,
        )));
        // in the air, 5 mm up
        m.push(Step::String(Str::line(
            DVec3::new(50.0, 50.0, 5.0),
            DVec3::new(60.0, 50.0, 5.0),
            0.2,
            20.0,
        )));
        m.push(Step::String(Str::line(
            DVec3::new(60.0, 50.0, 5.0),
            DVec3::new(260.0, 50.0, 5.0),
            0.2,
            200.0,
        )));
        let r = check(&m, &Profile::ender3(), &CheckOptions::default());
        assert!(r.count(IssueKind::Unsupported) >= 1);
        assert_eq!(r.count(IssueKind::OutsideBed), 1);
        assert_eq!(r.count(IssueKind::FlowTooHigh), 1);
        let first = r.issues.iter().find(|i| i.kind == IssueKind::OutsideBed);
        assert_eq!(first.map(|i| i.step), Some(2));
    }

    #[test]
    fn travel_over_print_is_flagged() {
        use crate::design::model::Str;
        let mut m = Model::new([0.0, 0.0]);
        m.push(Step::String(Str::line(
            DVec3::new(10.0, 10.0, 0.2),
            DVec3::new(10.0, 30.0, 0.2),
            0.2,
            20.0,
        )));
        m.push(Step::Travel {
            to: DVec3::new(0.0, 20.0, 0.2),
            speed_mm_s: None,
        });
        m.push(Step::Travel {
            to: DVec3::new(20.0, 20.0, 0.2),
            speed_mm_s: None,
        });
        let r = check(&m, &Profile::ender3(), &CheckOptions::default());
        assert_eq!(r.count(IssueKind::TravelCrossesPrint), 1, "{:?}", r.issues);
    }

    fn line(m: &mut Model, a: [f64; 3], b: [f64; 3]) {
        m.push(Step::String(crate::design::model::Str::line(
            a.into(),
            b.into(),
            0.2,
            20.0,
        )));
    }

    /// A 40 mm bridge from one pillar onto another: both ends rest on the pillars, the middle
    /// is in the air.
    #[test]
    fn bridge_is_unsupported_in_the_middle() {
        let mut m = Model::new([0.0, 0.0]);
        for k in 0..10 {
            let z = 0.2 * (k + 1) as f64;
            line(&mut m, [100.0, 100.0, z], [101.0, 100.0, z]);
            line(&mut m, [140.0, 100.0, z], [141.0, 100.0, z]);
        }
        line(&mut m, [101.0, 100.0, 2.2], [140.0, 100.0, 2.2]);
        let r = check(&m, &Profile::ender3(), &CheckOptions::default());
        assert_eq!(r.count(IssueKind::Unsupported), 1, "{:?}", r.issues);
        let at = r.issues.iter().find(|i| i.kind == IssueKind::Unsupported);
        assert!(at.is_some_and(|i| i.at.x > 102.0 && i.at.x < 139.0));
    }

    #[test]
    fn first_layer_at_z0_is_flagged() {
        let mut m = Model::new([0.0, 0.0]);
        line(&mut m, [100.0, 100.0, 0.0], [120.0, 100.0, 0.0]);
        let r = check(&m, &Profile::ender3(), &CheckOptions::default());
        assert_eq!(r.count(IssueKind::OutsideBed), 1, "{:?}", r.issues);
        let mut ok = Model::new([0.0, 0.0]);
        line(&mut ok, [100.0, 100.0, 0.2], [120.0, 100.0, 0.2]);
        assert!(check(&ok, &Profile::ender3(), &CheckOptions::default()).is_clean());
    }

    /// The message names the limit the check applies: half the width plus the allowance.
    #[test]
    fn widening_message_states_the_limit_used() {
        let r = check(&helix(2.0), &Profile::ender3(), &CheckOptions::default());
        let i = r
            .issues
            .iter()
            .find(|i| i.kind == IssueKind::WideningTooFast);
        assert!(
            i.is_some_and(|i| i.msg.contains("plus the 0.25 mm sampling allowance")),
            "{:?}",
            r.issues
        );
    }
}
