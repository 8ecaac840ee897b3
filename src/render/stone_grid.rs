//! A uniform grid over x–y for stones laid out side by side on a tray.
//!
//! Such stones fill a slab much thinner than it is wide, so a ray crosses
//! the slab in a few grid cells: a camera ray 35° above the horizon crosses
//! a slab of height h in 1.4·h horizontally, about one stone's width. Walking
//! the cells the ray crosses, nearest first (Amanatides & Woo, "A Fast Voxel
//! Traversal Algorithm for Ray Tracing", 1987), tests the stones of those
//! cells alone and stops at the first cell that ends beyond the nearest hit
//! found; a BVH over the same boxes descends several levels of overlapping
//! boxes for every ray. The grid is only a faster way to find the same
//! candidates: [`crate::render::world::World`] tests each stone exactly as
//! it does through its BVH, so the answers are the same.

use glam::DVec3;

/// The stones are a tray only when the height of their union box is at
/// most this fraction of its narrower horizontal side.
const MAX_HEIGHT_OVER_WIDTH: f64 = 0.25;

/// At most this many cells per stone (a sparse tray gets larger cells).
const MAX_CELLS_PER_STONE: f64 = 4.0;

/// Above this mean number of stones per non-empty cell the stones are not
/// spread out (piled up, or boxes much larger than the mean): a BVH suits
/// them better.
const MAX_MEAN_STONES_PER_CELL: f64 = 4.0;

/// Stones indexed by the cells of a uniform grid over x–y.
#[derive(Clone, Debug)]
pub(crate) struct StoneGrid {
    /// x and y of the grid's corner (the minimum of the stones' union box).
    corner: [f64; 2],
    /// Cell side along x and along y.
    cell_size: [f64; 2],
    /// 1/`cell_size`: the walk's start cell by a product, not a quotient
    /// (the cells' margins absorb the different rounding).
    inverse_cell_size: [f64; 2],
    /// The last cell's index along x and along y, as a float (what the
    /// walk clamps a start cell to before the cast).
    last_cell: [f64; 2],
    /// Number of cells along x and along y, each ≥ 1.
    cells: [usize; 2],
    /// The stones of cell c = y·cells[0] + x are
    /// `members[starts[c]..starts[c + 1]]`, in increasing index.
    starts: Vec<u32>,
    /// Stone indices, cell after cell.
    members: Vec<u32>,
}

impl StoneGrid {
    /// The grid over stones with (padded) world boxes `boxes` whose union
    /// is `union`, or `None` when they do not lie side by side in a thin
    /// slab (see the constants above).
    pub(crate) fn for_tray(boxes: &[(DVec3, DVec3)], union: (DVec3, DVec3)) -> Option<Self> {
        let extent = union.1 - union.0;
        if boxes.is_empty()
            || !extent.is_finite()
            || extent.x <= 0.0
            || extent.y <= 0.0
            || extent.z > MAX_HEIGHT_OVER_WIDTH * extent.x.min(extent.y)
        {
            return None;
        }
        // Square cells of about one stone's footprint, coarser if that
        // would make more than MAX_CELLS_PER_STONE cells per stone.
        let count = boxes.len() as f64;
        let mean_footprint = boxes
            .iter()
            .map(|(lo, hi)| (hi.x - lo.x) * (hi.y - lo.y))
            .sum::<f64>()
            / count;
        let max_cells = MAX_CELLS_PER_STONE * count;
        let side = mean_footprint
            .sqrt()
            .max((extent.x * extent.y / max_cells).sqrt());
        if !(side > 0.0 && side.is_finite()) {
            return None;
        }
        let cells_along = |length: f64| ((length / side).ceil() as usize).max(1);
        let cells = [cells_along(extent.x), cells_along(extent.y)];
        let cell_size = [extent.x / cells[0] as f64, extent.y / cells[1] as f64];
        let corner = [union.0.x, union.0.y];
        // A stone goes into every cell its box overlaps, widened by far more
        // than the rounding of a cell index or of a crossing time, so that a
        // ray that rounding places on the wrong side of a cell border still
        // meets every stone near it.
        let magnitude = union.0.abs().max(union.1.abs()).max_element();
        let margin = 1e-9 * (magnitude + side);
        let range = |lo: f64, hi: f64, axis: usize| {
            let first = ((lo - margin - corner[axis]) / cell_size[axis]).floor();
            let last = ((hi + margin - corner[axis]) / cell_size[axis]).floor();
            let clamp = |c: f64| (c.max(0.0) as usize).min(cells[axis] - 1);
            clamp(first)..=clamp(last)
        };
        // Counting sort of (cell, stone) pairs: counts, then offsets.
        let cell_count = cells[0] * cells[1];
        let mut starts = vec![0u32; cell_count + 1];
        for (lo, hi) in boxes {
            for y in range(lo.y, hi.y, 1) {
                for x in range(lo.x, hi.x, 0) {
                    starts[y * cells[0] + x + 1] += 1;
                }
            }
        }
        for c in 0..cell_count {
            starts[c + 1] += starts[c];
        }
        let mut fill = starts.clone();
        let mut members = vec![0u32; starts[cell_count] as usize];
        for (index, (lo, hi)) in boxes.iter().enumerate() {
            for y in range(lo.y, hi.y, 1) {
                for x in range(lo.x, hi.x, 0) {
                    let slot = &mut fill[y * cells[0] + x];
                    members[*slot as usize] = index as u32;
                    *slot += 1;
                }
            }
        }
        let occupied = starts.windows(2).filter(|w| w[1] > w[0]).count();
        if members.len() as f64 > MAX_MEAN_STONES_PER_CELL * occupied as f64 {
            return None;
        }
        Some(Self {
            corner,
            cell_size,
            inverse_cell_size: [1.0 / cell_size[0], 1.0 / cell_size[1]],
            last_cell: [(cells[0] - 1) as f64, (cells[1] - 1) as f64],
            cells,
            starts,
            members,
        })
    }

