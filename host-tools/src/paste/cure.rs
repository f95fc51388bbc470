//! Cure check on time-based samples (SPEC §4): for every deposited sample, the nearest
//! material *directly below it* — laid before it by **another pass** of the head, on the
//! **layer one down** when the job has layer marks, lower by at least `min_dz_mm` and
//! horizontally within `radius_mm` — and the time since that material was laid. Spots below
//! the cure time are violations. The same check is an FDM minimum-layer-time check.
//!
//! The material below is the **deposited path**: the segments between consecutive depositing
//! samples, not the samples themselves (at 40 mm/s and 100 ms the samples of the layer below
//! are 4 mm apart, and a sample-to-sample search found nothing within a 1 mm radius for most
//! of a layer). The point below is the XY-nearest point of a segment; its time is interpolated
//! along the segment, `elapsed = t_i − (j − 1 + u) × period` for the point at fraction `u` of
//! the segment from sample `j − 1` to `j` (the head moves along a segment within one period).
//! A segment that crosses a layer change (the seam: the end of one layer, the rise, the
//! start of the next) is material of both layers, as far as it is low enough (of the new
//! one only when the head rose, travelled or waited before it). A sample where the head
//! rises away from printing (its piece climbs by at least `min_dz_mm`, nothing deposited
//! after it) lays the end of its layer on the way up and is not measured.
//!
//! **Another pass.** The head's way into the sample — the samples before it that stay within
//! the radius, along at most π × radius of path — is the pass that lays the sample, not
//! material below it: at a layer's first sample that is the end of the layer below arriving
//! at the seam a moment before (before issue 33 it was measured against its own rising
//! segment, 0.02 s, a false alarm at every layer's start). **One layer down**: with layer
//! marks only material of the layer right below counts (before, a layer's last sample, at
//! the seam, could be measured against the start of that layer two passes ago). Among points
//! equally near (the seam, where a layer starts and ends), the most recent counts: it has had
//! the least time.
//!
//! **Index**: every depositing segment is entered in each XY column (cell = radius) it
//! crosses; columns are sorted by the segments' lowest z. A query looks at the 3×3 columns
//! around the sample (any segment within the radius crosses one of them), starts at the
//! highest segment low enough (binary search) and walks down, stopping as soon as the height
//! difference alone exceeds the best distance found. Queries run in parallel (rayon).

use crate::paste::bins::bin_by_cell;
use crate::paste::timebased::Sample;
use glam::DVec2;
use rayon::prelude::*;

/// Parameters of the check.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CureParams {
    /// Sample period, s.
    pub period_s: f64,
    /// Required curing time before material is laid on top, s.
    pub cure_s: f64,
    /// Horizontal search radius, mm.
    pub radius_mm: f64,
    /// A sample counts as "below" when it is at least this much lower, mm.
    pub min_dz_mm: f64,
}

/// A spot laid on material that has not cured long enough.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Violation {
    /// Index of the sample (its time is `index × period`).
    pub index: usize,
    /// The sample nearest in time to the material below it (that material was laid at a
    /// point of the path between two samples; `elapsed_s` is exact).
    pub below_index: usize,
    /// Layer of the sample.
    pub layer: u32,
    /// Position, mm.
    pub x: f64,
    /// Position, mm.
    pub y: f64,
    /// Position, mm.
    pub z: f64,
    /// Time since the material below was laid, s.
    pub elapsed_s: f64,
}

/// Per-layer figures.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct LayerStat {
    /// Layer index.
    pub layer: u32,
    /// Deposited samples in the layer.
    pub samples: usize,
    /// Samples with material below them.
    pub supported: usize,
    /// Shortest elapsed time in the layer, s (None: nothing below).
    pub min_elapsed_s: Option<f64>,
    /// Violations in the layer.
    pub violations: usize,
}

/// Result of the check.
#[derive(Debug, Clone, serde::Serialize)]
pub struct CureReport {
    /// All samples, including travels and still periods.
    pub samples: usize,
    /// Samples that deposit material (the ones checked).
    pub deposited: usize,
    /// Deposited samples with earlier deposited material below them.
    pub supported: usize,
    /// Number of violations.
    pub violation_count: usize,
    /// Every violation, in time order.
    pub violations: Vec<Violation>,
    /// Shortest elapsed time found, s.
    pub min_elapsed_s: Option<f64>,
    /// Cure time asked for, s.
    pub cure_s: f64,
    /// Search radius, mm.
    pub radius_mm: f64,
    /// Sample period, s.
    pub period_s: f64,
    /// Per-layer figures.
    pub layers: Vec<LayerStat>,
    /// For every sample, the elapsed time to the sample below (None: not deposited or
    /// nothing below); used by the heat map.
    #[serde(skip)]
    pub elapsed_s: Vec<Option<f64>>,
}

