//! Geometry from points (FullControl's reach): generators that return lists of points —
//! polar points, arcs, circles, polygons, rectangles, spirals, helices, waves — and operations
//! on point lists: subdivision, move/copy, reflection.
//!
//! Angles are radians, counter-clockwise from +X, as in FullControl, so a FullControl design
//! ports line by line (`fc.arcXY(c, r, a0, sweep, n)` → `arc_xy(c, r, a0, sweep, n)`). Every
//! curve of `n` segments returns `n + 1` points, first and last included. The number of points
//! a call may produce is bounded by [`MAX_POINTS`]: a bad argument is an error, never an
//! unbounded allocation.

use glam::{DVec2, DVec3};
use std::f64::consts::{FRAC_PI_2, TAU};

/// Most points one generator call may return, checked before anything is allocated (a path
/// of a million points is ~24 MB native, ~100 MB as script arrays).
pub const MAX_POINTS: usize = 1_000_000;

/// A bad argument to a point generator.
#[derive(Debug, thiserror::Error, PartialEq)]
#[error("{0}")]
pub struct PointsError(pub String);

type Res<T> = Result<T, PointsError>;

fn finite(what: &str, v: f64) -> Res<f64> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(PointsError(format!("{what} must be finite, got {v}")))
    }
}

fn finite_p(what: &str, p: DVec3) -> Res<DVec3> {
    if p.is_finite() {
        Ok(p)
    } else {
        Err(PointsError(format!("{what} must be finite, got {p:?}")))
    }
}

fn segments(what: &str, n: usize) -> Res<usize> {
    if (1..MAX_POINTS).contains(&n) {
        Ok(n)
    } else {
        Err(PointsError(format!(
            "{what}: segments must be 1..{MAX_POINTS}, got {n}"
        )))
    }
}

/// The point at `radius` and `angle` (radians) from `centre`, at the centre's Z.
pub fn polar(centre: DVec3, radius: f64, angle: f64) -> DVec3 {
    DVec3::new(
        centre.x + radius * angle.cos(),
        centre.y + radius * angle.sin(),
        centre.z,
    )
}

/// `(radius, angle)` of `p` seen from `origin` in XY (angle in radians, −π..π).
pub fn to_polar(p: DVec3, origin: DVec3) -> (f64, f64) {
    let d = (p - origin).truncate();
    (d.length(), d.y.atan2(d.x))
}

/// An arc whose radius and Z change linearly along it (FullControl's `variable_arcXY`):
/// `segments + 1` points from `start_angle` through `sweep` radians (negative: clockwise).
pub fn variable_arc_xy(
    centre: DVec3,
    start_radius: f64,
    start_angle: f64,
    sweep: f64,
    n: usize,
    radius_change: f64,
    z_change: f64,
) -> Res<Vec<DVec3>> {
    let centre = finite_p("centre", centre)?;
    for (what, v) in [
        ("radius", start_radius),
        ("start angle", start_angle),
        ("sweep", sweep),
        ("radius change", radius_change),
        ("z change", z_change),
    ] {
        finite(what, v)?;
    }
    let n = segments("arc", n)?;
    Ok((0..=n)
        .map(|k| {
            let t = k as f64 / n as f64;
            let mut p = polar(
                centre,
                start_radius + radius_change * t,
                start_angle + sweep * t,
            );
            p.z += z_change * t;
            p
        })
        .collect())
}

/// A flat arc at the centre's Z: `segments + 1` points.
pub fn arc_xy(
    centre: DVec3,
    radius: f64,
    start_angle: f64,
    sweep: f64,
    n: usize,
) -> Res<Vec<DVec3>> {
    variable_arc_xy(centre, radius, start_angle, sweep, n, 0.0, 0.0)
}

/// A closed circle (first point repeated last): `segments + 1` points, counter-clockwise
/// unless `cw`.
pub fn circle_xy(
    centre: DVec3,
    radius: f64,
    start_angle: f64,
    n: usize,
    cw: bool,
) -> Res<Vec<DVec3>> {
    arc_xy(centre, radius, start_angle, if cw { -TAU } else { TAU }, n)
}

