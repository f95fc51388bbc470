//! Rotating, scaling and polar moves of paths and models (FullControl's `move_polar`, and
//! the rotation and scaling its designs do by hand): one [`Transform`] applied to every point
//! of a path, or to every string, travel, arc centre, marker and the axis of a [`Model`].
//! Mirroring is [`Model::reflect_xy`] / [`crate::design::points::reflect_xy`].
//!
//! Angles are radians, counter-clockwise, as in FullControl. Strings keep their cross-section
//! and speed: a scale in Z changes the layer height the strings are laid at (the checks' line
//! width then flags a cross-section that no longer fits). A transform that does not keep
//! circles circles (a non-uniform XY scale, a polar move with a radius change) turns arcs into
//! straight strings first (within 0.01 mm).

use crate::design::model::{Model, Step, MAX_STRINGS};
use glam::{DVec2, DVec3};

/// Chord tolerance when arcs must become straight strings, mm.
pub const ARC_TOLERANCE_MM: f64 = 0.01;

/// A transform of points.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Transform {
    /// Rotation about the vertical through `centre` by `angle` radians (counter-clockwise).
    RotateXy {
        /// Centre (X, Y), mm.
        centre: DVec2,
        /// Angle, radians.
        angle: f64,
    },
    /// Scaling about `centre` by `k` per axis (a negative factor mirrors).
    Scale {
        /// Fixed point, mm.
        centre: DVec3,
        /// Factors for X, Y, Z.
        k: DVec3,
    },
    /// FullControl's `move_polar`: every point's distance from the vertical through `centre`
    /// grows by `radius` and its angle about it by `angle`.
    Polar {
        /// Centre (X, Y), mm.
        centre: DVec2,
        /// Radial change, mm.
        radius: f64,
        /// Angle, radians.
        angle: f64,
    },
}

impl Transform {
    /// Refuses non-finite values and a zero scale factor (it would flatten the design).
    pub fn validate(&self) -> Result<(), String> {
        let ok = match *self {
            Transform::RotateXy { centre, angle } => centre.is_finite() && angle.is_finite(),
            Transform::Scale { centre, k } => {
                if centre.is_finite() && k.is_finite() && k.abs().min_element() == 0.0 {
                    return Err(format!(
                        "scale: a factor of 0 flattens the design, got {k:?}"
                    ));
                }
                centre.is_finite() && k.is_finite()
            }
            Transform::Polar {
                centre,
                radius,
                angle,
            } => centre.is_finite() && radius.is_finite() && angle.is_finite(),
        };
        if ok {
            Ok(())
        } else {
            Err(format!("transform values must be finite, got {self:?}"))
        }
    }

    /// The point moved.
    pub fn apply(&self, p: DVec3) -> DVec3 {
        match *self {
            Transform::RotateXy { centre, angle } => {
                let v = DVec2::from_angle(angle).rotate(p.truncate() - centre);
                (centre + v).extend(p.z)
            }
            Transform::Scale { centre, k } => centre + (p - centre) * k,
            Transform::Polar {
                centre,
                radius,
                angle,
            } => {
                let d = p.truncate() - centre;
                let (r, a) = (d.length(), d.y.atan2(d.x));
                (centre + DVec2::from_angle(a + angle) * (r + radius)).extend(p.z)
            }
        }
    }

    /// True when circles stay circles (arcs can be kept).
    fn keeps_arcs(&self) -> bool {
        match *self {
            Transform::RotateXy { .. } => true,
            Transform::Scale { k, .. } => k.x.abs() == k.y.abs(),
            Transform::Polar { radius, .. } => radius == 0.0,
        }
    }

    /// True when the transform mirrors XY (arcs change direction).
    fn mirrors(&self) -> bool {
        matches!(*self, Transform::Scale { k, .. } if k.x * k.y < 0.0)
    }

    /// Factor on heights (marker heights, layer thickness).
    fn z_factor(&self) -> f64 {
        match *self {
            Transform::Scale { k, .. } => k.z,
            _ => 1.0,
        }
    }
}

/// Every point of a path transformed.
pub fn path(points: &[DVec3], t: &Transform) -> Result<Vec<DVec3>, String> {
    t.validate()?;
    Ok(points.iter().map(|p| t.apply(*p)).collect())
}

/// `copies` copies of a path one after another, the k-th transformed k times (k = 0..copies):
/// FullControl's `move_polar(..., copy=True, copy_quantity)`.
pub fn copies(
    points: &[DVec3],
    t: &Transform,
    copies: usize,
    max: usize,
) -> Result<Vec<DVec3>, String> {
    t.validate()?;
    if copies == 0 || points.len().saturating_mul(copies) > max {
        return Err(format!(
            "copies: 1..{} copies of {} points, got {copies}",
            max / points.len().max(1),
            points.len()
        ));
    }
    let mut out = Vec::with_capacity(points.len() * copies);
    let mut cur = points.to_vec();
    for _ in 0..copies {
        out.extend_from_slice(&cur);
        for p in &mut cur {
            *p = t.apply(*p);
        }
    }
    Ok(out)
}