/// Depositing segments in XY columns.
struct Columns {
    origin: DVec2,
    cell: f64,
    nx: usize,
    ny: usize,
    starts: Vec<u32>,
    /// Segment ends `j` (the segment from sample `j - 1` to `j`), grouped by column, each
    /// column sorted by the segment's lowest z.
    order: Vec<u32>,
    /// Lowest z of the segment `order[k]` (contiguous for the binary search).
    zs: Vec<f64>,
    /// Largest rise of any segment (highest minus lowest z), for the walk's stopping bound.
    max_rise: f64,
}

/// True when sample `j` ends a depositing segment (from sample `j - 1`).
fn deposits(samples: &[Sample], j: usize) -> bool {
    j > 0 && samples[j].extruding && samples[j].pos.is_finite() && samples[j - 1].pos.is_finite()
}

impl Columns {
    fn new(samples: &[Sample], cell: f64) -> Columns {
        let segs = || (1..samples.len()).filter(|&j| deposits(samples, j));
        let (mut lo, mut hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
        for j in segs() {
            for p in [samples[j - 1].pos, samples[j].pos] {
                lo = lo.min(p.truncate());
                hi = hi.max(p.truncate());
            }
        }
        if lo.x > hi.x {
            lo = DVec2::ZERO;
            hi = DVec2::ZERO;
        }
        // Keep the grid bounded (≤ 16 M columns): grow the cell for huge, sparse areas.
        let mut cell = cell;
        while ((hi.x - lo.x) / cell + 1.0) * ((hi.y - lo.y) / cell + 1.0) > 16e6 {
            cell *= 2.0;
        }
        let nx = ((hi.x - lo.x) / cell) as usize + 1;
        let ny = ((hi.y - lo.y) / cell) as usize + 1;
        let col = |p: DVec2| -> (usize, usize) {
            (
                (((p.x - lo.x) / cell) as usize).min(nx - 1),
                (((p.y - lo.y) / cell) as usize).min(ny - 1),
            )
        };
        // Every column a segment crosses: the boxes of its pieces no longer than a cell (at
        // most 2 × 2 columns each).
        let mut entries: Vec<(u32, usize)> = Vec::new();
        let mut cols: Vec<usize> = Vec::new();
        let mut max_rise = 0.0f64;
        for j in segs() {
            let (a, b) = (samples[j - 1].pos, samples[j].pos);
            max_rise = max_rise.max((a.z - b.z).abs());
            let len = a.truncate().distance(b.truncate());
            let pieces = ((len / cell).ceil() as usize).clamp(1, 1 << 20);
            cols.clear();
            for k in 0..pieces {
                let p0 = a.truncate().lerp(b.truncate(), k as f64 / pieces as f64);
                let p1 = a
                    .truncate()
                    .lerp(b.truncate(), (k + 1) as f64 / pieces as f64);
                let (c0, c1) = (col(p0.min(p1)), col(p0.max(p1)));
                for iy in c0.1..=c1.1 {
                    for ix in c0.0..=c1.0 {
                        cols.push(iy * nx + ix);
                    }
                }
            }
            cols.sort_unstable();
            cols.dedup();
            entries.extend(cols.iter().map(|&c| (j as u32, c)));
        }
        let (mut starts, mut cursor, mut order) = (Vec::new(), Vec::new(), Vec::new());
        bin_by_cell(
            nx * ny,
            || entries.iter().copied(),
            &mut starts,
            &mut cursor,
            &mut order,
        );
        drop(entries);
        let low = |j: u32| samples[j as usize].pos.z.min(samples[j as usize - 1].pos.z);
        // Sort every column by lowest z (ties by index), in parallel over disjoint slices.
        let mut slices: Vec<&mut [u32]> = Vec::with_capacity(nx * ny);
        let mut rest: &mut [u32] = &mut order;
        for c in 0..nx * ny {
            let len = (starts[c + 1] - starts[c]) as usize;
            let (head, tail) = rest.split_at_mut(len);
            slices.push(head);
            rest = tail;
        }
        slices.par_iter_mut().for_each(|sl| {
            if sl.len() > 1 {
                sl.sort_unstable_by(|&a, &b| low(a).total_cmp(&low(b)).then(a.cmp(&b)));
            }
        });
        let zs = order.iter().map(|&j| low(j)).collect();
        Columns {
            origin: lo,
            cell,
            nx,
            ny,
            starts,
            order,
            zs,
            max_rise,
        }
    }
}

/// The material below a sample: its time in sample periods (`j - 1 + u`).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Found {
    at: f64,
}

