//! From the grown stroke to a print: checking it never crosses itself, and stacking it into
//! layers as one continuous extrusion.

use super::PointGrid;
use glam::DVec2;
use rayon::prelude::*;

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
