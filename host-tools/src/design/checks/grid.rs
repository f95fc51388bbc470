//! The checks' spatial index: printed points in a uniform grid of cubic cells (the support
//! radius wide), indexed directly over the design's bounding box when that has
//! at most 4 M cells, hashed by cell coordinates otherwise (and outside the box), plus the
//! highest point of every XY column.
//!
//! - [`Grid::nearest_below`] (support): the cells around the point (3×3 columns, the heights
//!   below it), its own column first and from the top down, skipping cells farther than the
//!   best point so far;
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
    /// Cell height: `cell / Z_SPLIT`.
    cell_z: f64,
    /// Cells inside the design's bounding box, indexed directly (no hashing) when that box
    /// is small enough; `None` for huge designs.
    dense: Option<Dense>,
    /// Cells outside `dense` (all of them without it).
    cells: Map<[i32; 3], Vec<[f64; 3]>>,
    /// Highest point per XY column outside `dense`.
    columns: Map<[i32; 2], f64>,
}

/// A directly indexed block of cells: `slot` maps a cell to 1 + its index in `store` (0 =
/// empty; zeroed memory is an empty grid), `tops` holds each column's highest point.
struct Dense {
    lo: [i32; 3],
    n: [i32; 3],
    slot: Vec<u32>,
    store: Vec<Vec<[f64; 3]>>,
    tops: Vec<f64>,
}

/// Cells per `cell` of height (1: cubic cells; 2 and 4 measured no faster on the globe).
const Z_SPLIT: f64 = 1.0;

/// Most cells of a dense block (16 MB of slots, zeroed lazily by the allocator).
const MAX_DENSE_CELLS: i64 = 1 << 22;

impl Dense {
    #[inline]
    fn cell_index(&self, k: [i32; 3]) -> Option<usize> {
        let mut idx = 0i64;
        for a in (0..3).rev() {
            let d = i64::from(k[a]) - i64::from(self.lo[a]);
            if d < 0 || d >= i64::from(self.n[a]) {
                return None;
            }
            idx = idx * i64::from(self.n[a]) + d;
        }
        Some(idx as usize)
    }

    #[inline]
    fn column_index(&self, ix: i32, iy: i32) -> Option<usize> {
        let dx = i64::from(ix) - i64::from(self.lo[0]);
        let dy = i64::from(iy) - i64::from(self.lo[1]);
        if dx < 0 || dy < 0 || dx >= i64::from(self.n[0]) || dy >= i64::from(self.n[1]) {
            return None;
        }
        Some((dy * i64::from(self.n[0]) + dx) as usize)
    }
}

impl Grid {
    /// An empty grid with cells of `cell_mm` (the support radius: a radius query then touches
    /// 3×3×3 cells).
    pub fn new(cell_mm: f64) -> Grid {
        Grid {
            cell: cell_mm,
            cell_z: cell_mm / Z_SPLIT,
            dense: None,
            cells: Map::default(),
            columns: Map::default(),
        }
    }

    /// [`Grid::new`] with the cells of the box `lo..=hi` (the design's bounding box, grown by
    /// two cells) indexed directly when it has at most 4 M cells: no hashing on the hot path.
    /// Points outside the box still work (hashed).
    pub fn with_bounds(cell_mm: f64, lo: [f64; 3], hi: [f64; 3]) -> Grid {
        let mut g = Grid::new(cell_mm);
        if !(lo.iter().chain(&hi).all(|v| v.is_finite()) && cell_mm > 0.0) {
            return g;
        }
        let l = [
            g.idx(lo[0]).saturating_sub(2),
            g.idx(lo[1]).saturating_sub(2),
            g.idx_z(lo[2]).saturating_sub(2),
        ];
        let h = [
            g.idx(hi[0]).saturating_add(2),
            g.idx(hi[1]).saturating_add(2),
            g.idx_z(hi[2]).saturating_add(2),
        ];
        let n = [0, 1, 2].map(|a| i64::from(h[a]) - i64::from(l[a]) + 1);
        let total = n[0].saturating_mul(n[1]).saturating_mul(n[2]);
        if n.iter().any(|v| *v <= 0) || total > MAX_DENSE_CELLS {
            return g;
        }
        let n32 = n.map(|v| v as i32);
        g.dense = Some(Dense {
            lo: l,
            n: n32,
            slot: vec![0; total as usize],
            store: Vec::new(),
            tops: vec![f64::NEG_INFINITY; (n[0] * n[1]) as usize],
        });
        g
    }

    fn idx(&self, v: f64) -> i32 {
        // Saturating: coordinates beyond ±2^31 cells land in the edge cells.
        (v / self.cell).floor() as i32
    }

    fn idx_z(&self, v: f64) -> i32 {
        (v / self.cell_z).floor() as i32
    }

