//! Nozzle and carriage against the base part.
//!
//! The print head is a solid of revolution about the vertical through the nozzle tip: a cone
//! (the nozzle) from the tip, radius `tip_radius_mm` widening at `cone_half_angle_deg`, up to
//! `cone_height_mm`; above it a cylinder (heater block, fan shroud, carriage) of radius
//! `carriage_radius_mm` and height `carriage_height_mm`. A base-part point `q` hits the head
//! at tip position `p` when its height above the tip `h = q.z − p.z` is within the head and
//! its horizontal distance to the tip is below the head's radius at `h`.
//!
//! The base mesh is sampled on its surface (vertices, edges and interior, every
//! `sample_mm` or closer) and indexed in a uniform XY grid; the toolpath is walked in steps of
//! at most `sample_mm`. The check is therefore exact up to `sample_mm`.

use super::stl::Mesh;
use glam::{DVec2, DVec3};

/// Geometry of the print head, mm and degrees.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct HeadModel {
    /// Radius of the flat nozzle tip.
    pub tip_radius_mm: f64,
    /// Half angle of the nozzle cone (0 = a vertical needle).
    pub cone_half_angle_deg: f64,
    /// Height of the cone above the tip (the nozzle's free length below the heater block).
    pub cone_height_mm: f64,
    /// Radius of the cylinder modelling heater block, shroud and carriage.
    pub carriage_radius_mm: f64,
    /// Height of that cylinder.
    pub carriage_height_mm: f64,
}

impl Default for HeadModel {
    /// An Ender-3-class hot end: E3D-style nozzle (45° taper) protruding 8 mm below a shroud
    /// of 20 mm radius.
    fn default() -> Self {
        HeadModel {
            tip_radius_mm: 0.5,
            cone_half_angle_deg: 45.0,
            cone_height_mm: 8.0,
            carriage_radius_mm: 20.0,
            carriage_height_mm: 60.0,
        }
    }
}

impl HeadModel {
    /// Radius of the head at height `h` above the tip, or `None` outside the head.
    pub fn radius_at(&self, h: f64) -> Option<f64> {
        if h < 0.0 || h > self.cone_height_mm + self.carriage_height_mm {
            None
        } else if h <= self.cone_height_mm {
            Some(self.tip_radius_mm + h * self.cone_half_angle_deg.to_radians().tan())
        } else {
            Some(self.carriage_radius_mm.max(self.cone_top_radius_mm()))
        }
    }

    /// Radius at the top of the cone.
    pub fn cone_top_radius_mm(&self) -> f64 {
        self.tip_radius_mm + self.cone_height_mm * self.cone_half_angle_deg.to_radians().tan()
    }

    /// Largest radius of the head.
    pub fn max_radius_mm(&self) -> f64 {
        self.carriage_radius_mm.max(self.cone_top_radius_mm())
    }

    /// True when the point `q` is inside the head whose tip is at `tip`.
    pub fn contains(&self, tip: DVec3, q: DVec3) -> bool {
        match self.radius_at(q.z - tip.z) {
            Some(r) => (q.truncate() - tip.truncate()).length_squared() < r * r,
            None => false,
        }
    }

