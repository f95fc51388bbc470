//! The checks' spatial index: every sample point the design will print, known before the
//! checks start, sorted once into XY columns (a counting sort by column, then by height
//! inside each column: one flat array, CSR layout), of which only the first `printed` (in
//! print order) count as printed material. Printing a string is then just moving that
//! count on, with no allocation.
//!
//! - [`Grid::nearest_below`] (support and widening at a string's end) and
//!   [`Grid::any_below`] (support along a string): started from the points printed right
//!   after the previous answer (consecutive queries follow the material below them, so the
//!   previous answer's successor is usually the answer or close to it), then the query's own
//!   column, then the columns within the best distance so far; in each column a binary search
//!   finds the highest point allowed and the scan goes down, stopping as soon as the height
//!   difference alone is farther than the best point.
//! - [`Grid::any_at_or_above`] (travel): the columns under a small XY box, skipped in O(1)
//!   when their highest printed point is lower than asked, else only the points between the
//!   asked height and that top.
//!
//! The answers are exactly those of a scan over the printed points (the property tests
//! in `checks::scan` compare them): the nearest point, ties to the earliest printed.
//! Replaces a grid of cubic cells with one growable list per cell (and, before it, an
//! R*-tree), which cost 2.1× (and ~10×) the compile on the globe.

use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};
use std::ops::Range;

/// A multiplicative hash for small integer keys (the std SipHash is several times slower and
/// guards against adversarial keys, which column coordinates are not).
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

/// Most columns indexed directly (16 MB of ids, zeroed lazily by the allocator); beyond
/// that (designs spread over kilometres) the columns are hashed.
const MAX_DENSE_COLUMNS: i64 = 1 << 22;

/// How a column's cell coordinates map to its id (0..count).
enum ColumnIds {
    /// `ids[(iy - lo.1) * nx + (ix - lo.0)]` holds 1 + the id (0: no points).
    Dense {
        lo: [i32; 2],
        nx: i32,
        ny: i32,
        ids: Vec<u32>,
    },
    /// Sparse designs.
    Hashed(Map<[i32; 2], u32>),
}

impl ColumnIds {
    #[inline(always)]
    fn get(&self, ix: i32, iy: i32) -> Option<usize> {
        match self {
            ColumnIds::Dense { lo, nx, ny, ids } => {
                let (dx, dy) = (ix.wrapping_sub(lo[0]), iy.wrapping_sub(lo[1]));
                // Negative differences wrap to huge unsigned values: one comparison per axis.
                if (dx as u32) >= (*nx as u32) || (dy as u32) >= (*ny as u32) {
                    return None;
                }
                let id = ids[dy as usize * *nx as usize + dx as usize];
                id.checked_sub(1).map(|v| v as usize)
            }
            ColumnIds::Hashed(m) => m.get(&[ix, iy]).map(|v| *v as usize),
        }
    }
}

/// The printed-so-far view of a design's sample points, in XY columns of `cell_mm`.
pub struct Grid {
    cell_mm: f64,
    /// `1 / cell_mm`: a column index is `floor(v * inv_cell)` (a product, not a division,
    /// the same at build and query time).
    inv_cell: f64,
    /// Every point in print order (the queries' warm start reads its neighbours here).
    points: Vec<[f64; 3]>,
    /// How many of `points` are printed.
    printed: usize,
    /// Print index of the last point a query found (its successor starts the next query).
    hint: usize,
    ids: ColumnIds,
    /// Column cell coordinates covered by some point: query boxes are clipped to them.
    extent: [[i32; 2]; 2],
    /// Per column id: its entries and search state (one cache line for a query's lookups).
    cols: Vec<Column>,
    /// Column id of each point in print order (`u32::MAX`: not indexed, NaN).
    column_of: Vec<u32>,
    /// The points column by column, by height (ascending) within each.
    entries: Vec<Entry>,
}

/// A point in its column (32 bytes: two per cache line, all a scan reads of one point).
#[derive(Clone, Copy)]
struct Entry {
    x_mm: f64,
    y_mm: f64,
    z_mm: f64,
    /// Print index: only `seq < printed` is printed material.
    seq: u32,
}

