//! The reference the grid must agree with: every query answered by a plain scan over the
//! printed points (nearest point, ties to the earliest printed), and property tests
//! comparing the two, query by query on random point sets and report by report on random
//! small designs (fixed seed in CI, `PROPTEST_RNG_SEED` in `.cargo/config.toml`).

use super::grid::{dist2, Grid};
use super::{check_with, CheckOptions, Printed};
use crate::design::model::{Model, Step, Str};
use crate::design::profile::Profile;
use glam::DVec3;
use proptest::prelude::*;

/// Printed material as a list scanned whole by every query.
pub(crate) struct Scan {
    points: Vec<[f64; 3]>,
    printed: usize,
}

impl Printed for Scan {
    fn build(_cell_mm: f64, points: Vec<[f64; 3]>) -> Self {
        Scan { points, printed: 0 }
    }
    fn point(&self, i: usize) -> [f64; 3] {
        self.points[i]
    }
    fn print_through(&mut self, end: usize) {
        self.printed = self.printed.max(end.min(self.points.len()));
    }
    fn nearest_below(&mut self, q: [f64; 3], r2: f64, max_z: f64) -> Option<usize> {
        let mut best: Option<(f64, usize)> = None;
        for (i, p) in self.points[..self.printed].iter().enumerate() {
            let d2 = dist2(*p, q);
            if p[2] <= max_z && d2 <= r2 && best.is_none_or(|(b, _)| d2 < b) {
                best = Some((d2, i));
            }
        }
        best.map(|(_, i)| i)
    }
    fn any_below(&mut self, q: [f64; 3], r2: f64, max_z: f64) -> bool {
        self.nearest_below(q, r2, max_z).is_some()
    }
    fn printed(&self) -> usize {
        self.printed
    }
    fn any_at_or_above(&self, lo: [f64; 2], hi: [f64; 2], min_z: f64) -> bool {
        self.points[..self.printed].iter().any(|p| {
            p[2] >= min_z && p[0] >= lo[0] && p[0] <= hi[0] && p[1] >= lo[1] && p[1] <= hi[1]
        })
    }
}

/// A coordinate on a 1/4 mm lattice (exact in binary: equal distances and points on column
/// edges are common) or anywhere in the same range.
fn coord(range_mm: f64) -> impl Strategy<Value = f64> {
    let steps = (range_mm * 4.0) as i32;
    prop_oneof![
        2 => (0..=steps).prop_map(|k| f64::from(k) * 0.25),
        1 => 0.0..range_mm,
    ]
}

fn point() -> impl Strategy<Value = [f64; 3]> {
    (coord(4.0), coord(4.0), coord(2.0)).prop_map(|(x, y, z)| [x, y, z])
}

/// One step of a grid-vs-scan session.
#[derive(Clone, Debug)]
enum Op {
    /// Print this many more points.
    Print(usize),
    /// Nearest (or, with `any`, existence) query.
    Below {
        q: [f64; 3],
        r_mm: f64,
        drop_mm: f64,
        any: bool,
    },
    /// Travel query: XY box of half-width `r_mm` at height `z`.
    Above { q: [f64; 3], r_mm: f64 },
}

fn op() -> impl Strategy<Value = Op> {
    prop_oneof![
        (1usize..12).prop_map(Op::Print),
        (point(), 0.05f64..2.5, -1.0f64..0.4, any::<bool>()).prop_map(|(q, r_mm, drop_mm, any)| {
            Op::Below {
                q,
                r_mm,
                drop_mm,
                any,
            }
        }),
        (point(), 0.0f64..1.0).prop_map(|(q, r_mm)| Op::Above { q, r_mm }),
    ]
}

/// Random small designs: strings (some not extruding) and travels between lattice points,
/// rising slowly so that many points are supported and some widen or hang in the air.
fn design() -> impl Strategy<Value = Model> {
    let step = (point(), 0u8..10, 0.0f64..0.6, 1.0f64..60.0)
        .prop_map(|(p, kind, cross, speed)| (DVec3::from_array(p), kind, cross, speed));
    proptest::collection::vec(step, 1..60).prop_map(|steps| {
        let mut m = Model::new([0.0, 0.0]);
        let mut at = DVec3::new(1.0, 1.0, 0.2);
        for (k, (p, kind, cross, speed)) in steps.into_iter().enumerate() {
            let to = DVec3::new(p.x, p.y, 0.2 + 0.1 * k as f64 * p.z / 3.0);
            match kind {
                0 => m.push(Step::Travel {
                    to,
                    speed_mm_s: None,
                }),
                1 => m.push(Step::String(Str::line(at, to, 0.0, speed))),
                // Short moves near the last point: layers stacked on each other.
                2..=5 => {
                    let near = at + (to - at) * 0.2;
                    m.push(Step::String(Str::line(at, near, cross, speed)));
                    m.push(Step::String(Str::line(
                        near,
                        at + DVec3::Z * 0.2,
                        cross,
                        speed,
                    )));
                }
                _ => m.push(Step::String(Str::line(at, to, cross, speed))),
            }
            at = match m.steps.last() {
                Some(Step::String(s)) => s.end,
                _ => to,
            };
        }
        m
    })
}