/// A closed regular polygon with `sides` corners on a circle of `radius` (`sides + 1` points).
pub fn polygon_xy(
    centre: DVec3,
    radius: f64,
    start_angle: f64,
    sides: usize,
    cw: bool,
) -> Res<Vec<DVec3>> {
    if sides < 3 {
        return Err(PointsError(format!(
            "polygon: at least 3 sides, got {sides}"
        )));
    }
    circle_xy(centre, radius, start_angle, sides, cw)
}

/// A closed axis-aligned rectangle from `start` (5 points, counter-clockwise unless `cw`).
pub fn rectangle_xy(start: DVec3, x_size: f64, y_size: f64, cw: bool) -> Res<Vec<DVec3>> {
    let s = finite_p("start", start)?;
    let (w, h) = (finite("x size", x_size)?, finite("y size", y_size)?);
    let (a, c) = if cw {
        (DVec3::new(0.0, h, 0.0), DVec3::new(w, 0.0, 0.0))
    } else {
        (DVec3::new(w, 0.0, 0.0), DVec3::new(0.0, h, 0.0))
    };
    Ok(vec![s, s + a, s + DVec3::new(w, h, 0.0), s + c, s])
}

/// A flat spiral from `start_radius` to `end_radius` over `turns` (fractions allowed).
pub fn spiral_xy(
    centre: DVec3,
    start_radius: f64,
    end_radius: f64,
    start_angle: f64,
    turns: f64,
    n: usize,
    cw: bool,
) -> Res<Vec<DVec3>> {
    let sign = if cw { -1.0 } else { 1.0 };
    variable_arc_xy(
        centre,
        start_radius,
        start_angle,
        sign * turns * TAU,
        n,
        end_radius - start_radius,
        0.0,
    )
}

/// A helix rising `pitch` per turn from the centre's Z, its radius going from `start_radius`
/// to `end_radius`.
#[allow(clippy::too_many_arguments)]
pub fn helix_z(
    centre: DVec3,
    start_radius: f64,
    end_radius: f64,
    start_angle: f64,
    turns: f64,
    pitch: f64,
    n: usize,
    cw: bool,
) -> Res<Vec<DVec3>> {
    let sign = if cw { -1.0 } else { 1.0 };
    variable_arc_xy(
        centre,
        start_radius,
        start_angle,
        sign * turns * TAU,
        n,
        end_radius - start_radius,
        finite("pitch", pitch)? * turns,
    )
}

fn periods(what: &str, n: usize, per: usize) -> Res<()> {
    if n.saturating_mul(per.max(1)) < MAX_POINTS {
        Ok(())
    } else {
        Err(PointsError(format!("{what}: too many periods ({n})")))
    }
}

/// A sine wave from `start` along the direction `angle` (radians): `periods` periods of
/// `period` mm, amplitude `amplitude` mm to the left of the direction, `per_period` segments
/// each, shifted by `phase` radians (FullControl's `sinewaveXYpolar`).
#[allow(clippy::too_many_arguments)]
pub fn sine_wave_xy(
    start: DVec3,
    angle: f64,
    amplitude: f64,
    period: f64,
    periods_n: usize,
    per_period: usize,
    extra_half_period: bool,
    phase: f64,
) -> Res<Vec<DVec3>> {
    let start = finite_p("start", start)?;
    for (w, v) in [
        ("angle", angle),
        ("amplitude", amplitude),
        ("period", period),
        ("phase", phase),
    ] {
        finite(w, v)?;
    }
    let per = segments("sine wave", per_period)?;
    periods("sine wave", periods_n, per)?;
    let n = periods_n * per + if extra_half_period { per / 2 } else { 0 };
    let along = DVec2::from_angle(angle);
    let left = DVec2::from_angle(angle + FRAC_PI_2);
    Ok((0..=n)
        .map(|k| {
            let u = k as f64 / per as f64; // periods travelled
            let d = along * (u * period)
                + left * (amplitude * (u * TAU + phase).sin() - amplitude * phase.sin());
            start + d.extend(0.0)
        })
        .collect())
}