    /// Adds a printed point.
    pub fn insert(&mut self, p: [f64; 3]) {
        let k = [self.idx(p[0]), self.idx(p[1]), self.idx_z(p[2])];
        if let Some(d) = &mut self.dense {
            if let (Some(ci), Some(col)) = (d.cell_index(k), d.column_index(k[0], k[1])) {
                let s = d.slot[ci];
                if s == 0 {
                    d.store.push(vec![p]);
                    d.slot[ci] = d.store.len() as u32;
                } else {
                    d.store[s as usize - 1].push(p);
                }
                if p[2] > d.tops[col] {
                    d.tops[col] = p[2];
                }
                return;
            }
        }
        self.cells.entry(k).or_default().push(p);
        let top = self
            .columns
            .entry([k[0], k[1]])
            .or_insert(f64::NEG_INFINITY);
        *top = top.max(p[2]);
    }

    /// The points of one cell.
    #[inline]
    fn cell_points(&self, k: [i32; 3]) -> Option<&[[f64; 3]]> {
        if let Some(d) = &self.dense {
            if let Some(ci) = d.cell_index(k) {
                let s = d.slot[ci];
                return (s != 0).then(|| d.store[s as usize - 1].as_slice());
            }
        }
        self.cells.get(&k).map(Vec::as_slice)
    }

    /// The highest point of one XY column, if it has any.
    #[inline]
    fn column_top(&self, ix: i32, iy: i32) -> Option<f64> {
        // A column may hold dense cells and, above or below the dense block, hashed ones.
        let hashed = if self.columns.is_empty() {
            None
        } else {
            self.columns.get(&[ix, iy]).copied()
        };
        let dense = self
            .dense
            .as_ref()
            .and_then(|d| d.column_index(ix, iy).map(|c| d.tops[c]))
            .filter(|t| *t > f64::NEG_INFINITY);
        match (dense, hashed) {
            (Some(a), Some(b)) => Some(a.max(b)),
            (a, b) => a.or(b),
        }
    }

    /// The nearest point within `sqrt(r2)` of `q` whose z is at most `max_z`, if any.
    pub fn nearest_below(&self, q: [f64; 3], r2: f64, max_z: f64) -> Option<[f64; 3]> {
        let r = r2.sqrt();
        let lo = [self.idx(q[0] - r), self.idx(q[1] - r), self.idx_z(q[2] - r)];
        let hi = [
            self.idx(q[0] + r),
            self.idx(q[1] + r),
            self.idx_z(q[2].min(max_z)),
        ];
        let size = [self.cell, self.cell, self.cell_z];
        // Squared distance from q[a] to the cell interval i along axis a (0 inside it).
        let gap2 = |a: usize, i: i32| {
            let c = size[a];
            let (l, h) = (f64::from(i) * c, f64::from(i + 1) * c);
            let d = if q[a] < l {
                l - q[a]
            } else if q[a] > h {
                q[a] - h
            } else {
                0.0
            };
            d * d
        };
        let mut best: Option<(f64, [f64; 3])> = None;
        let mut best_d2 = r2;
        // The point's own column first (the material right below is usually there), then the
        // others; cells farther than the best point so far are skipped, and each column is
        // searched from the top down (nearest heights first).
        let (cx, cy) = (self.idx(q[0]), self.idx(q[1]));
        let centre = (lo[0]..=hi[0]).contains(&cx) && (lo[1]..=hi[1]).contains(&cy);
        let others = (lo[0]..=hi[0])
            .flat_map(|ix| (lo[1]..=hi[1]).map(move |iy| (ix, iy)))
            .filter(|&(ix, iy)| !(centre && ix == cx && iy == cy));
        for (ix, iy) in centre.then_some((cx, cy)).into_iter().chain(others) {
            let dxy = gap2(0, ix) + gap2(1, iy);
            if dxy > best_d2 || self.column_top(ix, iy).is_none() {
                continue;
            }
            for iz in (lo[2]..=hi[2]).rev() {
                if dxy + gap2(2, iz) > best_d2 {
                    continue;
                }
                let Some(pts) = self.cell_points([ix, iy, iz]) else {
                    continue;
                };
                for p in pts {
                    if p[2] > max_z {
                        continue;
                    }
                    let d2 = (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2);
                    if d2 <= best_d2 && best.is_none_or(|(b, _)| d2 < b) {
                        best = Some((d2, *p));
                        best_d2 = d2;
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
                let Some(top) = self.column_top(ix, iy) else {
                    continue;
                };
                if top < min_z {
                    continue;
                }
                for iz in self.idx_z(min_z)..=self.idx_z(top) {
                    let Some(pts) = self.cell_points([ix, iy, iz]) else {
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
        // Hashed only; dense over part of the points (the rest hashed); dense over all.
        for bounds in [
            None,
            Some(([-4.0, -4.0, 0.0], [4.0, 4.0, 5.0])),
            Some(([-10.0, -10.0, 0.0], [10.0, 10.0, 10.0])),
        ] {
            scan_matches(match bounds {
                None => Grid::new(1.2),
                Some((lo, hi)) => Grid::with_bounds(1.2, lo, hi),
            });
        }
    }

    fn scan_matches(mut g: Grid) {
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
