//! Cure check on time-based samples (SPEC §4): for every deposited sample, the nearest earlier
//! deposited sample *directly below it* — lower by at least `min_dz_mm`, horizontally within
//! `radius_mm`, and on an earlier layer when the job has layer marks (so neighbouring samples
//! of one tilted or helical layer never count as "below") — and the time since it was laid,
//! `elapsed = (i − j) × period`. Spots below the
//! cure time are violations. The same check is an FDM minimum-layer-time check.
//!
//! **Index**: samples are bucketed into a uniform XY grid of columns (cell = radius) and each
//! column is sorted by height. A query looks at the 3×3 columns around the sample, starts at
//! the highest point lower than `z − min_dz` (binary search) and walks down, stopping as soon
//! as the height difference alone exceeds the best distance found: the first layer below is
//! usually all it reads. Queries run in parallel (rayon).

use crate::paste::bins::bin_by_cell;
use crate::paste::timebased::Sample;
use glam::{DVec2, DVec3};
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
    /// Index of the sample below it.
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
    /// Deposited samples with an earlier sample below them.
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

struct Columns {
    origin: DVec2,
    cell: f64,
    nx: usize,
    ny: usize,
    starts: Vec<u32>,
    /// Sample indices, grouped by column, each column sorted by z.
    order: Vec<u32>,
    /// z of `order[k]` (contiguous for the binary search).
    zs: Vec<f64>,
}

impl Columns {
    fn new(samples: &[Sample], cell: f64) -> Columns {
        let dep = || samples.iter().filter(|s| s.extruding && s.pos.is_finite());
        let (mut lo, mut hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
        for s in dep() {
            lo = lo.min(s.pos.truncate());
            hi = hi.max(s.pos.truncate());
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
        let col = |p: DVec3| -> usize {
            let ix = (((p.x - lo.x) / cell) as usize).min(nx - 1);
            let iy = (((p.y - lo.y) / cell) as usize).min(ny - 1);
            iy * nx + ix
        };
        let (mut starts, mut cursor, mut order) = (Vec::new(), Vec::new(), Vec::new());
        let items = || {
            samples
                .iter()
                .enumerate()
                .filter(|(_, s)| s.extruding && s.pos.is_finite())
                .map(|(i, s)| (i as u32, col(s.pos)))
        };
        bin_by_cell(nx * ny, items, &mut starts, &mut cursor, &mut order);
        // Sort every column by z (ties by index), in parallel over disjoint slices.
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
                sl.sort_unstable_by(|&a, &b| {
                    samples[a as usize]
                        .pos
                        .z
                        .total_cmp(&samples[b as usize].pos.z)
                        .then(a.cmp(&b))
                });
            }
        });
        let zs = order.iter().map(|&i| samples[i as usize].pos.z).collect();
        Columns {
            origin: lo,
            cell,
            nx,
            ny,
            starts,
            order,
            zs,
        }
    }
}

