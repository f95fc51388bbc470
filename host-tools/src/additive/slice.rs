//! Plane sections of a triangle mesh, chained into closed, oriented loops.
//!
//! Robustness:
//! - **Vertices exactly on a plane**: a vertex with `z >= plane` counts as *above* (symbolic
//!   perturbation). Every triangle then crosses the plane on exactly zero or two edges, never
//!   through a vertex, so no zero-length or doubled segments appear.
//! - **Coplanar faces**: a face lying in the plane has all vertices "above" and contributes
//!   nothing; its neighbours close the section correctly.
//! - **Chaining by topology**: a segment end is keyed by the mesh edge it lies on, and the
//!   crossing point of an edge is computed from its vertices in a canonical order, so the two
//!   triangles sharing an edge produce bit-identical points and loops close exactly.
//! - **Small gaps** (unwelded or slightly open meshes): chains left open are joined end to end
//!   when their ends are closer than `gap_mm`; chains that still cannot close are reported.
//!
//! Loops come out oriented by nesting depth: outer boundaries counter-clockwise, holes
//! clockwise (even-odd rule), so material is always on the left.

use super::stl::Mesh;
use glam::DVec2;
use std::collections::HashMap;

/// One plane section.
#[derive(Debug, Clone, Default)]
pub struct Section {
    /// Height of the cutting plane (mesh coordinates, mm).
    pub z: f64,
    /// Closed loops (first point not repeated): outer CCW, holes CW.
    pub loops: Vec<Vec<DVec2>>,
    /// Chains that could not be closed even with the gap tolerance (dropped).
    pub open_chains: usize,
}

/// Signed area (positive counter-clockwise).
pub fn signed_area(poly: &[DVec2]) -> f64 {
    let n = poly.len();
    (0..n)
        .map(|i| poly[i].perp_dot(poly[(i + 1) % n]))
        .sum::<f64>()
        * 0.5
}

/// Even-odd point-in-polygon test.
pub fn point_in_polygon(p: DVec2, poly: &[DVec2]) -> bool {
    let n = poly.len();
    let mut inside = false;
    let mut j = n.wrapping_sub(1);
    for i in 0..n {
        let (a, b) = (poly[i], poly[j]);
        if (a.y > p.y) != (b.y > p.y) {
            let x = a.x + (p.y - a.y) * (b.x - a.x) / (b.y - a.y);
            if p.x < x {
                inside = !inside;
            }
        }
        j = i;
    }
    inside
}

/// Even-odd containment in a set of loops.
pub fn point_in_region(p: DVec2, loops: &[Vec<DVec2>]) -> bool {
    loops.iter().filter(|l| point_in_polygon(p, l)).count() % 2 == 1
}

/// Cuts `mesh` with the plane `z`; chains ends closer than `gap_mm` when topology fails.
pub fn slice_at(mesh: &Mesh, z: f64, gap_mm: f64) -> Section {
    let above = |i: usize| mesh.vertices[i].z >= z;
    // Segments as (edge key a, point a, edge key b, point b).
    let mut segs: Vec<([usize; 2], DVec2, [usize; 2], DVec2)> = Vec::new();
    for f in &mesh.faces {
        if f.iter().any(|&i| i >= mesh.vertices.len()) {
            continue;
        }
        let mut ends: [([usize; 2], DVec2); 2] = [([0, 0], DVec2::ZERO); 2];
        let mut n = 0;
        for k in 0..3 {
            let (u, v) = (f[k], f[(k + 1) % 3]);
            if above(u) != above(v) && n < 2 {
                let (lo, hi) = (u.min(v), u.max(v));
                let (p, q) = (mesh.vertices[lo], mesh.vertices[hi]);
                let t = (z - p.z) / (q.z - p.z);
                ends[n] = ([lo, hi], (p + (q - p) * t).truncate());
                n += 1;
            }
        }
        if n == 2 {
            segs.push((ends[0].0, ends[0].1, ends[1].0, ends[1].1));
        }
    }
    let mut by_edge: HashMap<[usize; 2], Vec<usize>> = HashMap::with_capacity(segs.len() * 2);
    for (i, s) in segs.iter().enumerate() {
        by_edge.entry(s.0).or_default().push(i);
        by_edge.entry(s.2).or_default().push(i);
    }
    let mut used = vec![false; segs.len()];
    let mut closed: Vec<Vec<DVec2>> = Vec::new();
    let mut open: Vec<Vec<DVec2>> = Vec::new();
    for start in 0..segs.len() {
        if used[start] {
            continue;
        }
        used[start] = true;
        let (k0, p0, mut key, p1) = segs[start];
        let mut pts = vec![p0, p1];
        let mut is_closed = false;
        loop {
            if key == k0 {
                is_closed = true;
                pts.pop(); // the closing point equals the first
                break;
            }
            let next = by_edge
                .get(&key)
                .and_then(|v| v.iter().copied().find(|&i| !used[i]));
            let Some(i) = next else { break };
            used[i] = true;
            let s = segs[i];
            if s.0 == key {
                key = s.2;
                pts.push(s.3);
            } else {
                key = s.0;
                pts.push(s.1);
            }
        }
        if is_closed {
            closed.push(pts);
        } else {
            open.push(pts);
        }
    }
    let open_chains = join_open_chains(&mut open, &mut closed, gap_mm);
    let mut loops: Vec<Vec<DVec2>> = closed
        .into_iter()
        .map(dedupe)
        .filter(|l| l.len() >= 3 && signed_area(l).abs() > 1e-12)
        .collect();
    orient_by_nesting(&mut loops);
    Section {
        z,
        loops,
        open_chains,
    }
}

