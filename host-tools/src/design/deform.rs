//! Deformations (Kanada): `deform_xyz(fd, fc, fv)` maps every string's end points with `fd`,
//! its cross-section with `fc` and its speed with `fv`; `deform_cylinder` does the same in
//! cylindrical coordinates `(r, θ, z)` about the model's axis (θ in radians). Only end points
//! move, so strings stay straight; with a chord tolerance, strings are first subdivided until
//! the deformed string follows the deformation within the tolerance: a string longer than
//! [`PROBE_SPACING_MM`] is probed every (at most) that distance, and pieces are halved until
//! every probe lies within the tolerance of the deformed chord; pieces between neighbouring
//! probes are then halved while their deformed midpoint is off. Features of the deformation
//! shorter than the probe spacing can still be missed between probes.
//!
//! Bounds: a tolerance below [`MIN_TOLERANCE_MM`] is an error (the writer resolves 1 µm), and
//! a deformation that would write more than [`MAX_STRINGS`] strings is an error.
//!
//! `fc` and `fv` receive the value and the *original* coordinates of the string's midpoint.
//! Built-ins: [`cup_to_dish`], [`helix_to_sphere`], [`heart_dish`], [`twisted_vase`].

use crate::design::model::{Model, Step, Str};
use glam::DVec3;
use std::f64::consts::PI;

/// Deepest recursive subdivision (2^12 pieces per string at most).
pub const MAX_SUBDIVISION_DEPTH: u32 = 12;
/// Longest distance between probes of the tolerance test along one string, mm.
pub const PROBE_SPACING_MM: f64 = 1.0;
/// Smallest chord tolerance, mm.
pub const MIN_TOLERANCE_MM: f64 = 1e-4;
/// Most strings a deformation may produce.
pub const MAX_STRINGS: usize = 20_000_000;

/// Deformation errors.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum DeformError {
    /// A user function returned a non-finite or invalid value.
    #[error("deformation produced an invalid value at ({x:.3}, {y:.3}, {z:.3}): {msg}")]
    Invalid {
        /// X of the original point, mm.
        x: f64,
        /// Y of the original point, mm.
        y: f64,
        /// Z of the original point, mm.
        z: f64,
        /// What was wrong.
        msg: String,
    },
    /// A user (script) function failed.
    #[error("{0}")]
    Callback(String),
    /// The deformation would exceed a documented bound.
    #[error("{0}")]
    Limit(String),
}

/// A point map that may fail (script callbacks do).
pub type PointFn<'a> = dyn FnMut(DVec3) -> Result<DVec3, DeformError> + 'a;
/// A value map `(value, original point) -> value` that may fail.
pub type ValueFn<'a> = dyn FnMut(f64, DVec3) -> Result<f64, DeformError> + 'a;

fn invalid(p: DVec3, msg: impl Into<String>) -> DeformError {
    DeformError::Invalid {
        x: p.x,
        y: p.y,
        z: p.z,
        msg: msg.into(),
    }
}