/// One XY column: entries `start..end` of the arrays in [`Grid`].
#[derive(Clone, Copy)]
struct Column {
    /// Cell coordinates (ix, iy).
    key: [i32; 2],
    start: u32,
    end: u32,
    /// Where the last support query's height split the column (queries climb slowly: the
    /// next split is usually at or next to it, found without a binary search).
    cursor: u32,
    /// Highest printed z (−∞ before the column's first printed point).
    top_z: f64,
}

/// The best point so far of a nearest search: squared distance and print index.
#[derive(Clone, Copy)]
struct Best {
    d2: f64,
    seq: usize,
}

impl Best {
    /// True when the point at `d2`, printed at `seq`, is better: nearer, or as near and
    /// printed earlier (the tie rule that makes the answer independent of the search order).
    #[inline]
    fn beaten_by(&self, d2: f64, seq: usize) -> bool {
        d2 < self.d2 || (d2 == self.d2 && seq < self.seq)
    }
}

/// Squared distance, summed in the same order everywhere (the scan reference included), so
/// equal points compare equal to the last bit.
#[inline]
pub fn dist2(p: [f64; 3], q: [f64; 3]) -> f64 {
    (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)
}

impl Grid {
    /// Indexes `points` (every point the design will print, in print order) in XY columns
    /// of `cell_mm`; none is printed yet. Points with a NaN coordinate are never found (no
    /// distance or comparison with NaN holds), so they are left out, and so are points past
    /// the first `u32::MAX - 1` (indices are 32-bit; such a design would need over 100 GB for
    /// its points alone, so the allocation fails long before).
    pub fn build(cell_mm: f64, points: Vec<[f64; 3]>) -> Grid {
        let cell_mm = if cell_mm > 0.0 && cell_mm.is_finite() {
            cell_mm
        } else {
            1.0
        };
        let inv_cell = 1.0 / cell_mm;
        let n = points.len().min(u32::MAX as usize - 1);
        let indexed = |p: &[f64; 3]| !p.iter().any(|v| v.is_nan());
        // The column extent from the coordinates' extent (the column of a coordinate grows
        // with it).
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for p in points[..n].iter().filter(|p| indexed(p)) {
            for a in 0..2 {
                lo[a] = lo[a].min(p[a]);
                hi[a] = hi[a].max(p[a]);
            }
        }
        let extent = [
            lo.map(|v| floor_div(v, inv_cell)),
            hi.map(|v| floor_div(v, inv_cell)),
        ];
        let span = |a: usize| i64::from(extent[1][a]) - i64::from(extent[0][a]) + 1;
        let dense =
            span(0) > 0 && span(1) > 0 && span(0).saturating_mul(span(1)) <= MAX_DENSE_COLUMNS;
        let mut ids = if dense {
            ColumnIds::Dense {
                lo: extent[0],
                nx: span(0) as i32,
                ny: span(1) as i32,
                ids: vec![0; (span(0) * span(1)) as usize],
            }
        } else {
            ColumnIds::Hashed(Map::default())
        };
        // Column ids in order of first appearance, and the size of each column.
        let mut count: Vec<u32> = Vec::new();
        let mut keys = Vec::new();
        let mut column_of = Vec::with_capacity(n);
        for p in &points[..n] {
            if !indexed(p) {
                column_of.push(u32::MAX);
                continue;
            }
            let (ix, iy) = (floor_div(p[0], inv_cell), floor_div(p[1], inv_cell));
            let next = count.len() as u32;
            let id = match &mut ids {
                ColumnIds::Dense { lo, nx, ids, .. } => {
                    let slot =
                        &mut ids[(iy - lo[1]) as usize * *nx as usize + (ix - lo[0]) as usize];
                    if *slot == 0 {
                        *slot = next + 1;
                    }
                    *slot - 1
                }
                ColumnIds::Hashed(m) => *m.entry([ix, iy]).or_insert(next),
            };
            if id == next {
                count.push(0);
                keys.push([ix, iy]);
            }
            count[id as usize] += 1;
            column_of.push(id);
        }
        // Counting sort by column (print order inside each), then by height in each column
        // (a stable sort: print order stays for equal heights; layered designs print
        // upwards, so most columns are sorted already and the sort only checks them).
        let mut cols = Vec::with_capacity(count.len());
        let mut total = 0u32;
        for (c, key) in count.iter().zip(keys) {
            cols.push(Column {
                key,
                start: total,
                end: total,
                cursor: 0,
                top_z: f64::NEG_INFINITY,
            });
            total += c;
        }
        let mut entries = vec![
            Entry {
                x_mm: 0.0,
                y_mm: 0.0,
                z_mm: 0.0,
                seq: 0,
            };
            total as usize
        ];
        for (i, (c, p)) in column_of.iter().zip(&points).enumerate() {
            if let Some(col) = cols.get_mut(*c as usize) {
                entries[col.end as usize] = Entry {
                    x_mm: p[0],
                    y_mm: p[1],
                    z_mm: p[2],
                    seq: i as u32,
                };
                col.end += 1;
            }
        }
        for c in &cols {
            let col = &mut entries[c.start as usize..c.end as usize];
            if !col.is_sorted_by(|a, b| a.z_mm <= b.z_mm) {
                col.sort_by(|a, b| a.z_mm.total_cmp(&b.z_mm));
            }
        }
        Grid {
            cell_mm,
            inv_cell,
            points,
            printed: 0,
            hint: 0,
            ids,
            extent,
            cols,
            column_of,
            entries,
        }
    }