/// A point of the deposited path below a sample: its horizontal distance, height below,
/// time (`j − 1 + u` periods) and how far its piece may lie from the head's true path (half
/// the piece's length, at most the radius: a chord cuts a corner by less).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Candidate {
    dxy: f64,
    dz: f64,
    at: f64,
    slack: f64,
}

/// Runs the check.
pub fn check(samples: &[Sample], p: &CureParams) -> CureReport {
    let cols = Columns::new(samples, p.radius_mm.max(1e-6));
    let layered = samples.iter().any(|s| s.layer > 0);
    let r2 = p.radius_mm * p.radius_mm;
    let below: Vec<Option<Found>> = (0..samples.len())
        .into_par_iter()
        .map_init(Vec::new, |scratch, i| {
            let s = samples[i];
            if !s.extruding || !s.pos.is_finite() || leaves_printing(samples, i, p.min_dz_mm) {
                return None;
            }
            let q = Query {
                i,
                pass: pass_start(samples, i, p.radius_mm),
                r2,
                min_dz: p.min_dz_mm,
                layered,
            };
            nearest_below(&cols, samples, &q, scratch)
        })
        .collect();
    let mut report = CureReport {
        samples: samples.len(),
        deposited: 0,
        supported: 0,
        violation_count: 0,
        violations: Vec::new(),
        min_elapsed_s: None,
        cure_s: p.cure_s,
        radius_mm: p.radius_mm,
        period_s: p.period_s,
        layers: Vec::new(),
        elapsed_s: vec![None; samples.len()],
    };
    let max_layer = samples.iter().map(|s| s.layer).max().unwrap_or(0) as usize;
    let mut layers: Vec<LayerStat> = (0..=max_layer)
        .map(|l| LayerStat {
            layer: l as u32,
            samples: 0,
            supported: 0,
            min_elapsed_s: None,
            violations: 0,
        })
        .collect();
    for (i, s) in samples.iter().enumerate() {
        if !s.extruding {
            continue;
        }
        report.deposited += 1;
        let ls = &mut layers[s.layer as usize];
        ls.samples += 1;
        let Some(f) = below[i] else { continue };
        let elapsed = (i as f64 - f.at) * p.period_s;
        report.elapsed_s[i] = Some(elapsed);
        report.supported += 1;
        ls.supported += 1;
        ls.min_elapsed_s = Some(ls.min_elapsed_s.map_or(elapsed, |m: f64| m.min(elapsed)));
        report.min_elapsed_s = Some(
            report
                .min_elapsed_s
                .map_or(elapsed, |m: f64| m.min(elapsed)),
        );
        if elapsed < p.cure_s {
            ls.violations += 1;
            report.violations.push(Violation {
                index: i,
                below_index: f.at.round() as usize,
                layer: s.layer,
                x: s.pos.x,
                y: s.pos.y,
                z: s.pos.z,
                elapsed_s: elapsed,
            });
        }
    }
    report.violation_count = report.violations.len();
    report.layers = layers.into_iter().filter(|l| l.samples > 0).collect();
    report
}

/// The first sample of the pass that lays sample `i`: the samples before it that stay
/// within `radius` of it (XY), along at most π × `radius` of path (a path circling inside
/// the radius longer than that comes round again: another pass).
fn pass_start(samples: &[Sample], i: usize, radius: f64) -> usize {
    let here = samples[i].pos.truncate();
    let (r2, max_len) = (radius * radius, std::f64::consts::PI * radius);
    let (mut m, mut len) = (i, 0.0);
    while m > 0 {
        let prev = samples[m - 1].pos.truncate();
        let step = prev.distance(samples[m].pos.truncate());
        if !(prev.distance_squared(here) <= r2 && len + step <= max_len) {
            break;
        }
        len += step;
        m -= 1;
    }
    m
}

/// Whether the piece ending at sample `j` lays material of layer `layer`: its own layer, and
/// for a piece that crosses a layer change (the seam) also the layer it leaves when the head
/// was printing that layer as it began (not after a rise, travel or wait: then the piece is
/// the new layer's start only).
fn of_layer(samples: &[Sample], j: usize, layer: u32) -> bool {
    let (a, b) = (&samples[j - 1], &samples[j]);
    b.layer == layer || (a.layer == layer && a.extruding)
}

