//! Neighbour search for growth: a uniform grid over the nodes, rebuilt every iteration by a
//! counting sort, queried over the 3×3 cells around a point.

use crate::paste::bins::bin_by_cell;
use glam::DVec2;

/// Uniform grid over points, rebuilt by counting sort.
#[derive(Default)]
pub struct PointGrid {
    origin: DVec2,
    cell: f64,
    nx: usize,
    ny: usize,
    starts: Vec<u32>,
    order: Vec<u32>,
    cursor: Vec<u32>,
}

impl PointGrid {
    /// Rebuilds the grid over `pts` with cell size `cell`.
    pub fn rebuild(&mut self, pts: &[DVec2], cell: f64) {
        let (mut lo, mut hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
        for p in pts {
            lo = lo.min(*p);
            hi = hi.max(*p);
        }
        if pts.is_empty() {
            lo = DVec2::ZERO;
            hi = DVec2::ZERO;
        }
        self.origin = lo;
        self.cell = cell;
        self.nx = (((hi.x - lo.x) / cell) as usize + 1).min(1 << 14);
        self.ny = (((hi.y - lo.y) / cell) as usize + 1).min(1 << 14);
        let cells = self.nx * self.ny;
        let (mut starts, mut cursor, mut order) = (
            std::mem::take(&mut self.starts),
            std::mem::take(&mut self.cursor),
            std::mem::take(&mut self.order),
        );
        let items = || {
            pts.iter()
                .enumerate()
                .map(|(k, p)| (k as u32, self.cell_of(*p)))
        };
        bin_by_cell(cells, items, &mut starts, &mut cursor, &mut order);
        (self.starts, self.cursor, self.order) = (starts, cursor, order);
    }

    fn coords(&self, p: DVec2) -> (usize, usize) {
        let g = (p - self.origin) / self.cell;
        (
            (g.x.max(0.0) as usize).min(self.nx - 1),
            (g.y.max(0.0) as usize).min(self.ny - 1),
        )
    }

    fn cell_of(&self, p: DVec2) -> usize {
        let (x, y) = self.coords(p);
        y * self.nx + x
    }

    /// Calls `f(index)` for every point in the 3×3 cells around `p` (a superset of the points
    /// within one cell size).
    pub fn for_near(&self, p: DVec2, mut f: impl FnMut(usize)) {
        let (cx, cy) = self.coords(p);
        for y in cy.saturating_sub(1)..=(cy + 1).min(self.ny - 1) {
            for x in cx.saturating_sub(1)..=(cx + 1).min(self.nx - 1) {
                let c = y * self.nx + x;
                let (s, e) = (self.starts[c] as usize, self.starts[c + 1] as usize);
                for &k in &self.order[s..e] {
                    f(k as usize);
                }
            }
        }
    }
}