    /// Calls `visit(stones of the cell, t where the ray leaves the cell)`
    /// for each cell that the ray `origin + t·direction` crosses for t in
    /// [`t_start`, `t_end`], in order of t, until `visit` returns true. The
    /// exit time passed is at most `t_end`. Cells are found from x and y
    /// alone: the caller clips [`t_start`, `t_end`] to the stones' slab.
    /// `inverse_direction` is `direction.recip()`, which the callers have
    /// already made for their box tests.
    #[inline]
    pub fn walk(
        &self,
        origin: DVec3,
        direction: DVec3,
        inverse_direction: DVec3,
        t_start: f64,
        t_end: f64,
        mut visit: impl FnMut(&[u32], f64) -> bool,
    ) {
        self.walk_cells(
            origin,
            direction,
            inverse_direction,
            t_start,
            t_end,
            |c, t_exit| visit(self.members_of(c), t_exit),
        );
    }

    /// The stones of cell number c = y·cells[0] + x.
    #[inline(always)]
    fn members_of(&self, c: usize) -> &[u32] {
        &self.members[self.starts[c] as usize..self.starts[c + 1] as usize]
    }

    /// The cell along `axis` that coordinate `p` falls in, clamped into the
    /// grid (a point on the border of the union box may round to just
    /// outside it). A product with 1/cell size, clamped as a float and cast
    /// through u32: a cast from f64 to usize takes a dozen instructions in
    /// the baseline x86-64 code, and the product replaces a division. `max`
    /// first turns a NaN into 0.
    #[inline(always)]
    fn cell_of(&self, p: f64, axis: usize) -> usize {
        let c = (p - self.corner[axis]) * self.inverse_cell_size[axis];
        c.max(0.0).min(self.last_cell[axis]) as u32 as usize
    }

    /// [`StoneGrid::walk`] by cell number y·cells[0] + x.
    #[inline(always)]
    fn walk_cells(
        &self,
        origin: DVec3,
        direction: DVec3,
        inverse_direction: DVec3,
        t_start: f64,
        t_end: f64,
        mut visit: impl FnMut(usize, f64) -> bool,
    ) {
        let start = origin + direction * t_start;
        let o = [origin.x, origin.y];
        let d = [direction.x, direction.y];
        let inverse_d = [inverse_direction.x, inverse_direction.y];
        // Cell indices made floats through u32, as `cell_of` casts back (a
        // cell index is below u32::MAX: the grid has at most
        // MAX_CELLS_PER_STONE cells per stone).
        let float = |c: usize| f64::from(c as u32);
        let mut cell = [self.cell_of(start.x, 0), self.cell_of(start.y, 1)];
        // When the ray crosses the far border of cell c along an axis,
        // computed from the border's position (not accumulated), so that
        // rounding errors do not build up along a long walk.
        let crossing = |axis: usize, c: usize| {
            if d[axis] > 0.0 {
                (self.corner[axis] + float(c + 1) * self.cell_size[axis] - o[axis])
                    * inverse_d[axis]
            } else if d[axis] < 0.0 {
                (self.corner[axis] + float(c) * self.cell_size[axis] - o[axis]) * inverse_d[axis]
            } else {
                f64::INFINITY
            }
        };
        let mut next = [crossing(0, cell[0]), crossing(1, cell[1])];
        loop {
            let axis = usize::from(next[1] < next[0]);
            let t_exit = next[axis].min(t_end);
            if visit(cell[1] * self.cells[0] + cell[0], t_exit) || t_exit >= t_end {
                return;
            }
            if d[axis] > 0.0 {
                cell[axis] += 1;
                if cell[axis] == self.cells[axis] {
                    return;
                }
            } else {
                if cell[axis] == 0 {
                    return;
                }
                cell[axis] -= 1;
            }
            next[axis] = crossing(axis, cell[axis]);
        }
    }