/// Deforms in Cartesian coordinates (fallible callbacks; the general form).
pub fn deform_xyz_try(
    model: Model,
    fd: &mut PointFn<'_>,
    fc: &mut ValueFn<'_>,
    fv: &mut ValueFn<'_>,
    chord_tol_mm: Option<f64>,
) -> Result<Model, DeformError> {
    let tol = chord_tol_mm.filter(|t| t.is_finite() && *t > 0.0);
    if let Some(t) = tol.filter(|t| *t < MIN_TOLERANCE_MM) {
        return Err(DeformError::Limit(format!(
            "chord tolerance {t} mm is below {MIN_TOLERANCE_MM} mm"
        )));
    }
    let model = model.arcs_to_lines(tol.unwrap_or(0.01));
    let mut out = Model {
        steps: Vec::with_capacity(model.steps.len()),
        axis_xy: model.axis_xy,
        emission: model.emission,
    };
    let map = |p: DVec3, fd: &mut PointFn<'_>| -> Result<DVec3, DeformError> {
        let q = fd(p)?;
        if q.is_finite() {
            Ok(q)
        } else {
            Err(invalid(p, format!("point mapped to {q:?}")))
        }
    };
    let mut pieces = Vec::new();
    // Consecutive strings share end points: map each point once.
    let mut last: Option<(DVec3, DVec3)> = None;
    for step in model.steps {
        match step {
            Step::String(s) => {
                let a = match last {
                    Some((p, q)) if p == s.start => q,
                    _ => map(s.start, fd)?,
                };
                let b = map(s.end, fd)?;
                last = Some((s.end, b));
                pieces.clear();
                subdivide_string(s.start, s.end, a, b, tol, fd, &mut pieces)?;
                if out.steps.len() + pieces.len() > MAX_STRINGS {
                    return Err(DeformError::Limit(format!(
                        "the deformation makes more than {MAX_STRINGS} strings; use a larger tolerance"
                    )));
                }
                for &(p0, p1, q0, q1) in &pieces {
                    let mid = 0.5 * (p0 + p1);
                    let c = fc(s.cross_mm2, mid)?;
                    let v = fv(s.speed_mm_s, mid)?;
                    if !(c.is_finite() && c >= 0.0) {
                        return Err(invalid(mid, format!("cross-section mapped to {c}")));
                    }
                    if !(v.is_finite() && v > 0.0) {
                        return Err(invalid(mid, format!("speed mapped to {v}")));
                    }
                    out.steps.push(Step::String(Str::line(q0, q1, c, v)));
                }
            }
            Step::Travel { to, speed_mm_s } => out.steps.push(Step::Travel {
                to: map(to, fd)?,
                speed_mm_s,
            }),
            other => out.steps.push(other),
        }
    }
    fix_markers(&mut out);
    Ok(out)
}

type Piece = (DVec3, DVec3, DVec3, DVec3);

/// Subdivides one string (see the module docs): probes every [`PROBE_SPACING_MM`], halves
/// probe ranges until every probe inside is within `tol` of the chord, then refines pieces
/// between neighbouring probes by their midpoints.
fn subdivide_string(
    p0: DVec3,
    p1: DVec3,
    q0: DVec3,
    q1: DVec3,
    tol: Option<f64>,
    fd: &mut PointFn<'_>,
    out: &mut Vec<Piece>,
) -> Result<(), DeformError> {
    let Some(t) = tol else {
        out.push((p0, p1, q0, q1));
        return Ok(());
    };
    let max_n = 1usize << MAX_SUBDIVISION_DEPTH;
    let n = ((p0.distance(p1) / PROBE_SPACING_MM).ceil() as usize).clamp(1, max_n);
    if n <= 2 {
        // One probe at most: the midpoint test alone (the probe is the midpoint).
        return subdivide(p0, p1, q0, q1, tol, 0, fd, out);
    }
    let ps: Vec<DVec3> = (0..=n).map(|i| p0.lerp(p1, i as f64 / n as f64)).collect();
    let mut qs = Vec::with_capacity(n + 1);
    qs.push(q0);
    for &p in &ps[1..n] {
        let q = fd(p)?;
        if !q.is_finite() {
            return Err(invalid(p, format!("point mapped to {q:?}")));
        }
        qs.push(q);
    }
    qs.push(q1);
    // Depth left for the midpoint refinement between neighbouring probes.
    let depth = MAX_SUBDIVISION_DEPTH.saturating_sub(n.next_power_of_two().trailing_zeros());
    let mut stack = vec![(0usize, n)];
    // Ranges are taken from the stack in order: push the right half first.
    while let Some((i, j)) = stack.pop() {
        if j == i + 1 {
            subdivide(ps[i], ps[j], qs[i], qs[j], tol, depth, fd, out)?;
            continue;
        }
        let off = (i + 1..j).any(|k| {
            let f = (k - i) as f64 / (j - i) as f64;
            qs[k].distance(qs[i].lerp(qs[j], f)) > t
        });
        if off {
            let m = (i + j) / 2;
            stack.push((m, j));
            stack.push((i, m));
        } else {
            out.push((ps[i], ps[j], qs[i], qs[j]));
        }
    }
    Ok(())
}

