//! A uniform grid over the horizontal plane: which items (buildings, discs) may touch a
//! point, a rectangle or a segment.
//!
//! Cells are `cell_m` squares aligned on multiples of `cell_m` from the origin: cell `(i, j)`
//! covers east `[i c, (i + 1) c]` and north `[j c, (j + 1) c]`. An item is listed in every
//! cell its bounding rectangle touches (closed), so a point query looks at one cell. The
//! lists are stored compressed (CSR: one `starts` offset per cell into one `items` array),
//! built in two O(n) passes; items keep ascending order inside a cell.

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use super::building::clip_segment;

/// A horizontal bounding rectangle, ENU metres: `[min_east, min_north, max_east, max_north]`.
pub type Rect = [f64; 4];

/// Largest grid coordinate (cell index from the origin, either sign) of a consistent index:
/// 2^40 cells of a metre are 10^12 m, far beyond any world, and coordinate sums stay far
/// from `i64` overflow.
const MAX_COORD: i64 = 1 << 40;

/// Uniform-grid index of items given by their bounding rectangles (item `k` is `rects[k]`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GridIndex {
    cell_m: f64,
    /// Grid coordinates of cell 0 of the stored block of cells.
    i0: i64,
    j0: i64,
    nx: usize,
    ny: usize,
    /// `starts[c]..starts[c + 1]` are cell `c`'s entries in `items`; `c = j nx + i`.
    starts: Vec<u32>,
    items: Vec<u32>,
}

impl GridIndex {
    /// Indexes `rects` on a grid of `cell_m` cells. Empty input gives an empty grid.
    ///
    /// # Assumptions
    /// `cell_m > 0`, rectangles finite with min <= max, fewer than 2^32 entries.
    pub fn new(cell_m: f64, rects: &[Rect]) -> Self {
        let mut grid = Self { cell_m, i0: 0, j0: 0, nx: 0, ny: 0, starts: vec![0], items: vec![] };
        if rects.is_empty() {
            return grid;
        }
        let (mut i_lo, mut j_lo, mut i_hi, mut j_hi) = (i64::MAX, i64::MAX, i64::MIN, i64::MIN);
        for r in rects {
            i_lo = i_lo.min(grid.coord(r[0]));
            j_lo = j_lo.min(grid.coord(r[1]));
            i_hi = i_hi.max(grid.coord(r[2]));
            j_hi = j_hi.max(grid.coord(r[3]));
        }
        grid.i0 = i_lo;
        grid.j0 = j_lo;
        grid.nx = (i_hi - i_lo + 1) as usize;
        grid.ny = (j_hi - j_lo + 1) as usize;

        // Pass 1: count entries per cell (shifted by one), prefix-sum into offsets.
        let mut starts = vec![0_u32; grid.nx * grid.ny + 1];
        for r in rects {
            grid.for_cells_in(r, |c| starts[c + 1] += 1);
        }
        for c in 0..grid.nx * grid.ny {
            starts[c + 1] += starts[c];
        }
        // Pass 2: fill, in item order, so every cell lists its items ascending.
        let mut fill = starts.clone();
        let mut items = vec![0_u32; starts[grid.nx * grid.ny] as usize];
        for (k, r) in rects.iter().enumerate() {
            grid.for_cells_in(r, |c| {
                items[fill[c] as usize] = k as u32;
                fill[c] += 1;
            });
        }
        grid.starts = starts;
        grid.items = items;
        grid
    }

    /// Whether the offsets and entries fit together and name items below `items`, and the
    /// block of cells is empty or lies within [`MAX_COORD`] of the origin (for a decoded
    /// index: queries on it then stay in bounds and their integer arithmetic cannot
    /// overflow).
    pub fn is_consistent(&self, items: usize) -> bool {
        let cells = self.nx.checked_mul(self.ny).and_then(|c| c.checked_add(1));
        let within =
            |origin: i64, n: usize| (-MAX_COORD..=MAX_COORD).contains(&origin) && (n as u64) <= MAX_COORD as u64;
        cells == Some(self.starts.len())
            && (self.nx == 0) == (self.ny == 0)
            && within(self.i0, self.nx)
            && within(self.j0, self.ny)
            && self.starts.first() == Some(&0)
            && self.starts.windows(2).all(|w| w[0] <= w[1])
            && self.starts.last().is_some_and(|&n| n as usize == self.items.len())
            && self.items.iter().all(|&k| (k as usize) < items)
            && self.cell_m > 0.0
            && self.cell_m.is_finite()
    }

    /// Items whose rectangle may contain the point (all that do, plus others).
    pub fn at(&self, east_m: f64, north_m: f64) -> &[u32] {
        match self.cell_index(self.coord(east_m).saturating_sub(self.i0), self.coord(north_m).saturating_sub(self.j0)) {
            Some(c) => self.cell(c),
            None => &[],
        }
    }

