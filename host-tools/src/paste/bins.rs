//! Counting sort into the cells of a uniform grid, shared by the neighbour searches of `grow`
//! (rebuilt every iteration, so the buffers are reused) and of the cure check.

/// Sorts the items into `cells` cells: afterwards `order[starts[c]..starts[c + 1]]` holds the
/// indices of the items of cell `c`, in the order `items` gives them. `items` yields
/// `(index, cell)` with `cell < cells` and is walked twice (count, then place); the three
/// buffers are cleared and reused.
pub(super) fn bin_by_cell<I: Iterator<Item = (u32, usize)>>(
    cells: usize,
    items: impl Fn() -> I,
    starts: &mut Vec<u32>,
    cursor: &mut Vec<u32>,
    order: &mut Vec<u32>,
) {
    starts.clear();
    starts.resize(cells + 1, 0);
    for (_, c) in items() {
        starts[c + 1] += 1;
    }
    for i in 0..cells {
        starts[i + 1] += starts[i];
    }
    cursor.clear();
    cursor.extend_from_slice(&starts[..cells]);
    order.clear();
    order.resize(starts[cells] as usize, 0);
    for (k, c) in items() {
        let slot = cursor[c] as usize;
        order[slot] = k;
        cursor[c] += 1;
    }
}