/// A square wave from `start` along `angle`: each period goes `amplitude` left, `spacing`
/// ahead, `amplitude` right, `spacing` ahead (the last ahead step left out, as FullControl's
/// `squarewaveXYpolar`); `extra_half_period` adds one more ahead + left.
pub fn square_wave_xy(
    start: DVec3,
    angle: f64,
    amplitude: f64,
    spacing: f64,
    periods_n: usize,
    extra_half_period: bool,
) -> Res<Vec<DVec3>> {
    let start = finite_p("start", start)?;
    for (w, v) in [
        ("angle", angle),
        ("amplitude", amplitude),
        ("spacing", spacing),
    ] {
        finite(w, v)?;
    }
    periods("square wave", periods_n, 4)?;
    let ahead = (DVec2::from_angle(angle) * spacing).extend(0.0);
    let left = (DVec2::from_angle(angle + FRAC_PI_2) * amplitude).extend(0.0);
    let mut out = Vec::with_capacity(periods_n * 4 + 3);
    let mut p = start;
    out.push(p);
    for i in 0..periods_n {
        for d in [left, ahead, -left] {
            p += d;
            out.push(p);
        }
        if i + 1 != periods_n {
            p += ahead;
            out.push(p);
        }
    }
    if extra_half_period {
        for d in [ahead, left] {
            p += d;
            out.push(p);
        }
    }
    Ok(out)
}

/// A triangle wave from `start` along `angle`: tips `amplitude` to the left and back, tips
/// `tip_spacing` apart.
pub fn triangle_wave_xy(
    start: DVec3,
    angle: f64,
    amplitude: f64,
    tip_spacing: f64,
    periods_n: usize,
) -> Res<Vec<DVec3>> {
    let start = finite_p("start", start)?;
    for (w, v) in [
        ("angle", angle),
        ("amplitude", amplitude),
        ("tip spacing", tip_spacing),
    ] {
        finite(w, v)?;
    }
    periods("triangle wave", periods_n, 2)?;
    let half = (DVec2::from_angle(angle) * (tip_spacing / 2.0)).extend(0.0);
    let left = (DVec2::from_angle(angle + FRAC_PI_2) * amplitude).extend(0.0);
    let mut out = vec![start];
    let mut p = start;
    for _ in 0..periods_n {
        p += half + left;
        out.push(p);
        p += half - left;
        out.push(p);
    }
    Ok(out)
}

/// `segments + 1` evenly spaced points from `a` to `b`.
pub fn segmented_line(a: DVec3, b: DVec3, n: usize) -> Res<Vec<DVec3>> {
    let (a, b) = (finite_p("start", a)?, finite_p("end", b)?);
    let n = segments("line", n)?;
    Ok((0..=n).map(|k| a.lerp(b, k as f64 / n as f64)).collect())
}

/// The same path with every segment longer than `max_len` mm split into equal pieces no
/// longer than `max_len` (the original points are kept).
pub fn subdivide(points: &[DVec3], max_len: f64) -> Res<Vec<DVec3>> {
    if !(max_len.is_finite() && max_len > 0.0) {
        return Err(PointsError(format!(
            "subdivide: max length must be > 0, got {max_len}"
        )));
    }
    let mut out = Vec::with_capacity(points.len());
    let Some(first) = points.first() else {
        return Ok(out);
    };
    out.push(finite_p("point", *first)?);
    for w in points.windows(2) {
        let (a, b) = (w[0], finite_p("point", w[1])?);
        let pieces = (a.distance(b) / max_len).ceil();
        if out.len() as f64 + pieces >= MAX_POINTS as f64 {
            return Err(PointsError(format!(
                "subdivide: more than {MAX_POINTS} points at max length {max_len}"
            )));
        }
        let n = (pieces as usize).max(1);
        for k in 1..n {
            out.push(a.lerp(b, k as f64 / n as f64));
        }
        out.push(b);
    }
    Ok(out)
}

