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

use crate::additive::slice::{point_in_polygon, signed_area};
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

/// A polygon boundary with a signed-distance field for fast containment.
pub struct Boundary {
    /// The polygon (counter-clockwise).
    pub polygon: Vec<DVec2>,
    origin: DVec2,
    cell: f64,
    nx: usize,
    ny: usize,
    /// Signed distance at grid nodes: negative inside.
    sdf: Vec<f64>,
}

impl Boundary {
    /// Builds the boundary from a polygon (any orientation) with an SDF of about `res` cells
    /// across its larger side.
    pub fn new(mut polygon: Vec<DVec2>, res: usize) -> anyhow::Result<Boundary> {
        polygon.dedup_by(|a, b| a.distance_squared(*b) < 1e-18);
        if polygon.len() < 3 || polygon.iter().any(|p| !p.is_finite()) {
            anyhow::bail!("boundary needs at least 3 finite points");
        }
        if signed_area(&polygon) < 0.0 {
            polygon.reverse();
        }
        if signed_area(&polygon).abs() < 1e-9 {
            anyhow::bail!("boundary has zero area");
        }
        let (mut lo, mut hi) = (polygon[0], polygon[0]);
        for p in &polygon {
            lo = lo.min(*p);
            hi = hi.max(*p);
        }
        let size = (hi - lo).max_element();
        let cell = size / res.max(8) as f64;
        let lo = lo - DVec2::splat(2.0 * cell);
        let hi = hi + DVec2::splat(2.0 * cell);
        let nx = ((hi.x - lo.x) / cell).ceil() as usize + 1;
        let ny = ((hi.y - lo.y) / cell).ceil() as usize + 1;
        let poly = &polygon;
        let sdf: Vec<f64> = (0..nx * ny)
            .into_par_iter()
            .map(|k| {
                let p = lo + DVec2::new((k % nx) as f64, (k / nx) as f64) * cell;
                let d = dist_to_polygon(p, poly);
                if point_in_polygon(p, poly) {
                    -d
                } else {
                    d
                }
            })
            .collect();
        Ok(Boundary {
            polygon,
            origin: lo,
            cell,
            nx,
            ny,
            sdf,
        })
    }

    /// Signed distance (bilinear), negative inside; far outside the grid: large positive.
    pub fn distance(&self, p: DVec2) -> f64 {
        let g = (p - self.origin) / self.cell;
        if g.x.is_nan() || g.y.is_nan() || g.x < 0.0 || g.y < 0.0 {
            return f64::MAX;
        }
        let (ix, iy) = (g.x as usize, g.y as usize);
        if ix + 1 >= self.nx || iy + 1 >= self.ny {
            return f64::MAX;
        }
        let (fx, fy) = (g.x - ix as f64, g.y - iy as f64);
        let at = |x: usize, y: usize| self.sdf[y * self.nx + x];
        let a = at(ix, iy) * (1.0 - fx) + at(ix + 1, iy) * fx;
        let b = at(ix, iy + 1) * (1.0 - fx) + at(ix + 1, iy + 1) * fx;
        a * (1.0 - fy) + b * fy
    }

    /// Moves `p` inside so that it is at least `margin` from the boundary.
    pub fn contain(&self, p: DVec2, margin: f64) -> DVec2 {
        let d = self.distance(p);
        if d <= -margin {
            return p;
        }
        if d == f64::MAX {
            return self.nearest_inside(p, margin);
        }
        let h = self.cell * 0.5;
        let grad = DVec2::new(
            self.distance(p + DVec2::X * h) - self.distance(p - DVec2::X * h),
            self.distance(p + DVec2::Y * h) - self.distance(p - DVec2::Y * h),
        );
        if !grad.is_finite() || grad.length_squared() < 1e-24 {
            return self.nearest_inside(p, margin);
        }
        p - grad.normalize() * (d + margin)
    }

    fn nearest_inside(&self, p: DVec2, margin: f64) -> DVec2 {
        let n = self.polygon.len();
        let mut best = (f64::INFINITY, p, DVec2::ZERO);
        for i in 0..n {
            let (a, b) = (self.polygon[i], self.polygon[(i + 1) % n]);
            let q = closest_on_segment(p, a, b);
            let d = q.distance_squared(p);
            if d < best.0 {
                best = (d, q, (b - a).perp().normalize_or_zero());
            }
        }
        best.1 + best.2 * margin
    }

    /// Area of the polygon, mm².
    pub fn area_mm2(&self) -> f64 {
        signed_area(&self.polygon)
    }

    /// Centroid of the polygon's vertices.
    pub fn center(&self) -> DVec2 {
        self.polygon.iter().copied().sum::<DVec2>() / self.polygon.len() as f64
    }
}