    /// Point `i` in print order.
    pub fn point(&self, i: usize) -> [f64; 3] {
        self.points[i]
    }

    /// How many points (a prefix in print order) are printed.
    pub fn printed(&self) -> usize {
        self.printed
    }

    /// Marks the points before `end` (in print order) as printed.
    pub fn print_through(&mut self, end: usize) {
        let end = end.min(self.points.len());
        for i in self.printed..end {
            let c = self.column_of.get(i).map_or(u32::MAX, |c| *c);
            if let Some(c) = self.cols.get_mut(c as usize) {
                c.top_z = c.top_z.max(self.points[i][2]);
            }
        }
        self.printed = self.printed.max(end);
    }

    /// Column index of a coordinate.
    #[inline]
    fn idx(&self, v: f64) -> i32 {
        floor_div(v, self.inv_cell)
    }

    /// Column cell coordinates of `lo..=hi` along axis `a`, clipped to the indexed extent
    /// (in i64: the extent may reach `i32::MAX`, whose successor ends the range).
    #[inline]
    fn span(&self, a: usize, lo: f64, hi: f64) -> Range<i64> {
        let l = i64::from(self.idx(lo).max(self.extent[0][a]));
        let h = i64::from(self.idx(hi).min(self.extent[1][a]));
        l..(h + 1).max(l)
    }

    /// True when the box `xs` × `ys` has more cells than there are columns with points (tiny
    /// cells, far-flung points or a huge radius): a query then walks the list of those
    /// columns instead of the cells, so its work stays bounded by the number of columns.
    #[inline]
    fn walk_list(&self, xs: &Range<i64>, ys: &Range<i64>) -> bool {
        (xs.end - xs.start).saturating_mul(ys.end - ys.start) > self.cols.len() as i64
    }

    /// The cells of column `c` when they lie in `xs` × `ys`.
    #[inline]
    fn listed(&self, c: usize, xs: &Range<i64>, ys: &Range<i64>) -> Option<(i32, i32)> {
        let [ix, iy] = self.cols[c].key;
        (xs.contains(&i64::from(ix)) && ys.contains(&i64::from(iy))).then_some((ix, iy))
    }

    /// Id and entries of a column (`None` when it has no points).
    #[inline(always)]
    fn column(&self, ix: i32, iy: i32) -> Option<(usize, Range<usize>)> {
        let c = self.ids.get(ix, iy)?;
        let col = &self.cols[c];
        Some((c, col.start as usize..col.end as usize))
    }

    /// Squared distance from `q` to column `(ix, iy)` in XY, a hair short (its edges widened
    /// by 1e-9 of their size) so rounding never makes a point inside seem farther.
    #[inline]
    fn gap2(&self, q: [f64; 3], ix: i32, iy: i32) -> f64 {
        let axis = |v: f64, i: i32| {
            let l = f64::from(i) * self.cell_mm;
            let h = l + self.cell_mm;
            let w = 1e-9 * (1.0 + l.abs() + self.cell_mm);
            if v < l - w {
                l - w - v
            } else if v > h + w {
                v - h - w
            } else {
                0.0
            }
        };
        axis(q[0], ix).powi(2) + axis(q[1], iy).powi(2)
    }