#[allow(clippy::too_many_arguments)]
fn subdivide(
    p0: DVec3,
    p1: DVec3,
    q0: DVec3,
    q1: DVec3,
    tol: Option<f64>,
    depth: u32,
    fd: &mut PointFn<'_>,
    out: &mut Vec<Piece>,
) -> Result<(), DeformError> {
    if let Some(t) = tol {
        if depth < MAX_SUBDIVISION_DEPTH {
            let pm = 0.5 * (p0 + p1);
            let qm = fd(pm)?;
            if !qm.is_finite() {
                return Err(invalid(pm, format!("point mapped to {qm:?}")));
            }
            if qm.distance(0.5 * (q0 + q1)) > t {
                subdivide(p0, pm, q0, qm, tol, depth + 1, fd, out)?;
                return subdivide(pm, p1, qm, q1, tol, depth + 1, fd, out);
            }
        }
    }
    out.push((p0, p1, q0, q1));
    Ok(())
}

/// After a deformation, markers take the height of the string that follows them and the
/// thickness the distance to the previous marker.
fn fix_markers(m: &mut Model) {
    let mut next_z: Option<f64> = None;
    for i in (0..m.steps.len()).rev() {
        match &mut m.steps[i] {
            Step::String(s) => next_z = Some(s.start.z),
            Step::Marker { z_mm, .. } => {
                if let Some(z) = next_z {
                    *z_mm = z;
                }
            }
            _ => {}
        }
    }
    let mut prev: Option<f64> = None;
    for s in &mut m.steps {
        if let Step::Marker {
            z_mm, height_mm, ..
        } = s
        {
            if let Some(p) = prev {
                if *z_mm > p {
                    *height_mm = *z_mm - p;
                }
            }
            prev = Some(*z_mm);
        }
    }
}

/// Deforms in Cartesian coordinates with infallible closures.
pub fn deform_xyz(
    model: Model,
    mut fd: impl FnMut(DVec3) -> DVec3,
    mut fc: impl FnMut(f64, DVec3) -> f64,
    mut fv: impl FnMut(f64, DVec3) -> f64,
    chord_tol_mm: Option<f64>,
) -> Result<Model, DeformError> {
    deform_xyz_try(
        model,
        &mut |p| Ok(fd(p)),
        &mut |c, p| Ok(fc(c, p)),
        &mut |v, p| Ok(fv(v, p)),
        chord_tol_mm,
    )
}

/// Cylindrical coordinates `(r, θ, z)` of `p` about `axis`.
pub fn to_cyl(p: DVec3, axis: [f64; 2]) -> DVec3 {
    let dx = p.x - axis[0];
    let dy = p.y - axis[1];
    DVec3::new((dx * dx + dy * dy).sqrt(), dy.atan2(dx), p.z)
}

/// Cartesian point of cylindrical `(r, θ, z)` about `axis`.
pub fn from_cyl(c: DVec3, axis: [f64; 2]) -> DVec3 {
    DVec3::new(axis[0] + c.x * c.y.cos(), axis[1] + c.x * c.y.sin(), c.z)
}

