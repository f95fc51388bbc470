//! Walls (perimeters) and infill of one layer, in the layer's own 2D coordinates.
//!
//! Wall `k` (0 = outermost) is the section offset `(k + ½)·w` into the material, `w` the line
//! width. Infill lines run at ±45° alternating per layer, spaced `w · 100 / infill%` (100 % =
//! solid), clipped by the even-odd rule against the region left inside the walls (with a
//! quarter line width of overlap so infill bonds to the innermost wall) and ordered
//! boustrophedon to keep travels short.

use super::offset::offset_region;
use glam::DVec2;

/// Parameters of the layer fill.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FillParams {
    /// Extrusion line width, mm.
    pub line_width_mm: f64,
    /// Number of walls (perimeters).
    pub walls: usize,
    /// Infill density in per cent (0 = hollow, 100 = solid).
    pub infill_percent: f64,
    /// Angle of infill lines on even layers, degrees (odd layers add 90°).
    pub infill_angle_deg: f64,
    /// Number of bottom and top layers filled solid whatever `infill_percent` says.
    pub solid_layers: usize,
}

impl Default for FillParams {
    fn default() -> Self {
        FillParams {
            line_width_mm: 0.45,
            walls: 2,
            infill_percent: 20.0,
            infill_angle_deg: 45.0,
            solid_layers: 3,
        }
    }
}

/// What a path is, for comments (`;TYPE:`) and speeds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PathKind {
    /// Wall number `k`, 0 the outermost.
    Wall(usize),
    /// Infill line.
    Infill,
}

/// An extruded path in layer coordinates.
#[derive(Debug, Clone, PartialEq)]
pub struct LayerPath {
    /// Role of the path.
    pub kind: PathKind,
    /// Points; a closed path repeats its first point at the end.
    pub points: Vec<DVec2>,
}

/// Fills one layer: walls from the outside in, then infill. `layer` and `layer_count` choose
/// the infill angle and the solid bottom/top layers.
pub fn fill_layer(
    loops: &[Vec<DVec2>],
    p: &FillParams,
    layer: usize,
    layer_count: usize,
) -> Vec<LayerPath> {
    let w = p.line_width_mm;
    let mut out = Vec::new();
    if w.is_nan() || w <= 0.0 {
        return out;
    }
    for k in 0..p.walls {
        for l in offset_region(loops, (k as f64 + 0.5) * w) {
            let mut pts = l.clone();
            pts.push(l[0]);
            out.push(LayerPath {
                kind: PathKind::Wall(k),
                points: pts,
            });
        }
    }
    let solid = layer < p.solid_layers || layer + p.solid_layers >= layer_count;
    let percent = if solid && p.infill_percent > 0.0 {
        100.0
    } else {
        p.infill_percent.clamp(0.0, 100.0)
    };
    if percent > 0.0 {
        let inset = if p.walls == 0 {
            0.5 * w
        } else {
            p.walls as f64 * w + 0.25 * w
        };
        let region = offset_region(loops, inset);
        let angle = p.infill_angle_deg + if layer % 2 == 1 { 90.0 } else { 0.0 };
        for seg in hatch(&region, w * 100.0 / percent, angle) {
            out.push(LayerPath {
                kind: PathKind::Infill,
                points: vec![seg[0], seg[1]],
            });
        }
    }
    out
}

/// Parallel lines `spacing` apart at `angle_deg`, clipped to the region (even-odd), ordered
/// boustrophedon.
pub fn hatch(region: &[Vec<DVec2>], spacing: f64, angle_deg: f64) -> Vec<[DVec2; 2]> {
    let mut out = Vec::new();
    if region.is_empty() || spacing.is_nan() || spacing <= 0.0 {
        return out;
    }
    let rot = DVec2::from_angle(angle_deg.to_radians());
    let unrot = DVec2::new(rot.x, -rot.y);
    // Rotate the region so the lines are horizontal.
    let rr: Vec<Vec<DVec2>> = region
        .iter()
        .map(|l| l.iter().map(|p| unrot.rotate(*p)).collect())
        .collect();
    let (mut y0, mut y1) = (f64::INFINITY, f64::NEG_INFINITY);
    for p in rr.iter().flatten() {
        y0 = y0.min(p.y);
        y1 = y1.max(p.y);
    }
    let count = ((y1 - y0) / spacing).floor() as usize + 1;
    let mut xs = Vec::new();
    for k in 0..count {
        let y = y0 + spacing * (k as f64 + 0.5);
        if y >= y1 {
            break;
        }
        xs.clear();
        for l in &rr {
            let n = l.len();
            for i in 0..n {
                let (a, b) = (l[i], l[(i + 1) % n]);
                if (a.y > y) != (b.y > y) {
                    xs.push(a.x + (y - a.y) * (b.x - a.x) / (b.y - a.y));
                }
            }
        }
        xs.sort_by(f64::total_cmp);
        let mut row: Vec<[DVec2; 2]> = xs
            .chunks_exact(2)
            .filter(|c| c[1] - c[0] > 1e-9)
            .map(|c| [DVec2::new(c[0], y), DVec2::new(c[1], y)])
            .collect();
        if k % 2 == 1 {
            row.reverse();
            for s in &mut row {
                s.swap(0, 1);
            }
        }
        out.extend(row);
    }
    out.into_iter()
        .map(|[a, b]| [rot.rotate(a), rot.rotate(b)])
        .collect()
}