    /// The print index of the nearest printed point within `sqrt(r2)` of `q` whose z is at
    /// most `max_z` (ties to the earliest printed), if any.
    pub fn nearest_below(&mut self, q: [f64; 3], r2: f64, max_z: f64) -> Option<usize> {
        let best = self.search(q, r2, max_z, false)?;
        self.hint = best.seq;
        Some(best.seq)
    }

    /// True when some printed point within `sqrt(r2)` of `q` has z at most `max_z`.
    pub fn any_below(&mut self, q: [f64; 3], r2: f64, max_z: f64) -> bool {
        match self.search(q, r2, max_z, true) {
            Some(b) => {
                self.hint = b.seq;
                true
            }
            None => false,
        }
    }

    /// The nearest (or, with `first`, any) printed point within `sqrt(r2)` of `q` at most
    /// `max_z` high: warm start from the last answer's successors, then q's own column, then
    /// the columns the best distance so far still reaches.
    fn search(&mut self, q: [f64; 3], r2: f64, max_z: f64, first: bool) -> Option<Best> {
        let mut best = Best {
            d2: r2,
            seq: usize::MAX,
        };
        for s in [self.hint + 1] {
            if s < self.printed {
                let p = self.points[s];
                let d2 = dist2(p, q);
                if p[2] <= max_z && best.beaten_by(d2, s) {
                    best = Best { d2, seq: s };
                    if first {
                        return Some(best);
                    }
                }
            }
        }
        let (cx, cy) = (self.idx(q[0]), self.idx(q[1]));
        if self.scan_column(q, max_z, cx, cy, 0.0, &mut best) && first {
            return Some(best);
        }
        // The box the best distance reaches, a hair wide (see `gap2`).
        let b = best.d2.sqrt();
        let b = b + 1e-9 * (1.0 + b + q[0].abs().max(q[1].abs()));
        let (xs, ys) = (
            self.span(0, q[0] - b, q[0] + b),
            self.span(1, q[1] - b, q[1] + b),
        );
        let mut visit = |g: &mut Grid, ix: i32, iy: i32| {
            // True when the search is over (`first` and found).
            if ix == cx && iy == cy {
                return false;
            }
            let g2 = g.gap2(q, ix, iy);
            g2 <= best.d2 && g.scan_column(q, max_z, ix, iy, g2, &mut best) && first
        };
        if self.walk_list(&xs, &ys) {
            for c in 0..self.cols.len() {
                if let Some((ix, iy)) = self.listed(c, &xs, &ys) {
                    if visit(self, ix, iy) {
                        return Some(best);
                    }
                }
            }
        } else {
            // Inside the extent, so within i32.
            for ix in xs.clone() {
                for iy in ys.clone() {
                    if visit(self, ix as i32, iy as i32) {
                        return Some(best);
                    }
                }
            }
        }
        (best.seq != usize::MAX).then_some(best)
    }

    /// Scans one column from its highest point at most `max_z` down, until the height
    /// difference plus the column's XY gap `g2` alone exceeds the best distance; true when
    /// it improved `best`.
    #[inline]
    fn scan_column(
        &mut self,
        q: [f64; 3],
        max_z: f64,
        ix: i32,
        iy: i32,
        g2: f64,
        best: &mut Best,
    ) -> bool {
        let Some((c, r)) = self.column(ix, iy) else {
            return false;
        };
        let col = &self.entries[r];
        let top = split_near(col, self.cols[c].cursor as usize, max_z);
        self.cols[c].cursor = top as u32;
        let mut improved = false;
        for e in col[..top].iter().rev() {
            let dz2 = (e.z_mm - q[2]).powi(2);
            if g2 + dz2 > best.d2 {
                if e.z_mm <= q[2] {
                    break; // every point lower is farther still
                }
                continue;
            }
            let s = e.seq as usize;
            if s >= self.printed {
                continue;
            }
            let d2 = dist2([e.x_mm, e.y_mm, e.z_mm], q);
            if best.beaten_by(d2, s) {
                *best = Best { d2, seq: s };
                improved = true;
            }
        }
        improved
    }