/// Deforms in cylindrical coordinates about the model's axis (fallible callbacks). `fd` maps
/// `(r, θ, z)` to `(r', θ', z')`; `fc`, `fv` receive the value and `(r, θ, z)`.
pub fn deform_cylinder_try(
    model: Model,
    fd: &mut PointFn<'_>,
    fc: &mut ValueFn<'_>,
    fv: &mut ValueFn<'_>,
    chord_tol_mm: Option<f64>,
) -> Result<Model, DeformError> {
    let axis = model.axis_xy;
    // fc and fv are called on the same midpoint one after the other: convert it once.
    let last = std::cell::Cell::new((DVec3::NAN, DVec3::NAN));
    let cyl = |p: DVec3| {
        let (q, c) = last.get();
        if q == p {
            c
        } else {
            let c = to_cyl(p, axis);
            last.set((p, c));
            c
        }
    };
    deform_xyz_try(
        model,
        &mut |p| Ok(from_cyl(fd(to_cyl(p, axis))?, axis)),
        &mut |c, p| fc(c, cyl(p)),
        &mut |v, p| fv(v, cyl(p)),
        chord_tol_mm,
    )
}

/// Deforms in cylindrical coordinates with infallible closures.
pub fn deform_cylinder(
    model: Model,
    mut fd: impl FnMut(DVec3) -> DVec3,
    mut fc: impl FnMut(f64, DVec3) -> f64,
    mut fv: impl FnMut(f64, DVec3) -> f64,
    chord_tol_mm: Option<f64>,
) -> Result<Model, DeformError> {
    deform_cylinder_try(
        model,
        &mut |p| Ok(fd(p)),
        &mut |c, p| Ok(fc(c, p)),
        &mut |v, p| Ok(fv(v, p)),
        chord_tol_mm,
    )
}

/// Cup → dish (SPEC §2): `fd(r,θ,z) = (r + 1.05 z, θ, 0.3 z)`, `fc = 0.96 c`, `fv = v`.
pub fn cup_to_dish(model: Model, chord_tol_mm: Option<f64>) -> Result<Model, DeformError> {
    deform_cylinder(
        model,
        |c| DVec3::new(c.x + 1.05 * c.z, c.y, 0.3 * c.z),
        |c, _| 0.96 * c,
        |v, _| v,
        chord_tol_mm,
    )
}

/// Helix → sphere (SPEC §2, pitch kept): `fd(r,θ,z) = (R sin(π z/H), θ, r − R cos(π z/H))`,
/// `fc = 1.2 c`, `fv = 1.2 ((r'/R)² + 0.1) v` with `r'` the new radius. `H` is the helix
/// height (half a meridian) measured from `z0_mm`, the helix's first point; the sphere's
/// bottom is lifted to `z0_mm` so it starts on the bed.
///
/// Without a chord tolerance (and without arcs) the model is deformed in place by a direct
/// evaluation of the same formulas: θ is unchanged, so a point's new X/Y is the old radius
/// vector scaled by `r'/r` — no `atan2`/`cos`/`sin` round trip through θ (the globe's
/// compile time is dominated by this step). Results agree with the general
/// [`deform_cylinder`] evaluation to rounding (tested).
pub fn helix_to_sphere(
    model: Model,
    radius_mm: f64,
    height_mm: f64,
    z0_mm: f64,
    chord_tol_mm: Option<f64>,
) -> Result<Model, DeformError> {
    if !(radius_mm.is_finite() && radius_mm > 0.0 && height_mm.is_finite() && height_mm > 0.0) {
        return Err(DeformError::Callback(format!(
            "sphere radius and height must be > 0 (got {radius_mm}, {height_mm})"
        )));
    }
    if chord_tol_mm.is_none() && !model.strings().any(|s| s.arc.is_some()) {
        return helix_to_sphere_direct(model, radius_mm, height_mm, z0_mm);
    }
    helix_to_sphere_general(model, radius_mm, height_mm, z0_mm, chord_tol_mm)
}

