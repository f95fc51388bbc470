//! The polygon frame of a base-part triangle and the paper's placement transform.
//!
//! Frame of triangle `(a, b, c)` (Yamauchi & Morishige):
//! - origin: the centroid;
//! - `Z'`: the face normal from the winding (outward for a correctly wound STL);
//! - `Y'`: global `Z` projected onto the face, normalised (the "up-slope" direction);
//! - `X' = Y' × Z'`.
//!
//! **Horizontal face fallback**: when the face is horizontal the projection of global `Z` is
//! zero (we test `|proj| < 1e-9`); `Y'` is then global `Y` projected onto the face. For a top
//! face (normal `+Z`) this gives `X' = X, Y' = Y`, for a bottom face (normal `−Z`)
//! `X' = −X, Y' = Y`: always right-handed.

use super::stl::{winding_normal, Mesh};
use anyhow::bail;
use glam::{DMat4, DVec2, DVec3, DVec4};

/// Below this length the projected global Z counts as zero (horizontal face).
pub const HORIZONTAL_EPS: f64 = 1e-9;

/// An orthonormal right-handed frame on a face.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frame {
    /// Centroid of the triangle (world, mm).
    pub origin: DVec3,
    /// `X' = Y' × Z'`.
    pub x: DVec3,
    /// Global Z projected onto the face (fallback: global Y projected).
    pub y: DVec3,
    /// The face normal.
    pub z: DVec3,
    /// True when the horizontal-face fallback was used.
    pub horizontal_fallback: bool,
}

impl Frame {
    /// Builds the polygon frame of a triangle; errors for a degenerate triangle.
    pub fn from_triangle(a: DVec3, b: DVec3, c: DVec3) -> anyhow::Result<Frame> {
        let z = winding_normal(a, b, c);
        if z == DVec3::ZERO || !z.is_finite() {
            bail!("degenerate triangle: no normal");
        }
        let origin = (a + b + c) / 3.0;
        let project = |v: DVec3| v - v.dot(z) * z;
        let mut y = project(DVec3::Z);
        let mut horizontal_fallback = false;
        if y.length() < HORIZONTAL_EPS {
            y = project(DVec3::Y);
            horizontal_fallback = true;
        }
        let y = y.normalize();
        let x = y.cross(z).normalize();
        Ok(Frame {
            origin,
            x,
            y,
            z,
            horizontal_fallback,
        })
    }

    /// The frame of face `index` of `mesh`.
    pub fn from_face(mesh: &Mesh, index: usize) -> anyhow::Result<Frame> {
        let Some([a, b, c]) = mesh.triangle(index) else {
            bail!(
                "face {index} does not exist (the mesh has {} triangles)",
                mesh.faces.len()
            );
        };
        Frame::from_triangle(a, b, c).map_err(|e| anyhow::anyhow!("face {index}: {e}"))
    }

    /// `T_wp⁻¹`: polygon-frame coordinates → world.
    pub fn to_world(&self) -> DMat4 {
        DMat4::from_cols(
            self.x.extend(0.0),
            self.y.extend(0.0),
            self.z.extend(0.0),
            self.origin.extend(1.0),
        )
    }

    /// `T_wp`: world → polygon-frame coordinates.
    pub fn from_world(&self) -> DMat4 {
        // Inverse of a rigid transform: transpose the rotation, rotate the negated origin.
        let r = DMat4::from_cols(
            DVec4::new(self.x.x, self.y.x, self.z.x, 0.0),
            DVec4::new(self.x.y, self.y.y, self.z.y, 0.0),
            DVec4::new(self.x.z, self.y.z, self.z.z, 0.0),
            DVec4::W,
        );
        r * DMat4::from_translation(-self.origin)
    }

    /// Tilt of the face: angle between its normal and global `+Z`, in degrees.
    pub fn tilt_deg(&self) -> f64 {
        self.z.dot(DVec3::Z).clamp(-1.0, 1.0).acos().to_degrees()
    }
}

/// The user's placement of the added shape in the polygon frame.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Placement {
    /// Offset of the shape's local origin in the polygon frame (X', Y'), mm.
    pub offset_mm: DVec2,
    /// Rotation about the shape's local Z, degrees (counter-clockwise seen from +Z').
    pub rotate_deg: f64,
}

/// The paper's transform `T = T_wp⁻¹ · T_pa⁻¹ · R_z · T_pa · Q_xy · T_wp` (column vectors,
/// applied right to left).
///
/// It acts on points of the added shape *placed on the face*: local coordinates `p` first put
/// into the world with the local axes equal to the polygon axes, `p₀ = T_wp⁻¹ · p`. Then
/// `T_wp` takes them back into the polygon frame, `Q_xy` moves them by the user's offset,
/// `T_pa` (polygon → local, a translation by −offset) puts the shape's origin at the local
/// origin, `R_z` rotates about local Z, `T_pa⁻¹` returns to the polygon frame and `T_wp⁻¹` to
/// the world. The product is built literally from these six matrices; see [`local_to_world`]
/// for the composition with the initial placement.
pub fn paper_transform(frame: &Frame, placement: &Placement) -> DMat4 {
    let t_wp = frame.from_world();
    let t_wp_inv = frame.to_world();
    let q_xy = DMat4::from_translation(placement.offset_mm.extend(0.0));
    let t_pa = DMat4::from_translation(-placement.offset_mm.extend(0.0));
    let t_pa_inv = DMat4::from_translation(placement.offset_mm.extend(0.0));
    let r_z = DMat4::from_rotation_z(placement.rotate_deg.to_radians());
    t_wp_inv * t_pa_inv * r_z * t_pa * q_xy * t_wp
}

/// Maps the added shape's local coordinates (slice contours at their layer height) to the
/// world: `T · T_wp⁻¹`, which equals `T_wp⁻¹ · Trans(offset) · R_z`.
pub fn local_to_world(frame: &Frame, placement: &Placement) -> DMat4 {
    paper_transform(frame, placement) * frame.to_world()
}

/// Index of the face nearest to `p` (Euclidean distance to the triangle), with the distance.
pub fn nearest_face(mesh: &Mesh, p: DVec3) -> Option<(usize, f64)> {
    let mut best: Option<(usize, f64)> = None;
    for (i, [a, b, c]) in mesh.triangles().enumerate() {
        let d = (closest_point_on_triangle(p, a, b, c) - p).length();
        if best.is_none_or(|(_, bd)| d < bd) {
            best = Some((i, d));
        }
    }
    best
}

/// Closest point to `p` on triangle `abc` (Ericson, Real-Time Collision Detection §5.1.5).
pub fn closest_point_on_triangle(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> DVec3 {
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = ab.dot(ap);
    let d2 = ac.dot(ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = p - b;
    let d3 = ab.dot(bp);
    let d4 = ac.dot(bp);
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return a + v * ab;
    }
    let cp = p - c;
    let d5 = ab.dot(cp);
    let d6 = ac.dot(cp);
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return a + w * ac;
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return b + w * (c - b);
    }
    let denom = va + vb + vc;
    if denom.abs() < f64::MIN_POSITIVE {
        return a;
    }
    let v = vb / denom;
    let w = vc / denom;
    a + ab * v + ac * w
}