/// Joins open chains whose ends are within `gap_mm`; closes a chain whose ends meet. Returns
/// the number of chains left open (they are dropped).
fn join_open_chains(
    open: &mut Vec<Vec<DVec2>>,
    closed: &mut Vec<Vec<DVec2>>,
    gap_mm: f64,
) -> usize {
    let gap2 = gap_mm * gap_mm;
    let mut left_open = 0;
    while let Some(mut chain) = open.pop() {
        while let (Some(&first), Some(&last)) = (chain.first(), chain.last()) {
            if chain.len() >= 3 && first.distance_squared(last) <= gap2 {
                closed.push(std::mem::take(&mut chain));
                break;
            }
            // Nearest other chain end to our last point.
            let mut best: Option<(usize, bool, f64)> = None;
            for (i, c) in open.iter().enumerate() {
                for (rev, p) in [(false, c.first()), (true, c.last())] {
                    if let Some(p) = p {
                        let d = p.distance_squared(last);
                        if d <= gap2 && best.is_none_or(|b| d < b.2) {
                            best = Some((i, rev, d));
                        }
                    }
                }
            }
            let Some((i, rev, _)) = best else { break };
            let mut other = open.swap_remove(i);
            if rev {
                other.reverse();
            }
            chain.extend(other);
        }
        if !chain.is_empty() {
            left_open += 1;
        }
    }
    left_open
}

/// Removes consecutive (and wrap-around) duplicate points and points on a straight line
/// between their neighbours (a section through a quad's diagonal yields such points).
fn dedupe(mut l: Vec<DVec2>) -> Vec<DVec2> {
    l.dedup_by(|a, b| a.distance_squared(*b) < 1e-18);
    while l.len() > 1 && l[0].distance_squared(l[l.len() - 1]) < 1e-18 {
        l.pop();
    }
    let mut changed = true;
    while changed && l.len() > 3 {
        changed = false;
        let n = l.len();
        let keep: Vec<bool> = (0..n)
            .map(|i| {
                let (a, b, c) = (l[(i + n - 1) % n], l[i], l[(i + 1) % n]);
                let cross = (b - a).perp_dot(c - b);
                cross.abs() > 1e-12 * (b - a).length() * (c - b).length()
                    || (b - a).dot(c - b) < 0.0
            })
            .collect();
        if keep.iter().any(|k| !k) {
            // Drop every other collinear point per pass so neighbours stay valid.
            let mut out = Vec::with_capacity(n);
            let mut dropped_prev = false;
            for (i, p) in l.iter().enumerate() {
                if !keep[i] && !dropped_prev {
                    dropped_prev = true;
                    changed = true;
                } else {
                    out.push(*p);
                    dropped_prev = false;
                }
            }
            l = out;
        }
    }
    l
}

/// Orients loops: even nesting depth counter-clockwise, odd depth clockwise.
pub fn orient_by_nesting(loops: &mut [Vec<DVec2>]) {
    let depth: Vec<usize> = (0..loops.len())
        .map(|i| {
            let p = loops[i][0];
            (0..loops.len())
                .filter(|&j| j != i && point_in_polygon(p, &loops[j]))
                .count()
        })
        .collect();
    for (l, d) in loops.iter_mut().zip(depth) {
        let ccw = signed_area(l) > 0.0;
        if ccw != (d % 2 == 0) {
            l.reverse();
        }
    }
}

/// Slices the mesh at the middle of every layer of height `layer_mm`, from its lowest point
/// up: plane `k` at `z_min + (k + ½)·layer_mm`.
pub fn slice_layers(mesh: &Mesh, layer_mm: f64, gap_mm: f64) -> Vec<Section> {
    let Some((lo, hi)) = mesh.bbox() else {
        return Vec::new();
    };
    if layer_mm.is_nan() || layer_mm <= 0.0 {
        return Vec::new();
    }
    let n = ((hi.z - lo.z) / layer_mm).floor() as usize;
    (0..n)
        .map(|k| slice_at(mesh, lo.z + (k as f64 + 0.5) * layer_mm, gap_mm))
        .collect()
}