/// [`helix_to_sphere`] through the general cylindrical deformation (closures, subdivision).
fn helix_to_sphere_general(
    model: Model,
    radius_mm: f64,
    height_mm: f64,
    z0_mm: f64,
    chord_tol_mm: Option<f64>,
) -> Result<Model, DeformError> {
    let (rr, h) = (radius_mm, height_mm);
    let new_r = move |z: f64| rr * (PI * (z - z0_mm) / h).sin();
    deform_cylinder(
        model,
        move |c| {
            let zz = c.z - z0_mm;
            DVec3::new(
                rr * (PI * zz / h).sin(),
                c.y,
                z0_mm + c.x - rr * (PI * zz / h).cos(),
            )
        },
        |c, _| 1.2 * c,
        move |v, c| {
            let r1 = new_r(c.z) / rr;
            1.2 * (r1 * r1 + 0.1) * v
        },
        chord_tol_mm,
    )
}

/// [`helix_to_sphere`] evaluated directly, in place (no tolerance, no arcs).
fn helix_to_sphere_direct(
    mut model: Model,
    rr: f64,
    h: f64,
    z0_mm: f64,
) -> Result<Model, DeformError> {
    let axis = model.axis_xy;
    let map = |p: DVec3| -> Result<DVec3, DeformError> {
        let dx = p.x - axis[0];
        let dy = p.y - axis[1];
        let r = (dx * dx + dy * dy).sqrt();
        let zz = p.z - z0_mm;
        let (sin, cos) = (PI * zz / h).sin_cos();
        let r1 = rr * sin;
        let z1 = z0_mm + r - rr * cos;
        let q = if r > 0.0 {
            let k = r1 / r;
            DVec3::new(axis[0] + dx * k, axis[1] + dy * k, z1)
        } else {
            // On the axis θ = atan2(dy, dx) decides the direction, as in `from_cyl`.
            from_cyl(DVec3::new(r1, dy.atan2(dx), z1), axis)
        };
        if q.is_finite() {
            Ok(q)
        } else {
            Err(invalid(p, format!("point mapped to {q:?}")))
        }
    };
    // Consecutive strings share end points: map each point once.
    let mut last: Option<(DVec3, DVec3)> = None;
    for step in &mut model.steps {
        match step {
            Step::String(s) => {
                let a = match last {
                    Some((p, q)) if p == s.start => q,
                    _ => map(s.start)?,
                };
                let b = map(s.end)?;
                last = Some((s.end, b));
                let mid = 0.5 * (s.start + s.end);
                let c = 1.2 * s.cross_mm2;
                let r1 = rr * (PI * (mid.z - z0_mm) / h).sin() / rr;
                let v = 1.2 * (r1 * r1 + 0.1) * s.speed_mm_s;
                if !(c.is_finite() && c >= 0.0) {
                    return Err(invalid(mid, format!("cross-section mapped to {c}")));
                }
                if !(v.is_finite() && v > 0.0) {
                    return Err(invalid(mid, format!("speed mapped to {v}")));
                }
                *s = Str::line(a, b, c, v);
            }
            Step::Travel { to, .. } => *to = map(*to)?,
            _ => {}
        }
    }
    fix_markers(&mut model);
    Ok(model)
}

/// Unit heart outline at parameter `t` (the classic parametric heart scaled so its mean
/// radius about its centre is about 1; cleft up, tip down).
pub fn heart_point(t: f64) -> [f64; 2] {
    let x = 16.0 * t.sin().powi(3);
    let y = 13.0 * t.cos() - 5.0 * (2.0 * t).cos() - 2.0 * (3.0 * t).cos() - (4.0 * t).cos();
    // centre of the outline ≈ (0, −2); mean radius ≈ 13
    [x / 13.0, (y + 2.0) / 13.0]
}

/// Heart-shaped dish: a cup whose circular section becomes a heart (the circle's angle is the
/// heart's parameter, the radius scales the outline) and which flares like the dish:
/// `xy' = axis + (r + 1.05 z)·heart(θ)`, `z' = 0.3 z`, `fc = 0.96 c`.
pub fn heart_dish(model: Model, chord_tol_mm: Option<f64>) -> Result<Model, DeformError> {
    let axis = model.axis_xy;
    let rot = PI / 2.0; // θ = 0 (+X) maps to the cleft at the top
    deform_xyz(
        model,
        move |p| {
            let c = to_cyl(p, axis);
            let h = heart_point(c.y - rot);
            let s = c.x + 1.05 * c.z;
            DVec3::new(axis[0] + s * h[0], axis[1] + s * h[1], 0.3 * c.z)
        },
        |c, _| 0.96 * c,
        |v, _| v,
        chord_tol_mm,
    )
}

