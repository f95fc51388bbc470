//! Differential growth in 2D (SPEC §4, Nagura et al.): a closed curve inside a boundary
//! polygon relaxes and grows until it fills the region with one continuous stroke.
//!
//! Per iteration every node moves by the sum of (lengths in units of `u = 1.6·s`, see
//! [`GrowParams::repulsion_radius_factor`])
//! - **attraction** to its two neighbours on the curve (only while farther than `0.2·u`),
//! - **repulsion** from every node within the radius `u` (linear falloff),
//! - **alignment** towards the midpoint of its neighbours (smoothing),
//! - a tiny deterministic jitter that breaks symmetry,
//!
//! clamped to `max_step_frac·u` (0.05), then pushed back inside the boundary (a signed-distance field
//! of the polygon, margin `u/2`), and every edge longer than `0.5·u` is split at its midpoint.
//! `s` is the stroke spacing: `line_width / density`, so `density` (0 < d ≤ 1, the covered
//! fraction of the area) sets the spacing continuously from coarse to solid.
//!
//! **Neighbour search**: a uniform grid with cell size `s`, rebuilt every iteration by a
//! counting sort (O(n), no allocation after warm-up). Every node moves every iteration, so a
//! tree (kiddo/rstar) would be rebuilt from scratch each time at O(n log n); the grid's fixed
//! radius query touches exactly 3×3 cells. Forces are computed in parallel with rayon.
//!
//! The result is verified after every run ([`verify_simple`]): no two non-adjacent edges of
//! the stroke intersect (segments indexed in a uniform grid).
//!
//! This module runs the growth; `boundary` (the region and its distance field), `boundary_file`
//! (reading one), `grid` (neighbour search) and `stack` (checking and stacking the stroke)
//! hold the rest.

mod boundary;
mod boundary_file;
mod grid;
mod stack;

pub use boundary::{builtin_boundary, Boundary};
pub use boundary_file::read_boundary;
pub use grid::PointGrid;
pub use stack::{to_model, verify_simple, StackParams};

use boundary::deepest_point;
use glam::DVec2;
use rayon::prelude::*;

/// Growth parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GrowParams {
    /// Stroke spacing `s`, mm: repulsion radius and distance between neighbouring strokes.
    pub spacing_mm: f64,
    /// Stop when the curve has this many nodes.
    pub max_nodes: usize,
    /// Stop after this many iterations.
    pub max_iterations: usize,
    /// Region full: stop when the node count grew by less than 1 % over this many iterations.
    pub stall_iterations: usize,
    /// Attraction gain.
    pub attraction: f64,
    /// Repulsion gain.
    pub repulsion: f64,
    /// Alignment gain.
    pub alignment: f64,
    /// Largest move of a node per iteration, as a fraction of the spacing.
    pub max_step_frac: f64,
    /// Scale of the dynamics (repulsion radius) as a multiple of the spacing. The relaxed
    /// curve packs tighter than the repulsion radius (attraction and alignment pull it
    /// together, measured: mean spacing ≈ 0.62 × radius), so the default 1.6 makes a filled
    /// region's mean spacing (area ÷ stroke length) come out near `spacing_mm`.
    pub repulsion_radius_factor: f64,
    /// Seed of the jitter.
    pub seed: u64,
}

impl GrowParams {
    /// Defaults for a spacing `s`.
    pub fn with_spacing(spacing_mm: f64) -> GrowParams {
        GrowParams {
            spacing_mm,
            max_nodes: 50_000,
            max_iterations: 20_000,
            stall_iterations: 200,
            attraction: 0.2,
            repulsion: 0.5,
            alignment: 0.45,
            max_step_frac: 0.05,
            repulsion_radius_factor: 1.6,
            seed: 1,
        }
    }
}

/// Outcome of a growth run.
#[derive(Debug, Clone)]
pub struct Growth {
    /// The stroke (closed: the last node connects to the first).
    pub nodes: Vec<DVec2>,
    /// Iterations run.
    pub iterations: usize,
    /// Why it stopped.
    pub stop: &'static str,
}