    /// Items whose rectangle may touch `rect`. An item spanning several cells is yielded
    /// once per cell.
    pub fn in_rect(&self, rect: &Rect) -> impl Iterator<Item = u32> + '_ {
        let rel = |v_m: f64, origin: i64| self.coord(v_m).saturating_sub(origin);
        let (i_lo, i_hi) = self.clamp_range(rel(rect[0], self.i0), rel(rect[2], self.i0), self.nx);
        let (j_lo, j_hi) = self.clamp_range(rel(rect[1], self.j0), rel(rect[3], self.j0), self.ny);
        (j_lo..j_hi).flat_map(move |j| (i_lo..i_hi).flat_map(move |i| self.cell(j * self.nx + i).iter().copied()))
    }

    /// The first item met along the segment `a -> b` and its segment parameter `t` in [0, 1]
    /// (point `a + t (b - a)`), where `entry_t(k)` is the smallest `t` at which item `k` meets
    /// the segment. Only the part of the segment with `z` in `[z_lo, z_hi]` is walked: items
    /// are assumed to lie inside that height band. Ties go to the lower item index.
    ///
    /// Walks the cells the segment crosses in order (Amanatides & Woo 1987) and stops at the
    /// first cell whose exit lies beyond the best hit so far: an item in a later cell can only
    /// be met after that cell's entry. O(cells crossed), not O(items).
    ///
    /// # Caveats
    /// Where the segment passes exactly through a cell corner the diagonal cell is skipped;
    /// it shares a single point with the segment.
    pub fn first_hit(
        &self,
        a: &Vector3<f64>,
        b: &Vector3<f64>,
        z_lo: f64,
        z_hi: f64,
        mut entry_t: impl FnMut(u32) -> Option<f64>,
    ) -> Option<(u32, f64)> {
        if self.nx == 0 {
            return None;
        }
        let c = self.cell_m;
        let lo = Vector3::new(self.i0 as f64 * c, self.j0 as f64 * c, z_lo);
        let hi = Vector3::new((self.i0 + self.nx as i64) as f64 * c, (self.j0 + self.ny as i64) as f64 * c, z_hi);
        let d = b - a;
        let (t_lo, t_hi) = clip_segment(a, &d, &lo, &hi)?;

        let start = a + d * t_lo;
        let mut i = self.coord(start.x).saturating_sub(self.i0).clamp(0, self.nx as i64 - 1);
        let mut j = self.coord(start.y).saturating_sub(self.j0).clamp(0, self.ny as i64 - 1);
        let (step_i, step_j) = (step(d.x), step(d.y));
        // Parameter at which the segment leaves the current column / row. Recomputed from
        // the boundary each time (not accumulated) so rounding does not drift.
        let exit_t = |cell: i64, origin: i64, step: i64, a: f64, d: f64| -> f64 {
            if step == 0 {
                return f64::INFINITY;
            }
            let boundary = (origin + cell + i64::from(step > 0)) as f64 * c;
            (boundary - a) / d
        };

        let mut best: Option<(u32, f64)> = None;
        loop {
            for &k in self.cell(j as usize * self.nx + i as usize) {
                if let Some(t) = entry_t(k)
                    && best.is_none_or(|(bk, bt)| t < bt || (t == bt && k < bk))
                {
                    best = Some((k, t));
                }
            }
            let tx = exit_t(i, self.i0, step_i, a.x, d.x);
            let ty = exit_t(j, self.j0, step_j, a.y, d.y);
            let t_exit = tx.min(ty);
            if best.is_some_and(|(_, bt)| bt <= t_exit) || t_exit >= t_hi {
                return best;
            }
            if tx < ty {
                i += step_i;
            } else {
                j += step_j;
            }
            if i < 0 || j < 0 || i >= self.nx as i64 || j >= self.ny as i64 {
                return best;
            }
        }
    }

    /// Grid coordinate of a position along one axis (the same rounding for items and queries,
    /// so a point on an item's edge finds the item). Saturates at the `i64` range for huge or
    /// infinite positions (NaN gives 0): callers subtract with saturation.
    fn coord(&self, v_m: f64) -> i64 {
        (v_m / self.cell_m).floor() as i64
    }

    fn cell_index(&self, i: i64, j: i64) -> Option<usize> {
        (i >= 0 && j >= 0 && (i as usize) < self.nx && (j as usize) < self.ny)
            .then(|| j as usize * self.nx + i as usize)
    }

    fn cell(&self, c: usize) -> &[u32] {
        &self.items[self.starts[c] as usize..self.starts[c + 1] as usize]
    }

    /// Half-open range of stored cells covering grid coordinates `lo..=hi`.
    fn clamp_range(&self, lo: i64, hi: i64, n: usize) -> (usize, usize) {
        (lo.clamp(0, n as i64) as usize, hi.saturating_add(1).clamp(0, n as i64) as usize)
    }

    fn for_cells_in(&self, r: &Rect, mut f: impl FnMut(usize)) {
        for j in self.coord(r[1])..=self.coord(r[3]) {
            for i in self.coord(r[0])..=self.coord(r[2]) {
                f((j - self.j0) as usize * self.nx + (i - self.i0) as usize);
            }
        }
    }
}

