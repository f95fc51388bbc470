//! The region growth fills: a polygon with a signed-distance field for fast containment, its
//! deepest point (where growth starts), and the built-in shapes.

use crate::additive::slice::{point_in_polygon, signed_area};
use glam::DVec2;
use rayon::prelude::*;

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

pub(super) fn deepest_point(b: &Boundary) -> DVec2 {
    let mut best = (f64::INFINITY, b.center());
    for k in 0..b.sdf.len() {
        if b.sdf[k] < best.0 {
            let p = b.origin + DVec2::new((k % b.nx) as f64, (k / b.nx) as f64) * b.cell;
            best = (b.sdf[k], p);
        }
    }
    best.1
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