fn closest_on_segment(p: DVec2, a: DVec2, b: DVec2) -> DVec2 {
    let ab = b - a;
    let l2 = ab.length_squared();
    if l2 == 0.0 {
        return a;
    }
    a + ab * ((p - a).dot(ab) / l2).clamp(0.0, 1.0)
}

fn dist_to_polygon(p: DVec2, poly: &[DVec2]) -> f64 {
    let n = poly.len();
    (0..n)
        .map(|i| closest_on_segment(p, poly[i], poly[(i + 1) % n]).distance(p))
        .fold(f64::INFINITY, f64::min)
}

/// Uniform grid over points, rebuilt by counting sort.
#[derive(Default)]
pub struct PointGrid {
    origin: DVec2,
    cell: f64,
    nx: usize,
    ny: usize,
    starts: Vec<u32>,
    order: Vec<u32>,
    cursor: Vec<u32>,
}

impl PointGrid {
    /// Rebuilds the grid over `pts` with cell size `cell`.
    pub fn rebuild(&mut self, pts: &[DVec2], cell: f64) {
        let (mut lo, mut hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
        for p in pts {
            lo = lo.min(*p);
            hi = hi.max(*p);
        }
        if pts.is_empty() {
            lo = DVec2::ZERO;
            hi = DVec2::ZERO;
        }
        self.origin = lo;
        self.cell = cell;
        self.nx = (((hi.x - lo.x) / cell) as usize + 1).min(1 << 14);
        self.ny = (((hi.y - lo.y) / cell) as usize + 1).min(1 << 14);
        let cells = self.nx * self.ny;
        self.starts.clear();
        self.starts.resize(cells + 1, 0);
        for p in pts {
            let c = self.cell_of(*p);
            self.starts[c + 1] += 1;
        }
        for i in 0..cells {
            self.starts[i + 1] += self.starts[i];
        }
        self.cursor.clear();
        self.cursor.extend_from_slice(&self.starts[..cells]);
        self.order.clear();
        self.order.resize(pts.len(), 0);
        for (k, p) in pts.iter().enumerate() {
            let c = self.cell_of(*p);
            let slot = self.cursor[c] as usize;
            self.order[slot] = k as u32;
            self.cursor[c] += 1;
        }
    }

    fn coords(&self, p: DVec2) -> (usize, usize) {
        let g = (p - self.origin) / self.cell;
        (
            (g.x.max(0.0) as usize).min(self.nx - 1),
            (g.y.max(0.0) as usize).min(self.ny - 1),
        )
    }

    fn cell_of(&self, p: DVec2) -> usize {
        let (x, y) = self.coords(p);
        y * self.nx + x
    }

    /// Calls `f(index)` for every point in the 3×3 cells around `p` (a superset of the points
    /// within one cell size).
    pub fn for_near(&self, p: DVec2, mut f: impl FnMut(usize)) {
        let (cx, cy) = self.coords(p);
        for y in cy.saturating_sub(1)..=(cy + 1).min(self.ny - 1) {
            for x in cx.saturating_sub(1)..=(cx + 1).min(self.nx - 1) {
                let c = y * self.nx + x;
                let (s, e) = (self.starts[c] as usize, self.starts[c + 1] as usize);
                for &k in &self.order[s..e] {
                    f(k as usize);
                }
            }
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

fn deepest_point(b: &Boundary) -> DVec2 {
    let mut best = (f64::INFINITY, b.center());
    for k in 0..b.sdf.len() {
        if b.sdf[k] < best.0 {
            let p = b.origin + DVec2::new((k % b.nx) as f64, (k / b.nx) as f64) * b.cell;
            best = (b.sdf[k], p);
        }
    }
    best.1
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

/// The first pair of non-adjacent edges of the closed (or open) polyline that intersect, or
/// `None` when the stroke is simple. Segments are indexed in a uniform grid of cell size
/// equal to the longest edge, so each edge is compared only with edges in its 3×3 cells.
pub fn verify_simple(nodes: &[DVec2], closed: bool) -> Option<(usize, usize)> {
    let n = nodes.len();
    if n < 4 {
        return None;
    }
    let edges = if closed { n } else { n - 1 };
    let seg = |i: usize| (nodes[i], nodes[(i + 1) % n]);
    let longest = (0..edges)
        .map(|i| {
            let (a, b) = seg(i);
            a.distance(b)
        })
        .fold(0.0, f64::max)
        .max(1e-9);
    let mids: Vec<DVec2> = (0..edges)
        .map(|i| {
            let (a, b) = seg(i);
            (a + b) * 0.5
        })
        .collect();
    let mut grid = PointGrid::default();
    grid.rebuild(&mids, longest);
    (0..edges).into_par_iter().find_map_first(|i| {
        let (a, b) = seg(i);
        let mut hit = None;
        grid.for_near(mids[i], |j| {
            if hit.is_some() || j <= i {
                return;
            }
            let adjacent = j == i + 1 || (closed && i == 0 && j == edges - 1);
            if adjacent {
                return;
            }
            let (c, d) = seg(j);
            if crate::additive::offset::segments_cross(a, b, c, d) {
                hit = Some((i, j));
            }
        });
        hit
    })
}

/// Built-in boundaries: `circle`, `square`, `blob`, of overall size `size_mm`, centred on
/// the origin.
pub fn builtin_boundary(name: &str, size_mm: f64) -> Option<Vec<DVec2>> {
    let r = size_mm / 2.0;
    match name {
        "circle" => Some(
            (0..256)
                .map(|i| DVec2::from_angle(i as f64 / 256.0 * std::f64::consts::TAU) * r)
                .collect(),
        ),
        "square" => Some(vec![
            DVec2::new(-r, -r),
            DVec2::new(r, -r),
            DVec2::new(r, r),
            DVec2::new(-r, r),
        ]),
        "blob" => Some(
            (0..256)
                .map(|i| {
                    let t = i as f64 / 256.0 * std::f64::consts::TAU;
                    let k = 1.0 + 0.18 * (3.0 * t).sin() + 0.1 * (5.0 * t + 1.0).cos();
                    DVec2::from_angle(t) * (r / 1.28 * k)
                })
                .collect(),
        ),
        _ => None,
    }
}

/// Reads a boundary file: an SVG (`<polygon points>`, `<polyline points>` or a `<path d>` made
/// of M/L/H/V/Z commands, absolute or relative; curves are refused; SVG's downward y is
/// flipped) or a text file with one `x y` or `x,y` point per line (`#` comments).
pub fn read_boundary(text: &str) -> anyhow::Result<Vec<DVec2>> {
    if text.contains("<svg") {
        return read_svg_boundary(text);
    }
    let mut pts = Vec::new();
    for (ln, line) in text.lines().enumerate() {
        let line = line.split('#').next().unwrap_or("").trim();
        if line.is_empty() {
            continue;
        }
        let nums: Vec<&str> = line
            .split(|c: char| c == ',' || c.is_whitespace())
            .filter(|s| !s.is_empty())
            .collect();
        if nums.len() != 2 {
            anyhow::bail!("line {}: expected `x y`, got `{line}`", ln + 1);
        }
        let x: f64 = nums[0]
            .parse()
            .map_err(|_| anyhow::anyhow!("line {}: bad number `{}`", ln + 1, nums[0]))?;
        let y: f64 = nums[1]
            .parse()
            .map_err(|_| anyhow::anyhow!("line {}: bad number `{}`", ln + 1, nums[1]))?;
        pts.push(DVec2::new(x, y));
    }
    Ok(pts)
}

fn attr<'a>(tag: &'a str, name: &str) -> Option<&'a str> {
    let key = format!(" {name}=\"");
    let start = tag.find(&key)? + key.len();
    let end = tag[start..].find('"')? + start;
    Some(&tag[start..end])
}

fn numbers(s: &str) -> anyhow::Result<Vec<f64>> {
    s.split(|c: char| c == ',' || c.is_whitespace())
        .filter(|t| !t.is_empty())
        .map(|t| {
            t.parse::<f64>()
                .map_err(|_| anyhow::anyhow!("bad number `{t}` in SVG"))
        })
        .collect()
}

fn read_svg_boundary(text: &str) -> anyhow::Result<Vec<DVec2>> {
    for tag_name in ["<polygon", "<polyline"] {
        if let Some(i) = text.find(tag_name) {
            let tag = &text[i..text[i..].find('>').map_or(text.len(), |e| i + e)];
            if let Some(p) = attr(tag, "points") {
                let v = numbers(p)?;
                return Ok(v.chunks_exact(2).map(|c| DVec2::new(c[0], -c[1])).collect());
            }
        }
    }
    let i = text
        .find("<path")
        .ok_or_else(|| anyhow::anyhow!("SVG has no <polygon>, <polyline> or <path>"))?;
    let tag = &text[i..text[i..].find('>').map_or(text.len(), |e| i + e)];
    let d = attr(tag, "d").ok_or_else(|| anyhow::anyhow!("<path> without d"))?;
    let mut pts = Vec::new();
    let mut cur = DVec2::ZERO;
    let mut cmd = 'M';
    let mut tokens = Vec::new();
    let mut num = String::new();
    for ch in d.chars() {
        if ch.is_ascii_alphabetic() && ch != 'e' && ch != 'E' {
            if !num.is_empty() {
                tokens.push(std::mem::take(&mut num));
            }
            tokens.push(ch.to_string());
        } else if ch == ',' || ch.is_whitespace() {
            if !num.is_empty() {
                tokens.push(std::mem::take(&mut num));
            }
        } else if ch == '-' && !num.is_empty() && !num.ends_with(['e', 'E']) {
            tokens.push(std::mem::take(&mut num));
            num.push(ch);
        } else {
            num.push(ch);
        }
    }
    if !num.is_empty() {
        tokens.push(num);
    }
    let mut k = 0;
    while k < tokens.len() {
        let t = &tokens[k];
        if let Some(c) = t.chars().next().filter(|c| c.is_ascii_alphabetic()) {
            cmd = c;
            k += 1;
            if c == 'Z' || c == 'z' {
                break;
            }
            continue;
        }
        let num_at = |k: usize| -> anyhow::Result<f64> {
            tokens
                .get(k)
                .and_then(|t| t.parse::<f64>().ok())
                .ok_or_else(|| anyhow::anyhow!("SVG path: expected a number at token {k}"))
        };
        match cmd {
            'M' | 'L' => {
                cur = DVec2::new(num_at(k)?, num_at(k + 1)?);
                k += 2;
            }
            'm' | 'l' => {
                cur += DVec2::new(num_at(k)?, num_at(k + 1)?);
                k += 2;
            }
            'H' => {
                cur.x = num_at(k)?;
                k += 1;
            }
            'h' => {
                cur.x += num_at(k)?;
                k += 1;
            }
            'V' => {
                cur.y = num_at(k)?;
                k += 1;
            }
            'v' => {
                cur.y += num_at(k)?;
                k += 1;
            }
            other => anyhow::bail!(
                "SVG path command `{other}` is not supported (only M, L, H, V, Z): flatten curves first"
            ),
        }
        pts.push(cur);
    }
    // SVG's y axis points down: flip so the shape is not mirrored on the bed.
    Ok(pts.into_iter().map(|p| DVec2::new(p.x, -p.y)).collect())
}

/// How the grown stroke is stacked and extruded.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StackParams {
    /// Number of layers.
    pub layers: usize,
    /// Layer height, mm.
    pub layer_mm: f64,
    /// Extruded line width, mm (cross-section = width × layer height).
    pub line_width_mm: f64,
    /// Head speed while extruding, mm/s.
    pub speed_mm_s: f64,
}

/// Stacks a closed stroke into layers as one continuous extrusion: layer 0 flat at one layer
/// height, every later layer a spiral ramp rising one layer height over the loop (vase mode),
/// so extrusion never stops, not even between layers. One travel reaches the start.
pub fn to_model(nodes: &[DVec2], offset: DVec2, s: &StackParams) -> crate::design::model::Model {
    use crate::design::model::{MarkerKind, Model, Step, Str};
    let mut m = Model::new([offset.x, offset.y]);
    let n = nodes.len();
    if n < 2 || s.layers == 0 {
        return m;
    }
    let cross = s.line_width_mm * s.layer_mm;
    // Arc-length fraction of every node along the closed loop.
    let mut acc = vec![0.0; n + 1];
    for i in 0..n {
        acc[i + 1] = acc[i] + nodes[i].distance(nodes[(i + 1) % n]);
    }
    let total = acc[n].max(1e-12);
    let at = |i: usize, z: f64| (nodes[i % n] + offset).extend(z);
    m.push(Step::Comment(format!(
        "differential growth: {n} nodes, {:.1} mm per layer, {} layers",
        total, s.layers
    )));
    m.push(Step::Travel {
        to: at(0, s.layer_mm),
        speed_mm_s: None,
    });
    for layer in 0..s.layers {
        let z0 = s.layer_mm * (layer as f64 + if layer == 0 { 1.0 } else { 0.0 });
        let rise = if layer == 0 { 0.0 } else { s.layer_mm };
        m.push(Step::Marker {
            kind: MarkerKind::Layer,
            z_mm: s.layer_mm * (layer as f64 + 1.0),
            height_mm: s.layer_mm,
        });
        if layer == 0 {
            m.push(Step::Type("Growth".into()));
        }
        for i in 0..n {
            let za = z0 + rise * acc[i] / total;
            let zb = z0 + rise * acc[i + 1] / total;
            m.push(Step::String(Str::line(
                at(i, za),
                at(i + 1, zb),
                cross,
                s.speed_mm_s,
            )));
        }
    }
    m
}