/// Grows a closed curve (a small circle at the boundary's centre, radius `2·s`) inside the
/// boundary. `progress(nodes)` is called every iteration.
pub fn grow(
    boundary: &Boundary,
    p: &GrowParams,
    mut progress: impl FnMut(usize),
) -> anyhow::Result<Growth> {
    let s = p.spacing_mm;
    if !s.is_finite() || s <= 0.0 {
        anyhow::bail!("spacing must be a positive number");
    }
    // Every length of the dynamics scales with the repulsion radius `rr`.
    let rr = s * p.repulsion_radius_factor.clamp(0.5, 4.0);
    let s = rr;
    let margin = 0.5 * s;
    let c = if boundary.distance(boundary.center()) < -2.5 * s {
        boundary.center()
    } else {
        // A concave boundary whose vertex centroid is outside: start at its deepest grid point.
        deepest_point(boundary)
    };
    if boundary.distance(c) > -2.5 * s {
        anyhow::bail!("the boundary is too small for a stroke spacing of {s} mm");
    }
    let start_r = 2.0 * s;
    let n0 = ((std::f64::consts::TAU * start_r) / (0.4 * s)).ceil() as usize;
    let mut nodes: Vec<DVec2> = (0..n0)
        .map(|i| c + DVec2::from_angle(i as f64 / n0 as f64 * std::f64::consts::TAU) * start_r)
        .collect();
    let max_edge = 0.5 * s;
    let min_attract = 0.2 * s;
    let max_step = p.max_step_frac.clamp(0.001, 0.25) * s;
    let mut grid = PointGrid::default();
    let mut next: Vec<DVec2> = Vec::new();
    let mut split: Vec<DVec2> = Vec::new();
    let mut last_growth = 0;
    let mut checkpoint_n = nodes.len();
    let mut it = 0;
    let stop = loop {
        if nodes.len() >= p.max_nodes {
            break "node target reached";
        }
        if it >= p.max_iterations {
            break "iteration limit";
        }
        // Full when the curve grew by less than 1 % over the last `stall_iterations`.
        if it - last_growth >= p.stall_iterations.max(1) {
            if (nodes.len() as f64) < checkpoint_n as f64 * 1.01 {
                break "region full";
            }
            checkpoint_n = nodes.len();
            last_growth = it;
        }
        it += 1;
        grid.rebuild(&nodes, rr);
        let n = nodes.len();
        let cur = &nodes;
        let g = &grid;
        let iter_seed = p
            .seed
            .wrapping_mul(0x9E37_79B9_7F4A_7C15)
            .wrapping_add(it as u64);
        next.clear();
        next.par_extend((0..n).into_par_iter().map(|i| {
            let pi = cur[i];
            let prev = cur[(i + n - 1) % n];
            let nxt = cur[(i + 1) % n];
            let mut f = DVec2::ZERO;
            for q in [prev, nxt] {
                let d = q - pi;
                let l = d.length();
                if l > min_attract {
                    f += d / l * (l - min_attract) * p.attraction;
                }
            }
            let mut rep = DVec2::ZERO;
            g.for_near(pi, |j| {
                if j != i {
                    let d = pi - cur[j];
                    let l2 = d.length_squared();
                    if l2 < rr * rr && l2 > 1e-24 {
                        let l = l2.sqrt();
                        rep += d / l * ((rr - l) / rr);
                    }
                }
            });
            f += rep * (p.repulsion * s);
            f += ((prev + nxt) * 0.5 - pi) * p.alignment;
            f += jitter(iter_seed, i) * (0.01 * s);
            let l = f.length();
            if l > max_step {
                f *= max_step / l;
            }
            boundary.contain(pi + f, margin)
        }));
        // Split long edges.
        split.clear();
        let n = next.len();
        for i in 0..n {
            let a = next[i];
            let b = next[(i + 1) % n];
            split.push(a);
            if a.distance_squared(b) > max_edge * max_edge {
                split.push((a + b) * 0.5);
            }
        }
        std::mem::swap(&mut nodes, &mut split);
        progress(nodes.len());
    };
    remove_spikes(&mut nodes);
    Ok(Growth {
        nodes,
        iterations: it,
        stop,
    })
}

/// Removes nodes where the curve folds back on itself (the direction turns by more than
/// about 155°): such spikes are the only self-contacts the dynamics leave, at the boundary.
pub fn remove_spikes(nodes: &mut Vec<DVec2>) {
    let mut changed = true;
    while changed && nodes.len() > 3 {
        changed = false;
        let n = nodes.len();
        let mut keep = vec![true; n];
        let mut i = 0;
        while i < n {
            let (a, b, c) = (nodes[(i + n - 1) % n], nodes[i], nodes[(i + 1) % n]);
            let (u, v) = (b - a, c - b);
            if u.dot(v) < -0.9 * u.length() * v.length() {
                keep[i] = false;
                changed = true;
                i += 2; // never drop two neighbours in one pass
            } else {
                i += 1;
            }
        }
        if changed {
            let mut k = 0;
            nodes.retain(|_| {
                k += 1;
                keep[k - 1]
            });
        }
    }
}

/// A small pseudo-random unit-square vector from (seed, index): SplitMix64.
fn jitter(seed: u64, i: usize) -> DVec2 {
    let mut z = seed ^ (i as u64).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    let mut next = || {
        z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut x = z;
        x = (x ^ (x >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        x = (x ^ (x >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        x ^= x >> 31;
        (x >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    DVec2::new(next(), next())
}
