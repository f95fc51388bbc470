//! The checks' spatial index: printed points in a uniform grid of cubic cells, hashed by cell
//! coordinates (a design occupies a thin shell of its bounding box, so a dense array would be
//! mostly empty), plus the highest point of every XY column.
//!
//! - [`Grid::nearest_below`] (support): the 3×3×3 cells around the point when the radius is
//!   at most the cell size;
//! - [`Grid::any_at_or_above`] (travel): the columns under a small XY box, skipped in O(1)
//!   when their highest point is lower than asked, else only the cells from that height up.
//!
//! Replaces an R*-tree (`rstar`), whose incremental inserts cost ~10× the whole compile.

use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

/// A multiplicative hash for small integer keys (the std SipHash is several times slower and
/// guards against adversarial keys, which cell coordinates are not).
#[derive(Default)]
pub struct CellHasher(u64);

impl Hasher for CellHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(u64::from(b));
        }
    }
    fn write_u64(&mut self, v: u64) {
        self.0 = (self.0.rotate_left(5) ^ v).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }
    fn write_i32(&mut self, v: i32) {
        self.write_u64(u64::from(v as u32));
    }
    fn write_usize(&mut self, v: usize) {
        self.write_u64(v as u64);
    }
}

type Map<K, V> = HashMap<K, V, BuildHasherDefault<CellHasher>>;

/// Printed points in cubic cells of `cell` mm.
pub struct Grid {
    cell: f64,
    cells: Map<[i32; 3], Vec<[f64; 3]>>,
    /// Highest point per XY column.
    columns: Map<[i32; 2], f64>,
}

impl Grid {
    /// An empty grid with cells of `cell_mm` (the support radius: a radius query then touches
    /// 3×3×3 cells).
    pub fn new(cell_mm: f64) -> Grid {
        Grid {
            cell: cell_mm,
            cells: Map::default(),
            columns: Map::default(),
        }
    }

    fn idx(&self, v: f64) -> i32 {
        // Saturating: coordinates beyond ±2^31 cells land in the edge cells.
        (v / self.cell).floor() as i32
    }

    /// Adds a printed point.
    pub fn insert(&mut self, p: [f64; 3]) {
        let k = [self.idx(p[0]), self.idx(p[1]), self.idx(p[2])];
        self.cells.entry(k).or_default().push(p);
        let top = self
            .columns
            .entry([k[0], k[1]])
            .or_insert(f64::NEG_INFINITY);
        *top = top.max(p[2]);
    }

    /// The nearest point within `sqrt(r2)` of `q` whose z is at most `max_z`, if any.
    pub fn nearest_below(&self, q: [f64; 3], r2: f64, max_z: f64) -> Option<[f64; 3]> {
        let r = r2.sqrt();
        let lo = [self.idx(q[0] - r), self.idx(q[1] - r), self.idx(q[2] - r)];
        let hi = [
            self.idx(q[0] + r),
            self.idx(q[1] + r),
            self.idx(q[2].min(max_z)),
        ];
        let mut best: Option<(f64, [f64; 3])> = None;
        for ix in lo[0]..=hi[0] {
            for iy in lo[1]..=hi[1] {
                if !self.columns.contains_key(&[ix, iy]) {
                    continue;
                }
                for iz in lo[2]..=hi[2] {
                    let Some(pts) = self.cells.get(&[ix, iy, iz]) else {
                        continue;
                    };
                    for p in pts {
                        if p[2] > max_z {
                            continue;
                        }
                        let d2 =
                            (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2);
                        if d2 <= r2 && best.is_none_or(|(b, _)| d2 < b) {
                            best = Some((d2, *p));
                        }
                    }
                }
            }
        }
        best.map(|(_, p)| p)
    }

    /// True when a point lies in the XY box `lo..=hi` at height `min_z` or above.
    pub fn any_at_or_above(&self, lo: [f64; 2], hi: [f64; 2], min_z: f64) -> bool {
        for ix in self.idx(lo[0])..=self.idx(hi[0]) {
            for iy in self.idx(lo[1])..=self.idx(hi[1]) {
                let Some(&top) = self.columns.get(&[ix, iy]) else {
                    continue;
                };
                if top < min_z {
                    continue;
                }
                for iz in self.idx(min_z)..=self.idx(top) {
                    let Some(pts) = self.cells.get(&[ix, iy, iz]) else {
                        continue;
                    };
                    if pts.iter().any(|p| {
                        p[2] >= min_z
                            && p[0] >= lo[0]
                            && p[0] <= hi[0]
                            && p[1] >= lo[1]
                            && p[1] <= hi[1]
                    }) {
                        return true;
                    }
                }
            }
        }
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The grid answers as a scan over every point does.
    #[test]
    fn matches_a_linear_scan() {
        let mut g = Grid::new(1.2);
        let mut pts = Vec::new();
        let mut x = 12345u64;
        let mut rnd = || {
            x = x
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (x >> 11) as f64 / (1u64 << 53) as f64
        };
        for _ in 0..3000 {
            let p = [rnd() * 20.0 - 10.0, rnd() * 20.0 - 10.0, rnd() * 10.0];
            g.insert(p);
            pts.push(p);
        }
        for _ in 0..500 {
            let q = [rnd() * 24.0 - 12.0, rnd() * 24.0 - 12.0, rnd() * 12.0];
            let (r2, max_z) = (1.44, q[2] - 0.05);
            let want = pts
                .iter()
                .filter(|p| p[2] <= max_z)
                .map(|p| {
                    (
                        (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2),
                        *p,
                    )
                })
                .filter(|(d2, _)| *d2 <= r2)
                .min_by(|a, b| a.0.total_cmp(&b.0))
                .map(|(_, p)| p);
            assert_eq!(g.nearest_below(q, r2, max_z), want);
            let (lo, hi, z) = (
                [q[0] - 0.3, q[1] - 0.3],
                [q[0] + 0.3, q[1] + 0.3],
                q[2] - 0.1,
            );
            let any = pts.iter().any(|p| {
                p[2] >= z && p[0] >= lo[0] && p[0] <= hi[0] && p[1] >= lo[1] && p[1] <= hi[1]
            });
            assert_eq!(g.any_at_or_above(lo, hi, z), any);
        }
    }
}