/// Twisted vase: `r' = r (1 + a cos(n θ + twist·z)) (1 + b sin(π z / H))`, θ and z kept —
/// `lobes` n, `amplitude` a, `twist_deg_per_mm`, `bulge` b over height `H`.
pub fn twisted_vase(
    model: Model,
    lobes: f64,
    amplitude: f64,
    twist_deg_per_mm: f64,
    bulge: f64,
    height_mm: f64,
    chord_tol_mm: Option<f64>,
) -> Result<Model, DeformError> {
    let tw = twist_deg_per_mm.to_radians();
    let h = height_mm.max(1e-6);
    deform_cylinder(
        model,
        move |c| {
            let k = (1.0 + amplitude * (lobes * c.y + tw * c.z).cos())
                * (1.0 + bulge * (PI * c.z / h).sin());
            DVec3::new(c.x * k, c.y, c.z)
        },
        |c, _| c,
        |v, _| v,
        chord_tol_mm,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn direct_sphere_matches_the_general_deformation() {
        let mut h = crate::design::parts::Helix {
            turns: 20.0,
            per_turn: 37,
            radius_mm: 12.0,
            ..crate::design::parts::Helix::default()
        };
        h.center_xy = [100.0, 80.0];
        let m = h.build().expect("helix");
        let (r, height) = (12.0, 20.0 * h.pitch_mm);
        let mut with_travel = m.clone();
        with_travel.push(Step::Travel {
            to: DVec3::new(90.0, 70.0, 9.0),
            speed_mm_s: None,
        });
        let a = helix_to_sphere_direct(with_travel.clone(), r, height, 0.2).expect("direct");
        let b = helix_to_sphere_general(with_travel, r, height, 0.2, None).expect("general");
        assert_eq!(a.steps.len(), b.steps.len());
        for (x, y) in a.steps.iter().zip(&b.steps) {
            match (x, y) {
                (Step::String(p), Step::String(q)) => {
                    assert!(p.start.distance(q.start) < 1e-9, "{p:?} {q:?}");
                    assert!(p.end.distance(q.end) < 1e-9, "{p:?} {q:?}");
                    assert!((p.cross_mm2 - q.cross_mm2).abs() < 1e-12);
                    assert!((p.speed_mm_s - q.speed_mm_s).abs() < 1e-9);
                }
                (Step::Travel { to: p, .. }, Step::Travel { to: q, .. }) => {
                    assert!(p.distance(*q) < 1e-9)
                }
                (Step::Marker { z_mm: p, .. }, Step::Marker { z_mm: q, .. }) => {
                    assert!((p - q).abs() < 1e-9)
                }
                _ => assert_eq!(x, y),
            }
        }
        // Bad input stays an error on both paths.
        assert!(helix_to_sphere(m.clone(), 0.0, height, 0.0, None).is_err());
        assert!(helix_to_sphere(m, r, f64::NAN, 0.0, None).is_err());
    }
    use crate::design::parts::Helix;

    #[test]
    fn cup_to_dish_maps_points() {
        let h = Helix {
            center_xy: [0.0, 0.0],
            z0_mm: 0.0,
            radius_mm: 10.0,
            pitch_mm: 1.0,
            turns: 2.0,
            per_turn: 36,
            ..Helix::default()
        };
        let m = cup_to_dish(h.build().expect("helix"), None).expect("dish");
        let s = m.strings().last().copied().expect("strings");
        // end at z = 2 → r' = 10 + 2.1, z' = 0.6
        assert!((s.end.truncate().length() - 12.1).abs() < 1e-9);
        assert!((s.end.z - 0.6).abs() < 1e-9);
        assert!((s.cross_mm2 - 0.96 * 0.2).abs() < 1e-12);
    }

    #[test]
    fn sphere_radius_and_speed() {
        let r = 20.0;
        let h = Helix {
            center_xy: [100.0, 100.0],
            z0_mm: 0.0,
            radius_mm: r,
            pitch_mm: 0.4,
            turns: 100.0,
            per_turn: 100,
            ..Helix::default()
        };
        let height = 40.0;
        let m = helix_to_sphere(h.build().expect("helix"), r, height, 0.0, None).expect("sphere");
        let centre = DVec3::new(100.0, 100.0, r);
        for s in m.strings() {
            assert!((s.end.distance(centre) - r).abs() < 1e-6);
            assert!(s.speed_mm_s <= 1.2 * 1.1 * 20.0 + 1e-9);
        }
    }

    #[test]
    fn subdivision_meets_tolerance() {
        let h = Helix {
            center_xy: [0.0, 0.0],
            z0_mm: 0.0,
            radius_mm: 10.0,
            pitch_mm: 1.0,
            turns: 1.0,
            per_turn: 4,
            ..Helix::default()
        };
        let coarse =
            twisted_vase(h.build().expect("h"), 3.0, 0.2, 0.0, 0.0, 10.0, None).expect("vase");
        let fine = twisted_vase(h.build().expect("h"), 3.0, 0.2, 0.0, 0.0, 10.0, Some(0.05))
            .expect("vase");
        assert_eq!(coarse.string_count(), 4);
        assert!(fine.string_count() > 20);
    }

    /// A 40 mm line under a sine wave of 20 mm period: the deformed midpoint lies on the chord
    /// (sin 2π = 0), yet the string must follow the wave within the tolerance everywhere.
    #[test]
    fn tolerance_holds_along_the_whole_string_not_only_at_its_midpoint() {
        let mut m = Model::new([0.0, 0.0]);
        m.push(Step::String(Str::line(
            DVec3::new(0.0, 0.0, 5.0),
            DVec3::new(40.0, 0.0, 5.0),
            0.2,
            20.0,
        )));
        let wave = |p: DVec3| DVec3::new(p.x, p.y, p.z + 2.0 * (2.0 * PI * p.x / 20.0).sin());
        let tol = 0.05;
        let out = deform_xyz(m, wave, |c, _| c, |v, _| v, Some(tol)).expect("deform");
        assert!(out.string_count() > 20, "{} strings", out.string_count());
        // Every piece: the wave at 5 points inside it lies within the tolerance of the chord
        // (plus the second-order error of sampling between probes).
        for s in out.strings() {
            for k in 1..5 {
                let f = k as f64 / 5.0;
                let x = s.start.x + (s.end.x - s.start.x) * f;
                let want = wave(DVec3::new(x, 0.0, 5.0));
                let got = s.start.lerp(s.end, f);
                assert!(
                    (got.z - want.z).abs() <= 1.5 * tol,
                    "piece {:?}→{:?} is {} mm off at x = {x}",
                    s.start,
                    s.end,
                    (got.z - want.z).abs()
                );
            }
        }
    }

    #[test]
    fn tiny_tolerance_is_an_error_not_endless_memory() {
        let h = Helix::default().build().expect("h");
        let r = deform_xyz(h, |p| p * 1.01, |c, _| c, |v, _| v, Some(1e-12));
        assert!(matches!(r, Err(DeformError::Limit(_))), "{r:?}");
    }

    #[test]
    fn nan_from_callback_is_an_error() {
        let h = Helix::default().build().expect("h");
        let r = deform_xyz(h, |_| DVec3::NAN, |c, _| c, |v, _| v, None);
        assert!(r.is_err());
    }
}