/// Every point moved by `d`.
pub fn moved(points: &[DVec3], d: DVec3) -> Vec<DVec3> {
    points.iter().map(|p| *p + d).collect()
}

/// `copies` copies of the points, the k-th moved by `k·d` (k = 0..copies), one after
/// another (FullControl's `move(..., copy=True, copy_quantity)`).
pub fn copied(points: &[DVec3], d: DVec3, copies: usize) -> Res<Vec<DVec3>> {
    if copies == 0 || points.len().saturating_mul(copies) > MAX_POINTS {
        return Err(PointsError(format!(
            "copy: 1..{} copies of {} points, got {copies}",
            MAX_POINTS / points.len().max(1),
            points.len()
        )));
    }
    let d = finite_p("vector", d)?;
    Ok((0..copies)
        .flat_map(|k| points.iter().map(move |p| *p + d * k as f64))
        .collect())
}

/// `p` reflected in XY about the line through `a` and `b` (Z kept).
pub fn reflect_xy(p: DVec3, a: DVec3, b: DVec3) -> Res<DVec3> {
    let dir = (b - a).truncate();
    if !(dir.length_squared() > 0.0 && dir.is_finite()) {
        return Err(PointsError(
            "reflect: the two points of the mirror line must differ".into(),
        ));
    }
    let dir = dir.normalize();
    let v = (p - a).truncate();
    let foot = dir * v.dot(dir);
    let r = a.truncate() + foot * 2.0 - v;
    Ok(DVec3::new(r.x, r.y, p.z))
}