/// The model transformed: strings, travels, arc centres, markers and the axis.
pub fn model(m: Model, t: &Transform) -> Result<Model, String> {
    t.validate()?;
    let mut m = if t.keeps_arcs() {
        m
    } else {
        m.arcs_to_lines(ARC_TOLERANCE_MM)
    };
    let kz = t.z_factor();
    let z_of = |z: f64| t.apply(DVec3::new(0.0, 0.0, z)).z;
    for s in &mut m.steps {
        match s {
            Step::String(st) => {
                st.start = t.apply(st.start);
                st.end = t.apply(st.end);
                if let Some(arc) = &mut st.arc {
                    let c = t.apply(DVec3::new(arc.center_xy[0], arc.center_xy[1], 0.0));
                    arc.center_xy = [c.x, c.y];
                    if t.mirrors() {
                        arc.ccw = !arc.ccw;
                    }
                }
            }
            Step::Travel { to, .. } => *to = t.apply(*to),
            Step::Marker {
                z_mm, height_mm, ..
            } => {
                *z_mm = z_of(*z_mm);
                *height_mm *= kz.abs();
            }
            _ => {}
        }
    }
    let ax = t.apply(DVec3::new(m.axis_xy[0], m.axis_xy[1], 0.0));
    m.axis_xy = [ax.x, ax.y];
    Ok(m)
}

/// `n` copies of a model, the k-th transformed k times, assembled with lifted travels
/// between them ([`Model::assemble`]): a rotated (or scaled) array of parts.
pub fn model_copies(m: &Model, t: &Transform, n: usize) -> Result<Model, String> {
    t.validate()?;
    if n == 0 || m.steps.len().saturating_mul(n) > MAX_STRINGS {
        return Err(format!(
            "copies: 1.. copies of a {}-step model, got {n}",
            m.steps.len()
        ));
    }
    let mut parts = Vec::with_capacity(n);
    let mut cur = m.clone();
    for _ in 0..n {
        let next = model(cur.clone(), t)?;
        parts.push(cur);
        cur = next;
    }
    Ok(Model::assemble(parts))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::design::model::{Arc, Str};
    use std::f64::consts::FRAC_PI_2;

    fn close(a: DVec3, b: DVec3) -> bool {
        a.distance(b) < 1e-9
    }

    #[test]
    fn rotation_scale_and_polar_move_points() {
        let c = DVec2::new(10.0, 10.0);
        let r = Transform::RotateXy {
            centre: c,
            angle: FRAC_PI_2,
        };
        assert!(close(
            r.apply(DVec3::new(15.0, 10.0, 2.0)),
            DVec3::new(10.0, 15.0, 2.0)
        ));
        let s = Transform::Scale {
            centre: DVec3::new(10.0, 10.0, 0.0),
            k: DVec3::new(2.0, 3.0, 1.0),
        };
        assert!(close(
            s.apply(DVec3::new(11.0, 11.0, 0.4)),
            DVec3::new(12.0, 13.0, 0.4)
        ));
        // FullControl's move_polar: 5 mm out at 0 rad → 7 mm out at 90°.
        let p = Transform::Polar {
            centre: c,
            radius: 2.0,
            angle: FRAC_PI_2,
        };
        assert!(close(
            p.apply(DVec3::new(15.0, 10.0, 1.0)),
            DVec3::new(10.0, 17.0, 1.0)
        ));
        assert!(Transform::Scale {
            centre: DVec3::ZERO,
            k: DVec3::new(1.0, 0.0, 1.0)
        }
        .validate()
        .is_err());
    }

    #[test]
    fn models_keep_arcs_when_they_can_and_mirror_them() {
        let mut m = Model::new([0.0, 0.0]);
        m.push(Step::String(Str {
            start: DVec3::new(10.0, 0.0, 0.2),
            end: DVec3::new(0.0, 10.0, 0.2),
            cross_mm2: 0.08,
            speed_mm_s: 20.0,
            arc: Some(Arc {
                center_xy: [0.0, 0.0],
                ccw: true,
            }),
        }));
        let rot = model(
            m.clone(),
            &Transform::RotateXy {
                centre: DVec2::ZERO,
                angle: FRAC_PI_2,
            },
        )
        .expect("rotate");
        let s = rot.strings().next().copied().expect("string");
        assert!(s.arc.is_some_and(|a| a.ccw));
        assert!(close(s.end, DVec3::new(-10.0, 0.0, 0.2)));
        let mirrored = model(
            m.clone(),
            &Transform::Scale {
                centre: DVec3::ZERO,
                k: DVec3::new(-1.0, 1.0, 1.0),
            },
        )
        .expect("mirror");
        assert!(mirrored
            .strings()
            .next()
            .is_some_and(|s| s.arc.is_some_and(|a| !a.ccw)));
        let stretched = model(
            m,
            &Transform::Scale {
                centre: DVec3::ZERO,
                k: DVec3::new(2.0, 1.0, 1.0),
            },
        )
        .expect("stretch");
        assert!(stretched.string_count() > 1 && stretched.strings().all(|s| s.arc.is_none()));
    }
}