fn step(d: f64) -> i64 {
    if d > 0.0 {
        1
    } else if d < 0.0 {
        -1
    } else {
        0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn items_are_listed_in_every_touched_cell_and_points_find_them() {
        // Item 0 spans cells (0..=1, 0); item 1 sits in cell (-1, -1); grid cell 10 m.
        let grid = GridIndex::new(10.0, &[[2.0, 2.0, 15.0, 8.0], [-8.0, -8.0, -2.0, -2.0]]);
        assert_eq!(grid.at(3.0, 3.0), &[0]);
        assert_eq!(grid.at(12.0, 3.0), &[0]);
        assert_eq!(grid.at(-5.0, -5.0), &[1]);
        assert!(grid.at(-5.0, 5.0).is_empty());
        assert!(grid.at(500.0, 5.0).is_empty(), "outside the grid");
        let mut near: Vec<u32> = grid.in_rect(&[-1.0, -1.0, 1.0, 1.0]).collect();
        near.sort_unstable();
        assert_eq!(near, vec![0, 1]);
        assert!(GridIndex::new(10.0, &[]).at(0.0, 0.0).is_empty());
    }

    #[test]
    fn first_hit_walks_cells_in_order_and_prefers_the_nearest() {
        // Two 2 m "posts" along the east axis at x = 25 and x = 75, cell 10 m.
        let rects = [[74.0, -1.0, 76.0, 1.0], [24.0, -1.0, 26.0, 1.0]];
        let grid = GridIndex::new(10.0, &rects);
        let hit = |a: Vector3<f64>, b: Vector3<f64>, z_lo: f64, z_hi: f64| {
            grid.first_hit(&a, &b, z_lo, z_hi, |k| {
                let r = rects[k as usize];
                clip_segment(&a, &(b - a), &Vector3::new(r[0], r[1], 0.0), &Vector3::new(r[2], r[3], 10.0)).map(|t| t.0)
            })
        };
        let (west, east) = (Vector3::new(0.0, 0.0, 5.0), Vector3::new(100.0, 0.0, 5.0));
        assert_eq!(hit(west, east, 0.0, 10.0), Some((1, 0.24)));
        assert_eq!(hit(east, west, 0.0, 10.0), Some((0, 0.24)));
        assert_eq!(hit(west, east, 20.0, 30.0), None, "above the height band");
        assert_eq!(hit(west, Vector3::new(20.0, 0.0, 5.0), 0.0, 10.0), None, "stops short");
    }

    #[test]
    fn queries_far_outside_or_not_finite_find_nothing_and_never_overflow() {
        let grid = GridIndex::new(10.0, &[[-25.0, -25.0, 15.0, 8.0]]);
        for v in [f64::INFINITY, f64::NEG_INFINITY, f64::NAN, 1e300, -1e300, f64::MAX] {
            assert!(grid.at(v, 3.0).is_empty() || v.is_nan(), "{v}");
            assert!(grid.at(3.0, v).is_empty() || v.is_nan(), "{v}");
            let _ = grid.in_rect(&[v, v, f64::INFINITY, f64::INFINITY]).count();
            let _ = grid.in_rect(&[f64::NEG_INFINITY, -1.0, v, 1.0]).count();
        }
    }

    #[test]
    fn a_decoded_index_far_from_the_origin_or_with_an_empty_axis_is_inconsistent() {
        let good = GridIndex::new(10.0, &[[2.0, 2.0, 15.0, 8.0]]);
        assert!(good.is_consistent(1) && GridIndex::new(10.0, &[]).is_consistent(0));
        // What a fuzzed world.bin decoded to: grid origins near the ends of i64 (queries
        // subtracted them and overflowed), an axis of 0 cells beside one of usize::MAX.
        let far = GridIndex { i0: i64::MIN + 3, ..good.clone() };
        let farthest = GridIndex { j0: i64::MIN, ..good.clone() };
        let flat = GridIndex { nx: usize::MAX, ny: 0, starts: vec![0], items: vec![], ..good.clone() };
        let tiny = GridIndex { cell_m: f64::INFINITY, ..good.clone() };
        for (what, index) in [("far", far), ("farthest", farthest), ("flat", flat), ("infinite cells", tiny)] {
            assert!(!index.is_consistent(1), "{what}");
        }
    }
}