    /// True when a printed point lies in the XY box `lo..=hi` at height `min_z` or above.
    pub fn any_at_or_above(&self, lo: [f64; 2], hi: [f64; 2], min_z: f64) -> bool {
        if min_z.is_nan() {
            return false; // no height is at or above NaN
        }
        let found = |ix: i32, iy: i32| {
            let Some((c, r)) = self.column(ix, iy) else {
                return false;
            };
            let top = self.cols[c].top_z;
            if top < min_z {
                return false;
            }
            let col = &self.entries[r];
            for e in &col[col.partition_point(|e| e.z_mm < min_z)..] {
                if e.z_mm > top {
                    break; // nothing printed above the top
                }
                if (e.seq as usize) < self.printed
                    && e.x_mm >= lo[0]
                    && e.x_mm <= hi[0]
                    && e.y_mm >= lo[1]
                    && e.y_mm <= hi[1]
                {
                    return true;
                }
            }
            false
        };
        let (xs, ys) = (self.span(0, lo[0], hi[0]), self.span(1, lo[1], hi[1]));
        if self.walk_list(&xs, &ys) {
            (0..self.cols.len()).any(|c| {
                self.listed(c, &xs, &ys)
                    .is_some_and(|(ix, iy)| found(ix, iy))
            })
        } else {
            // Inside the extent, so within i32.
            xs.clone()
                .any(|ix| ys.clone().any(|iy| found(ix as i32, iy as i32)))
        }
    }
}

/// The number of entries in `zs` (ascending heights) at most `max_z` high, searched outwards from `guess`
/// (doubling steps, then halving): O(1) when the guess is right or next to it, O(log n) at
/// worst. Equals `zs.partition_point(|e| e.z_mm <= max_z)`.
#[inline]
fn split_near(zs: &[Entry], guess: usize, max_z: f64) -> usize {
    let below = |i: usize| zs[i].z_mm <= max_z;
    let n = zs.len();
    let g = guess.min(n);
    if g < n && below(g) {
        // The split is above g: find a step that passes it, then binary search.
        let (mut lo, mut step) = (g + 1, 1);
        while lo + step - 1 < n && below(lo + step - 1) {
            lo += step;
            step *= 2;
        }
        let hi = (lo + step - 1).min(n);
        lo + zs[lo..hi].partition_point(|e| e.z_mm <= max_z)
    } else {
        // The split is at or below g.
        let (mut hi, mut step) = (g, 1);
        while hi >= step && !below(hi - step) {
            hi -= step;
            step *= 2;
        }
        let lo = hi.saturating_sub(step - 1);
        lo + zs[lo..hi].partition_point(|e| e.z_mm <= max_z)
    }
}

/// `floor(v * inv_cell)` as a cell coordinate, saturating beyond ±2^31 cells (NaN gives 0), without
/// the libm `floor` call (x86-64 without SSE4.1 has no rounding instruction).
#[inline]
fn floor_div(v: f64, inv_cell: f64) -> i32 {
    let x = v * inv_cell;
    let t = x as i32;
    if f64::from(t) > x {
        t.saturating_sub(1)
    } else {
        t
    }
}

#[cfg(test)]
mod tests {
    use super::{split_near, Entry};
    use proptest::prelude::*;

    proptest! {
        /// The split found from any guess is the binary search's (ties, guesses past the end
        /// and a NaN height included).
        #[test]
        fn split_near_is_the_partition_point(
            mut zs in proptest::collection::vec(0u8..20, 0..80),
            guess in 0usize..90,
            max_z in prop_oneof![(0u8..22).prop_map(f64::from), Just(f64::NAN), -1.0f64..21.0],
        ) {
            zs.sort_unstable();
            let col: Vec<Entry> = zs
                .into_iter()
                .map(|z| Entry { x_mm: 0.0, y_mm: 0.0, z_mm: f64::from(z), seq: 0 })
                .collect();
            prop_assert_eq!(
                split_near(&col, guess, max_z),
                col.partition_point(|e| e.z_mm <= max_z)
            );
        }
    }
}