/// Runs the check.
pub fn check(samples: &[Sample], p: &CureParams) -> CureReport {
    let cols = Columns::new(samples, p.radius_mm.max(1e-6));
    let layered = samples.iter().any(|s| s.layer > 0);
    let r2 = p.radius_mm * p.radius_mm;
    let below: Vec<Option<usize>> = (0..samples.len())
        .into_par_iter()
        .map(|i| {
            let s = samples[i];
            if !s.extruding || !s.pos.is_finite() {
                return None;
            }
            nearest_below(&cols, samples, i, r2, p.min_dz_mm, layered)
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
        let Some(j) = below[i] else { continue };
        let elapsed = (i - j) as f64 * p.period_s;
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
                below_index: j,
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

fn nearest_below(
    cols: &Columns,
    samples: &[Sample],
    i: usize,
    r2: f64,
    min_dz: f64,
    layered: bool,
) -> Option<usize> {
    let s = samples[i].pos;
    let zmax = s.z - min_dz;
    let g = (s.truncate() - cols.origin) / cols.cell;
    let (cx, cy) = (g.x.floor() as i64, g.y.floor() as i64);
    let mut best: Option<(f64, usize)> = None;
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
            // Entries [a, a + k) have z ≤ zmax.
            let k = zs.partition_point(|&z| z <= zmax);
            for t in (0..k).rev() {
                let j = cols.order[a + t] as usize;
                let q = samples[j].pos;
                let dz = s.z - q.z;
                if let Some((bd2, _)) = best {
                    if dz * dz > bd2 {
                        break;
                    }
                }
                if j >= i || (layered && samples[j].layer >= samples[i].layer) {
                    continue;
                }
                let dxy2 = (q.truncate() - s.truncate()).length_squared();
                if dxy2 > r2 {
                    continue;
                }
                let d2 = dxy2 + dz * dz;
                if best.is_none_or(|(bd2, bj)| d2 < bd2 || (d2 == bd2 && j > bj)) {
                    best = Some((d2, j));
                }
            }
        }
    }
    best.map(|(_, j)| j)
}

/// Text summary (and every violation when `list` is set).
pub fn summary(r: &CureReport, list: bool) -> String {
    let mut out = String::new();
    if list {
        for v in &r.violations {
            out.push_str(&format!(
                "violation: layer {} at ({:.2}, {:.2}, {:.2}) t={:.1} s: {:.1} s after the material below (needs {:.1} s)\n",
                v.layer,
                v.x,
                v.y,
                v.z,
                v.index as f64 * r.period_s,
                v.elapsed_s,
                r.cure_s
            ));
        }
    }
    out.push_str(&format!(
        "{} samples ({} deposited, {} on material below); {} spots below the cure time of {:.1} s; shortest elapsed {}\n",
        r.samples,
        r.deposited,
        r.supported,
        r.violation_count,
        r.cure_s,
        r.min_elapsed_s
            .map_or("n/a (nothing is laid on earlier material)".to_string(), |m| format!("{m:.1} s"))
    ));
    let bad: Vec<String> = r
        .layers
        .iter()
        .filter(|l| l.violations > 0)
        .map(|l| {
            format!(
                "{} ({} spots, min {:.1} s)",
                l.layer,
                l.violations,
                l.min_elapsed_s.unwrap_or(0.0)
            )
        })
        .collect();
    if !bad.is_empty() {
        out.push_str(&format!("layers with violations: {}\n", bad.join(", ")));
    }
    out
}

/// Heat map (SVG): one row per layer (bottom layer at the bottom), columns the progress
/// through the layer in 200 bins; colour the shortest elapsed time in the bin relative to the
/// cure time (red below it, yellow at it, green at 3× and beyond); grey where nothing is below.
pub fn heat_map_svg(samples: &[Sample], r: &CureReport) -> String {
    const BINS: usize = 200;
    let (w, row_h) = (800.0, 6.0f64);
    // Indices of deposited samples per layer.
    let mut per_layer: Vec<Vec<usize>> = Vec::new();
    for (i, s) in samples.iter().enumerate() {
        if s.extruding {
            let l = s.layer as usize;
            if per_layer.len() <= l {
                per_layer.resize(l + 1, Vec::new());
            }
            per_layer[l].push(i);
        }
    }
    let rows: Vec<(usize, &Vec<usize>)> = per_layer
        .iter()
        .enumerate()
        .filter(|(_, v)| !v.is_empty())
        .collect();
    let row_h = if rows.len() as f64 * row_h > 900.0 {
        (900.0 / rows.len().max(1) as f64).max(0.5)
    } else {
        row_h
    };
    let h = rows.len() as f64 * row_h;
    let mut svg = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{}\" height=\"{:.0}\" font-family=\"sans-serif\" font-size=\"12\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n",
        w + 160.0,
        h + 70.0
    );
    svg.push_str(&format!(
        "<text x=\"60\" y=\"16\">elapsed time over the material below, per layer (cure {:.1} s; {} violations)</text>\n",
        r.cure_s, r.violation_count
    ));
    for (row, (layer, idx)) in rows.iter().enumerate() {
        let y = 30.0 + h - (row as f64 + 1.0) * row_h;
        let mut bins: Vec<Option<f64>> = vec![None; BINS];
        let mut seen = [false; BINS];
        for (k, &i) in idx.iter().enumerate() {
            let b = k * BINS / idx.len();
            seen[b] = true;
            if let Some(e) = r.elapsed_s[i] {
                bins[b] = Some(bins[b].map_or(e, |m: f64| m.min(e)));
            }
        }
        for b in 0..BINS {
            if !seen[b] {
                continue;
            }
            let color = match bins[b] {
                None => "#d0d0d0".to_string(),
                Some(e) => heat_color(e / r.cure_s.max(1e-9)),
            };
            svg.push_str(&format!(
                "<rect x=\"{:.2}\" y=\"{:.2}\" width=\"{:.2}\" height=\"{:.2}\" fill=\"{}\"/>\n",
                60.0 + b as f64 * w / BINS as f64,
                y,
                w / BINS as f64 + 0.05,
                row_h + 0.05,
                color
            ));
        }
        if row % (20.0 / row_h).ceil().max(1.0) as usize == 0 {
            svg.push_str(&format!(
                "<text x=\"4\" y=\"{:.1}\">L{}</text>\n",
                y + row_h,
                layer
            ));
        }
    }
    // Legend.
    let ly = h + 45.0;
    for k in 0..=30 {
        let ratio = k as f64 / 10.0;
        svg.push_str(&format!(
            "<rect x=\"{:.1}\" y=\"{:.1}\" width=\"10\" height=\"10\" fill=\"{}\"/>\n",
            60.0 + k as f64 * 10.0,
            ly,
            heat_color(ratio)
        ));
    }
    svg.push_str(&format!(
        "<text x=\"60\" y=\"{:.1}\">0</text><text x=\"155\" y=\"{:.1}\">cure</text><text x=\"355\" y=\"{:.1}\">3× cure</text><rect x=\"420\" y=\"{:.1}\" width=\"10\" height=\"10\" fill=\"#d0d0d0\"/><text x=\"435\" y=\"{:.1}\">nothing below</text>\n</svg>\n",
        ly + 24.0, ly + 24.0, ly + 24.0, ly, ly + 10.0
    ));
    svg
}

/// Red below 1, red→yellow→green from 1 to 3.
fn heat_color(ratio: f64) -> String {
    if ratio < 1.0 {
        let k = (ratio.max(0.0) * 120.0) as u8;
        return format!("rgb({},{},{})", 200 + k / 3, k / 3, k / 3);
    }
    let t = ((ratio - 1.0) / 2.0).clamp(0.0, 1.0);
    let (r, g) = if t < 0.5 {
        (255.0, 180.0 + 150.0 * t)
    } else {
        (
            255.0 * (1.0 - (t - 0.5) * 2.0) + 60.0 * (t - 0.5) * 2.0,
            255.0 - 75.0 * (t - 0.5) * 2.0,
        )
    };
    format!("rgb({:.0},{:.0},60)", r.min(255.0), g.min(255.0))
}