/// Total length of the path, mm.
pub fn path_length(points: &[DVec3]) -> f64 {
    points.windows(2).map(|w| w[0].distance(w[1])).sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: DVec3, b: DVec3) -> bool {
        a.distance(b) < 1e-9
    }

    #[test]
    fn arcs_circles_and_polygons_have_n_plus_one_points_on_the_circle() {
        let c = DVec3::new(10.0, 20.0, 0.3);
        let circle = circle_xy(c, 5.0, 0.0, 64, false).unwrap_or_default();
        assert_eq!(circle.len(), 65);
        assert!(close(circle[0], circle[64]));
        assert!(circle
            .iter()
            .all(|p| ((*p - c).length() - 5.0).abs() < 1e-9));
        // Counter-clockwise: the second point has a positive Y offset.
        assert!(circle[1].y > c.y);
        let cw = circle_xy(c, 5.0, 0.0, 64, true).unwrap_or_default();
        assert!(cw[1].y < c.y);
        let quarter = arc_xy(c, 5.0, 0.0, FRAC_PI_2, 10).unwrap_or_default();
        assert!(close(quarter[10], DVec3::new(10.0, 25.0, 0.3)));
        let hex = polygon_xy(c, 5.0, 0.0, 6, false).unwrap_or_default();
        assert_eq!(hex.len(), 7);
        assert!(
            (path_length(&hex) - 30.0).abs() < 1e-9,
            "a hexagon's side is its radius"
        );
        assert!(polygon_xy(c, 5.0, 0.0, 2, false).is_err());
        assert!(arc_xy(c, f64::NAN, 0.0, 1.0, 4).is_err());
        assert!(arc_xy(c, 1.0, 0.0, 1.0, 0).is_err());
        assert!(arc_xy(c, 1.0, 0.0, 1.0, usize::MAX).is_err());
    }

    #[test]
    fn spiral_and_helix_change_radius_and_height() {
        let c = DVec3::new(0.0, 0.0, 1.0);
        let h = helix_z(c, 10.0, 5.0, 0.0, 2.0, 0.5, 100, false).unwrap_or_default();
        assert_eq!(h.len(), 101);
        assert!(close(h[0], DVec3::new(10.0, 0.0, 1.0)));
        assert!(close(h[100], DVec3::new(5.0, 0.0, 2.0)));
        let s = spiral_xy(c, 1.0, 3.0, FRAC_PI_2, 0.5, 10, true).unwrap_or_default();
        assert!(close(s[0], DVec3::new(0.0, 1.0, 1.0)));
        // Half a turn clockwise from +Y ends at −Y with radius 3.
        assert!(close(s[10], DVec3::new(0.0, -3.0, 1.0)));
    }

    #[test]
    fn waves_and_rectangles() {
        let sq = square_wave_xy(DVec3::ZERO, 0.0, 2.0, 1.0, 2, false).unwrap_or_default();
        let want = [
            [0., 0.],
            [0., 2.],
            [1., 2.],
            [1., 0.],
            [2., 0.],
            [2., 2.],
            [3., 2.],
            [3., 0.],
        ];
        assert_eq!(sq.len(), want.len());
        for (p, w) in sq.iter().zip(want) {
            assert!(close(*p, DVec3::new(w[0], w[1], 0.0)), "{sq:?}");
        }
        let sine =
            sine_wave_xy(DVec3::ZERO, FRAC_PI_2, 1.0, 4.0, 3, 16, false, 0.0).unwrap_or_default();
        assert_eq!(sine.len(), 49);
        // Along +Y, amplitude to the left (−X): a quarter period in, x = −1.
        assert!(close(sine[4], DVec3::new(-1.0, 1.0, 0.0)), "{:?}", sine[4]);
        assert!(close(sine[48], DVec3::new(0.0, 12.0, 0.0)));
        let tri = triangle_wave_xy(DVec3::ZERO, 0.0, 1.0, 2.0, 2).unwrap_or_default();
        assert!(
            close(tri[1], DVec3::new(1.0, 1.0, 0.0)) && close(tri[4], DVec3::new(4.0, 0.0, 0.0))
        );
        let r = rectangle_xy(DVec3::new(1.0, 1.0, 0.2), 3.0, 2.0, false).unwrap_or_default();
        assert!(close(r[1], DVec3::new(4.0, 1.0, 0.2)) && close(r[4], r[0]));
        assert!(sine_wave_xy(DVec3::ZERO, 0.0, 1.0, 1.0, usize::MAX, 16, false, 0.0).is_err());
    }

    #[test]
    fn subdivide_move_copy_reflect() {
        let pts = [
            DVec3::ZERO,
            DVec3::new(10.0, 0.0, 0.0),
            DVec3::new(10.0, 0.5, 0.0),
        ];
        let s = subdivide(&pts, 3.0).unwrap_or_default();
        assert_eq!(s.len(), 6, "{s:?}"); // 10 mm in 4 pieces of 2.5, then 0.5 mm kept
        assert!(s.windows(2).all(|w| w[0].distance(w[1]) <= 3.0 + 1e-12));
        assert!((path_length(&s) - path_length(&pts)).abs() < 1e-9);
        assert!(subdivide(&pts, 0.0).is_err());
        assert!(subdivide(&pts, 1e-300).is_err());
        let c = copied(&pts, DVec3::new(0.0, 0.0, 0.2), 3).unwrap_or_default();
        assert_eq!(c.len(), 9);
        assert!(close(c[8], DVec3::new(10.0, 0.5, 0.4)));
        assert!(copied(&pts, DVec3::X, usize::MAX).is_err());
        let r = reflect_xy(
            DVec3::new(2.0, 0.0, 1.0),
            DVec3::ZERO,
            DVec3::new(1.0, 1.0, 0.0),
        );
        assert!(r.is_ok_and(|r| close(r, DVec3::new(0.0, 2.0, 1.0))));
        assert!(reflect_xy(DVec3::ZERO, DVec3::X, DVec3::X).is_err());
        let (r, a) = to_polar(polar(DVec3::ZERO, 2.0, 1.0), DVec3::ZERO);
        assert!((r - 2.0).abs() < 1e-12 && (a - 1.0).abs() < 1e-12);
    }
}