/// True when sample `i` is where the head rises away from printing: its piece climbs by at
/// least `min_dz` and nothing is deposited after it (a rise, travel or wait follows). That
/// piece lays the end of the layer on the way up; it is not measured.
fn leaves_printing(samples: &[Sample], i: usize, min_dz: f64) -> bool {
    i > 0
        && samples[i].pos.z - samples[i - 1].pos.z >= min_dz.max(1e-9)
        && !samples.get(i + 1).is_some_and(|n| n.extruding)
}

/// What [`nearest_below`] looks for.
struct Query {
    /// The sample.
    i: usize,
    /// The first sample of the pass that lays it ([`pass_start`]).
    pass: usize,
    /// The radius, squared, mm².
    r2: f64,
    /// Least height below, mm.
    min_dz: f64,
    /// The job has layer marks: only the layer right below counts.
    layered: bool,
}

/// The material right below sample `q.i` (see the module docs): of the points of earlier
/// passes within the radius, the horizontally nearest — and among those that may be as near
/// (within their piece's slack: the samples do not show the path between them), the most
/// recent. `scratch` is reused between queries.
fn nearest_below(
    cols: &Columns,
    samples: &[Sample],
    q: &Query,
    scratch: &mut Vec<Candidate>,
) -> Option<Found> {
    let i = q.i;
    let s = samples[i].pos;
    let zmax = s.z - q.min_dz;
    let radius = q.r2.sqrt();
    let g = (s.truncate() - cols.origin) / cols.cell;
    let (cx, cy) = (g.x.floor() as i64, g.y.floor() as i64);
    scratch.clear();
    for y in cy - 1..=cy + 1 {
        if y < 0 || y >= cols.ny as i64 {
            continue;
        }
        for x in cx - 1..=cx + 1 {
            if x < 0 || x >= cols.nx as i64 {
                continue;
            }
            let c = y as usize * cols.nx + x as usize;
            let (a, b) = (cols.starts[c] as usize, cols.starts[c + 1] as usize);
            let zs = &cols.zs[a..b];
            // Entries [a, a + k) start low enough.
            let k = zs.partition_point(|&z| z <= zmax);
            // The shallowest point found in this column: material more than a radius
            // deeper than it is not what the sample rests on.
            let mut top_dz = f64::INFINITY;
            for t in (0..k).rev() {
                // Lowest possible height difference of this and every later entry.
                if s.z - zs[t] - cols.max_rise > top_dz + radius {
                    break;
                }
                let j = cols.order[a + t] as usize;
                // Only pieces of earlier passes, and with layer marks only those of the layer
                // right below. A piece that crosses a layer change (the seam) belongs to both
                // layers: it lays the end of the one and the start of the other.
                if j >= q.pass || (q.layered && !of_layer(samples, j, samples[i].layer - 1)) {
                    continue;
                }
                let (p0, p1) = (samples[j - 1].pos, samples[j].pos);
                let d = p1.truncate() - p0.truncate();
                let l2 = d.length_squared();
                let mut u = if l2 > 0.0 {
                    ((s.truncate() - p0.truncate()).dot(d) / l2).clamp(0.0, 1.0)
                } else {
                    1.0
                };
                // Only the part of the piece low enough counts (a ramp between layers).
                let rise = p1.z - p0.z;
                if rise != 0.0 {
                    let uz = (zmax - p0.z) / rise;
                    u = if rise > 0.0 { u.min(uz) } else { u.max(uz) };
                    if !(0.0..=1.0).contains(&u) {
                        continue;
                    }
                }
                let p = p0.lerp(p1, u);
                // Laid before the sample (the piece reaching sample i itself only in part).
                if p.z > zmax + 1e-12 || (j - 1) as f64 + u >= i as f64 {
                    continue;
                }
                let dxy2 = (p.truncate() - s.truncate()).length_squared();
                if dxy2 > q.r2 {
                    continue;
                }
                top_dz = top_dz.min(s.z - p.z);
                scratch.push(Candidate {
                    dxy: dxy2.sqrt(),
                    dz: s.z - p.z,
                    at: (j - 1) as f64 + u,
                    slack: (l2.sqrt() / 2.0).min(radius),
                });
            }
        }
    }
    let nearest = scratch.iter().map(|c| c.dxy).reduce(f64::min)?;
    // Of the points that may be as near as the nearest, the most recent: it has had the
    // least time (at a seam, where the layer below starts and ends, the end).
    scratch
        .iter()
        .filter(|c| c.dxy - c.slack <= nearest + 1e-9)
        .max_by(|a, b| a.at.total_cmp(&b.at).then(b.dz.total_cmp(&a.dz)))
        .map(|c| Found { at: c.at })
}
