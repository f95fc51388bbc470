//! The paper's experiment geometry (Yamauchi & Morishige, Fig. 6): a base block whose top is a
//! 15° slope and a triangular pyramid. Used by `examples/additive` and the tests.

use super::stl::{prism_mesh, Mesh};
use glam::{DVec2, DVec3};

/// A block with footprint `width_mm × depth_mm` at `corner` (XY, on the bed), `low_mm` high at
/// its front (`y = corner.y`) and rising at `slope_deg` towards +Y.
pub fn slope_base(
    corner: DVec2,
    width_mm: f64,
    depth_mm: f64,
    low_mm: f64,
    slope_deg: f64,
) -> Mesh {
    let rise = depth_mm * slope_deg.to_radians().tan();
    let (x0, y0) = (corner.x, corner.y);
    let (x1, y1) = (x0 + width_mm, y0 + depth_mm);
    let p = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
    // Eight corners: bottom 0..4, top 4..8 (front low, back high).
    let b = [
        p(x0, y0, 0.0),
        p(x1, y0, 0.0),
        p(x1, y1, 0.0),
        p(x0, y1, 0.0),
    ];
    let t = [
        p(x0, y0, low_mm),
        p(x1, y0, low_mm),
        p(x1, y1, low_mm + rise),
        p(x0, y1, low_mm + rise),
    ];
    let quads = [
        [b[0], b[3], b[2], b[1]], // bottom (normal −Z)
        [t[0], t[1], t[2], t[3]], // slope (normal up and towards −Y)
        [b[0], b[1], t[1], t[0]], // front
        [b[1], b[2], t[2], t[1]], // right
        [b[2], b[3], t[3], t[2]], // back
        [b[3], b[0], t[0], t[3]], // left
    ];
    let mut tris = Vec::new();
    for q in quads {
        tris.push([q[0], q[1], q[2]]);
        tris.push([q[0], q[2], q[3]]);
    }
    Mesh::from_triangles(&tris)
}

/// Index of the first slope triangle in [`slope_base`] (the slope is faces 2 and 3).
pub const SLOPE_FACE: usize = 2;

/// Centre of the slope face of [`slope_base`] (a point for `--at`).
pub fn slope_centre(
    corner: DVec2,
    width_mm: f64,
    depth_mm: f64,
    low_mm: f64,
    slope_deg: f64,
) -> DVec3 {
    let rise = depth_mm * slope_deg.to_radians().tan();
    DVec3::new(
        corner.x + width_mm / 2.0,
        corner.y + depth_mm / 2.0,
        low_mm + rise / 2.0,
    )
}

/// A triangular pyramid: equilateral base of side `side_mm` centred on the origin at z = 0,
/// apex `height_mm` above the centre.
pub fn triangular_pyramid(side_mm: f64, height_mm: f64) -> Mesh {
    let r = side_mm / 3f64.sqrt();
    let outline: Vec<DVec2> = (0..3)
        .map(|i| DVec2::from_angle((90.0 + 120.0 * i as f64).to_radians()) * r)
        .collect();
    prism_mesh(&outline, 0.0, height_mm, 0.0, DVec2::ZERO)
}