    /// Number of cells along x and along y.
    #[cfg(test)]
    pub fn cells(&self) -> [usize; 2] {
        self.cells
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Rng;

    fn unit_boxes(side: usize, pitch: f64, height: f64) -> Vec<(DVec3, DVec3)> {
        (0..side * side)
            .map(|i| {
                let centre = DVec3::new((i % side) as f64 * pitch, (i / side) as f64 * pitch, 0.0);
                (
                    centre - DVec3::new(0.3, 0.3, 0.0),
                    centre + DVec3::new(0.3, 0.3, height),
                )
            })
            .collect()
    }

    fn union(boxes: &[(DVec3, DVec3)]) -> (DVec3, DVec3) {
        boxes.iter().fold(
            (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |(lo, hi), b| (lo.min(b.0), hi.max(b.1)),
        )
    }

    #[test]
    fn only_flat_spread_out_layouts_get_a_grid() {
        let tray = unit_boxes(10, 1.1, 0.4);
        let grid = StoneGrid::for_tray(&tray, union(&tray)).expect("a flat tray");
        // Footprints of 0.6 × 0.6 over a 10.5 × 10.5 tray: ⌈17.5⌉ cells along each side.
        assert_eq!(grid.cells(), [18, 18]);
        // A tower (taller than wide) is not a tray, nor a pile (20 boxes in
        // one corner and one far away: flat, but 10 stones per used cell).
        let tower = unit_boxes(2, 1.0, 5.0);
        assert!(StoneGrid::for_tray(&tower, union(&tower)).is_none());
        let mut pile = vec![tray[0]; 20];
        pile.push(tray[99]);
        assert!(StoneGrid::for_tray(&pile, union(&pile)).is_none());
    }

    #[test]
    fn a_walk_visits_every_cell_the_ray_crosses_in_order() {
        // Against a brute force: sample the segment densely and record the
        // cells of the sample points. The walk must contain them in the same
        // order, move between edge-adjacent cells only (so no cell in
        // between is skipped), pass exit times that are nondecreasing, at
        // most t_end and not before any sample point of the cell.
        let tray = unit_boxes(8, 1.0, 0.3);
        let grid = StoneGrid::for_tray(&tray, union(&tray)).unwrap();
        let (lo, hi) = union(&tray);
        let cell_of = |p: DVec3| {
            let x = ((p.x - lo.x) / grid.cell_size[0]).floor() as usize;
            let y = ((p.y - lo.y) / grid.cell_size[1]).floor() as usize;
            y * grid.cells[0] + x
        };
        let mut rng = Rng::new(3, 0);
        let mut long_walks = 0;
        for _ in 0..500 {
            let [a, b, c] = rng.next_3();
            let origin = DVec3::new(lo.x + a * (hi.x - lo.x), lo.y + b * (hi.y - lo.y), 0.1);
            let angle = c * std::f64::consts::TAU;
            let direction = DVec3::new(angle.cos(), angle.sin(), 0.05).normalize();
            let t_end = 3.0;
            let mut walked: Vec<(usize, f64)> = Vec::new();
            grid.walk_cells(
                origin,
                direction,
                direction.recip(),
                0.0,
                t_end,
                |cell, t_exit| {
                    walked.push((cell, t_exit));
                    false
                },
            );
            long_walks += usize::from(walked.len() > 4);
            let mut position = 0;
            for k in 0..=3000 {
                let t = t_end * k as f64 / 3000.0;
                let p = origin + direction * t;
                if p.x <= lo.x || p.y <= lo.y || p.x >= hi.x || p.y >= hi.y {
                    break;
                }
                let cell = cell_of(p);
                let found = walked[position..].iter().position(|w| w.0 == cell);
                position += found.unwrap_or_else(|| panic!("cell {cell} at t = {t} not walked"));
                assert!(
                    walked[position].1 >= t - 1e-12,
                    "exit before a point of the cell"
                );
            }
            let columns = grid.cells[0];
            for w in walked.windows(2) {
                let (a, b) = (w[0].0, w[1].0);
                let (dx, dy) = (
                    (a % columns).abs_diff(b % columns),
                    (a / columns).abs_diff(b / columns),
                );
                assert_eq!(dx + dy, 1, "cells {a} and {b} are not neighbours");
                assert!(w[0].1 <= w[1].1);
            }
            assert!(walked.iter().all(|w| w.1 <= t_end));
        }
        assert!(long_walks > 100, "{long_walks}");
    }
}