    /// Largest tilt (degrees from horizontal) of an unbounded flat face that the head can
    /// print on with the first layer `layer_mm` thick: the face, rising uphill from a point
    /// `layer_mm` below the tip (measured along its normal), must stay below the head at every
    /// distance. Found by bisection (to 0.01°).
    pub fn max_face_tilt_deg(&self, layer_mm: f64) -> f64 {
        let clear = |theta: f64| {
            let (s, c) = theta.to_radians().sin_cos();
            let r_max = self.max_radius_mm();
            let steps = 2000;
            (1..=steps).all(|i| {
                let d = r_max * i as f64 / steps as f64;
                // Height of the face above the tip at horizontal distance d uphill.
                let face_h = d * s / c - layer_mm / c;
                // Lowest point of the head at radius d (just inside).
                let head_low = self.lowest_height_at_radius(d);
                face_h < head_low
            })
        };
        let (mut lo, mut hi) = (0.0, 90.0);
        if !clear(lo) {
            return 0.0;
        }
        while hi - lo > 0.01 {
            let mid = 0.5 * (lo + hi);
            if clear(mid) {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        lo
    }

    /// Lowest height above the tip at which the head reaches radius `d` (∞ beyond it).
    fn lowest_height_at_radius(&self, d: f64) -> f64 {
        if d < self.tip_radius_mm {
            return 0.0;
        }
        let t = self.cone_half_angle_deg.to_radians().tan();
        if d < self.cone_top_radius_mm() && t > 0.0 {
            return (d - self.tip_radius_mm) / t;
        }
        if d < self.carriage_radius_mm {
            return self.cone_height_mm;
        }
        f64::INFINITY
    }
}

/// The first place where the head hits the base part.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Collision {
    /// Index of the toolpath point (in the list handed to [`check_path`]) being approached.
    pub path_index: usize,
    /// Nozzle tip position at the hit (world, mm).
    pub tip: [f64; 3],
    /// The base-part point inside the head (world, mm).
    pub base_point: [f64; 3],
    /// "nozzle cone" or "carriage".
    pub part: &'static str,
}

/// Most surface samples [`BaseSamples::new`] takes (24 bytes each: 480 MB). A base part that
/// needs more at the chosen step is refused with a message naming a coarser step.
pub const MAX_BASE_SAMPLES: u64 = 20_000_000;

/// Surface samples of a mesh in a uniform XY grid.
pub struct BaseSamples {
    points: Vec<DVec3>,
    cell_mm: f64,
    origin: DVec2,
    nx: usize,
    ny: usize,
    /// Start offsets into `order` per cell (`nx·ny + 1`).
    starts: Vec<u32>,
    order: Vec<u32>,
}

impl BaseSamples {
    /// Samples the surface of `mesh` every `sample_mm` (at most) and indexes the samples.
    /// Errors when that takes more than [`MAX_BASE_SAMPLES`] samples.
    pub fn new(mesh: &Mesh, sample_mm: f64, cell_mm: f64) -> anyhow::Result<BaseSamples> {
        let s = sample_mm.max(0.01);
        let divisions = |[a, b, c]: [DVec3; 3]| -> usize {
            let longest = (b - a).length().max((c - b).length()).max((a - c).length());
            if longest.is_finite() {
                ((longest / s).ceil() as usize).clamp(1, 4000)
            } else {
                4000
            }
        };
        let total: u64 = mesh
            .triangles()
            .map(|t| {
                let n = divisions(t) as u64;
                (n + 1) * (n + 2) / 2
            })
            .fold(0u64, u64::saturating_add);
        if total > MAX_BASE_SAMPLES {
            anyhow::bail!(
                "the base part needs {total} surface samples at {s} mm (at most {MAX_BASE_SAMPLES}); use a coarser collision step"
            );
        }
        let mut points = Vec::with_capacity(total as usize);
        for [a, b, c] in mesh.triangles() {
            let n = divisions([a, b, c]);
            for i in 0..=n {
                for j in 0..=(n - i) {
                    let u = i as f64 / n as f64;
                    let v = j as f64 / n as f64;
                    points.push(a + (b - a) * u + (c - a) * v);
                }
            }
        }
        let cell = cell_mm.max(0.5);
        let (mut lo, mut hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
        for p in &points {
            lo = lo.min(p.truncate());
            hi = hi.max(p.truncate());
        }
        if points.is_empty() {
            lo = DVec2::ZERO;
            hi = DVec2::ZERO;
        }
        let nx = (((hi.x - lo.x) / cell).floor() as usize + 1).min(1 << 12);
        let ny = (((hi.y - lo.y) / cell).floor() as usize + 1).min(1 << 12);
        let cell_of = |p: DVec3| -> usize {
            let ix = (((p.x - lo.x) / cell) as usize).min(nx - 1);
            let iy = (((p.y - lo.y) / cell) as usize).min(ny - 1);
            iy * nx + ix
        };
        let mut starts = vec![0u32; nx * ny + 1];
        for p in &points {
            starts[cell_of(*p) + 1] += 1;
        }
        for i in 0..nx * ny {
            starts[i + 1] += starts[i];
        }
        let mut fill = starts.clone();
        let mut order = vec![0u32; points.len()];
        for (k, p) in points.iter().enumerate() {
            let c = cell_of(*p);
            order[fill[c] as usize] = k as u32;
            fill[c] += 1;
        }
        Ok(BaseSamples {
            points,
            cell_mm: cell,
            origin: lo,
            nx,
            ny,
            starts,
            order,
        })
    }

    /// Number of surface samples.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// True when there are no samples.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// The first sample inside the head with its tip at `tip`.
    pub fn hit(&self, head: &HeadModel, tip: DVec3) -> Option<DVec3> {
        let r = head.max_radius_mm();
        let lo = ((tip.truncate() - self.origin - DVec2::splat(r)) / self.cell_mm).floor();
        let hi = ((tip.truncate() - self.origin + DVec2::splat(r)) / self.cell_mm).floor();
        if hi.x < 0.0 || hi.y < 0.0 || lo.x >= self.nx as f64 || lo.y >= self.ny as f64 {
            return None;
        }
        let (x0, y0) = (lo.x.max(0.0) as usize, lo.y.max(0.0) as usize);
        let (x1, y1) = (
            (hi.x as usize).min(self.nx - 1),
            (hi.y as usize).min(self.ny - 1),
        );
        for iy in y0..=y1 {
            for ix in x0..=x1 {
                let c = iy * self.nx + ix;
                let (s, e) = (self.starts[c] as usize, self.starts[c + 1] as usize);
                for &k in &self.order[s..e] {
                    let q = self.points[k as usize];
                    if head.contains(tip, q) {
                        return Some(q);
                    }
                }
            }
        }
        None
    }
}

/// Walks the polyline `tips` (nozzle positions in order, travels included) in steps of at most
/// `step_mm` and returns the first collision with the base samples.
pub fn check_path(
    base: &BaseSamples,
    head: &HeadModel,
    tips: &[DVec3],
    step_mm: f64,
) -> Option<Collision> {
    let step = step_mm.max(0.01);
    let report = |i: usize, tip: DVec3, q: DVec3| Collision {
        path_index: i,
        tip: tip.to_array(),
        base_point: q.to_array(),
        part: if q.z - tip.z <= head.cone_height_mm {
            "nozzle cone"
        } else {
            "carriage"
        },
    };
    for (i, &p) in tips.iter().enumerate() {
        let prev = if i == 0 { p } else { tips[i - 1] };
        let n = (((p - prev).length() / step).ceil() as usize).max(1);
        for k in 1..=n {
            let tip = prev + (p - prev) * (k as f64 / n as f64);
            if let Some(q) = base.hit(head, tip) {
                return Some(report(i, tip, q));
            }
        }
    }
    None
}
