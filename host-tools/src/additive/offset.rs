//! Inward offsetting of oriented loops (material on the left), for walls and infill bounds.
//!
//! Each loop is treated as a cycle of edge lines; every line moves `d` to its left and each
//! offset vertex is the intersection of two consecutive offset lines (a miter). An edge whose
//! offset reverses direction has collapsed: its line is dropped and the neighbours are
//! intersected directly, repeated until no edge reverses. That is exact for convex loops
//! (every section of the paper's pyramid) and for mildly concave ones; a loop whose offset
//! would split into pieces or cross itself is dropped (reported as `None`), and offsets that
//! make a hole overlap the outer boundary are not resolved. Reflex corners are mitered, with
//! the miter length limited to `MITER_LIMIT · d`.

use super::slice::signed_area;
use glam::DVec2;

/// Longest miter at a reflex corner, as a multiple of the offset distance.
pub const MITER_LIMIT: f64 = 4.0;

/// Offsets one loop `d` mm to its left. `None` when it vanishes or would self-intersect.
pub fn offset_loop(poly: &[DVec2], d: f64) -> Option<Vec<DVec2>> {
    if poly.len() < 3 {
        return None;
    }
    let area0 = signed_area(poly);
    // Lines as (point on the original edge, unit direction).
    let mut lines: Vec<(DVec2, DVec2)> = (0..poly.len())
        .filter_map(|i| {
            let a = poly[i];
            let b = poly[(i + 1) % poly.len()];
            let dir = (b - a).normalize_or_zero();
            (dir != DVec2::ZERO).then_some((a, dir))
        })
        .collect();
    for _ in 0..poly.len() + 1 {
        if lines.len() < 3 {
            return None;
        }
        let pts = offset_vertices(&lines, d);
        let n = pts.len();
        let collapsed = (0..n).find(|&i| {
            let e = pts[(i + 1) % n] - pts[i];
            e.dot(lines[i].1) <= 0.0
        });
        match collapsed {
            Some(i) => {
                lines.remove(i);
            }
            None => {
                let area = signed_area(&pts);
                if area * area0 <= 0.0 || area.abs() < 1e-9 || self_intersects(&pts) {
                    return None;
                }
                return Some(pts);
            }
        }
    }
    None
}

/// Vertex `i` joins offset line `i − 1` to offset line `i`.
fn offset_vertices(lines: &[(DVec2, DVec2)], d: f64) -> Vec<DVec2> {
    let n = lines.len();
    (0..n)
        .map(|i| {
            let (p1, d1) = lines[(i + n - 1) % n];
            let (p2, d2) = lines[i];
            let n1 = d1.perp();
            let n2 = d2.perp();
            let a = p1 + n1 * d;
            let b = p2 + n2 * d;
            let cross = d1.perp_dot(d2);
            if cross.abs() < 1e-12 {
                return b;
            }
            // a + s·d1 = b + t·d2
            let s = (b - a).perp_dot(d2) / cross;
            let q = a + d1 * s;
            // Limit the miter where the loop turns right (the offset side is the outer side
            // of that turn and the miter grows without bound for sharp turns).
            let limit = MITER_LIMIT * d.abs();
            if cross < 0.0 && (q - p2).length() > limit {
                let mid = (n1 + n2).normalize_or_zero();
                return p2 + mid * limit * d.signum();
            }
            q
        })
        .collect()
}

/// True when two non-adjacent edges of the closed polygon cross (O(n²); sections are small).
pub fn self_intersects(pts: &[DVec2]) -> bool {
    let n = pts.len();
    for i in 0..n {
        let (a, b) = (pts[i], pts[(i + 1) % n]);
        for j in i + 2..n {
            if i == 0 && j == n - 1 {
                continue;
            }
            let (c, e) = (pts[j], pts[(j + 1) % n]);
            if segments_cross(a, b, c, e) {
                return true;
            }
        }
    }
    false
}

/// Proper or touching intersection of segments `ab` and `cd`.
pub fn segments_cross(a: DVec2, b: DVec2, c: DVec2, d: DVec2) -> bool {
    let o1 = (b - a).perp_dot(c - a);
    let o2 = (b - a).perp_dot(d - a);
    let o3 = (d - c).perp_dot(a - c);
    let o4 = (d - c).perp_dot(b - c);
    if ((o1 > 0.0 && o2 < 0.0) || (o1 < 0.0 && o2 > 0.0))
        && ((o3 > 0.0 && o4 < 0.0) || (o3 < 0.0 && o4 > 0.0))
    {
        return true;
    }
    let on = |p: DVec2, q: DVec2, r: DVec2, o: f64| {
        o == 0.0
            && r.x >= p.x.min(q.x)
            && r.x <= p.x.max(q.x)
            && r.y >= p.y.min(q.y)
            && r.y <= p.y.max(q.y)
    };
    on(a, b, c, o1) || on(a, b, d, o2) || on(c, d, a, o3) || on(c, d, b, o4)
}

/// Offsets every loop of a region `d` mm into the material; vanished loops are left out.
pub fn offset_region(loops: &[Vec<DVec2>], d: f64) -> Vec<Vec<DVec2>> {
    loops.iter().filter_map(|l| offset_loop(l, d)).collect()
}