fn options() -> impl Strategy<Value = CheckOptions> {
    (
        0.1f64..2.5,
        0.1f64..1.0,
        0.05f64..1.0,
        -0.1f64..0.3,
        0.0f64..0.3,
    )
        .prop_map(
            |(support_radius_mm, sample_mm, nozzle_radius_mm, min_drop_mm, clearance)| {
                CheckOptions {
                    support_radius_mm,
                    sample_mm,
                    nozzle_radius_mm,
                    min_drop_mm,
                    travel_clearance_mm: clearance,
                    max_listed: usize::MAX,
                    ..CheckOptions::default()
                }
            },
        )
}

proptest! {
    /// Query by query, the grid answers as the scan does, while points get printed. One
    /// point far away (half the cases) makes the grid hash its columns instead of indexing
    /// them directly.
    #[test]
    fn grid_matches_scan(
        mut points in proptest::collection::vec(point(), 0..300),
        ops in proptest::collection::vec(op(), 1..120),
        far in any::<bool>(),
        cell_mm in prop_oneof![Just(0.25), Just(0.5), Just(1.0), 0.1f64..2.0],
    ) {
        if far {
            points.push([4.0e7, 3.0, 1.0]);
        }
        let mut grid = Grid::build(cell_mm, points.clone());
        let mut scan = Scan::build(cell_mm, points);
        let mut printed = 0;
        for op in ops {
            match op {
                Op::Print(n) => {
                    printed += n;
                    grid.print_through(printed);
                    scan.print_through(printed);
                }
                Op::Below { q, r_mm, drop_mm, any } => {
                    let (r2, max_z) = (r_mm * r_mm, q[2] - drop_mm);
                    if any {
                        prop_assert_eq!(grid.any_below(q, r2, max_z), scan.any_below(q, r2, max_z));
                    } else {
                        prop_assert_eq!(
                            grid.nearest_below(q, r2, max_z),
                            scan.nearest_below(q, r2, max_z)
                        );
                    }
                }
                Op::Above { q, r_mm } => {
                    let (lo, hi) = ([q[0] - r_mm, q[1] - r_mm], [q[0] + r_mm, q[1] + r_mm]);
                    prop_assert_eq!(
                        grid.any_at_or_above(lo, hi, q[2]),
                        scan.any_at_or_above(lo, hi, q[2])
                    );
                }
            }
        }
    }

    /// Report by report (every issue, its step, place and message), the checks find the
    /// same with the grid as with the scan.
    #[test]
    fn checks_match_the_scan(model in design(), o in options()) {
        let p = Profile::ender3();
        prop_assert_eq!(check_with::<Grid>(&model, &p, &o), check_with::<Scan>(&model, &p, &o));
    }
}

/// Infinite, huge and NaN coordinates: no panic, and the grid still answers as the scan does
/// (the columns are hashed when the points spread over more than the direct index holds).
#[test]
fn extreme_coordinates_match_the_scan() {
    let (inf, nan) = (f64::INFINITY, f64::NAN);
    let points = vec![
        [0.0, 0.0, 0.2],
        [inf, 0.0, 0.2],
        [-1e300, 1e300, 0.4],
        [nan, 0.0, 0.2],
        [0.1, 0.1, inf],
        [0.2, -inf, 0.3],
        [0.3, 0.0, nan],
        [5e9, -5e9, 0.1],
        [0.2, 0.2, 0.6],
    ];
    let queries = [
        [0.0, 0.0, 1.0],
        [0.1, 0.1, 0.5],
        [inf, 0.0, 1.0],
        [nan, 0.0, 1.0],
        [5e9, -5e9, 0.5],
        [-1e300, 1e300, 1.0],
        [0.0, 0.0, -inf],
    ];
    for cell_mm in [1.2, 0.0, -1.0, nan, 1e-300] {
        let mut grid = Grid::build(cell_mm, points.clone());
        let mut scan = Scan::build(cell_mm, points.clone());
        for printed in [0, 3, 6, points.len()] {
            grid.print_through(printed);
            scan.print_through(printed);
            for q in queries {
                for (r2, drop) in [(1.44, 0.05), (1e-6, 0.0), (4.0, -1.0)] {
                    let z = q[2] - drop;
                    assert_eq!(grid.nearest_below(q, r2, z), scan.nearest_below(q, r2, z));
                    assert_eq!(grid.any_below(q, r2, z), scan.any_below(q, r2, z));
                }
                let (lo, hi) = ([q[0] - 0.3, q[1] - 0.3], [q[0] + 0.3, q[1] + 0.3]);
                assert_eq!(
                    grid.any_at_or_above(lo, hi, q[2]),
                    scan.any_at_or_above(lo, hi, q[2]),
                    "{q:?} {cell_mm}"
                );
            }
        }
    }
}
