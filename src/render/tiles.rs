//! Splitting a film into tiles for several machines: tile `index` of
//! `count` is a band of whole rows, the same band on every machine.
//!
//! Bands of rows, not squares: the film is stored row by row, so a tile is
//! one slice of each buffer, and [`crate::render::film::render_rows_cancellable`]
//! renders it by the same pixel loop as the whole film. Each pixel is keyed
//! by its place in the whole film, so a tile's pixels are the same bits as
//! in a single render and the merged tiles are the single render.

use std::ops::Range;

/// Tile `index` of `count` (counting from 0) of a film `height_px` rows
/// high; every tile holds at least one row.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TileSplit {
    index: u32,
    count: u32,
    height_px: u32,
}

impl TileSplit {
    /// Tile `index` of `count` over `height_px` rows; refused, with a message
    /// naming the allowed range, unless `1 ≤ count ≤ height_px` and
    /// `index < count`.
    pub fn new(index: u32, count: u32, height_px: u32) -> Result<TileSplit, String> {
        if count == 0 || count > height_px {
            return Err(format!(
                "tile count {count}: allowed 1 to {height_px} (the image height: every tile holds whole rows)"
            ));
        }
        if index >= count {
            return Err(format!(
                "tile {index} of {count}: tiles count from 0, allowed 0 to {}",
                count - 1
            ));
        }
        Ok(TileSplit {
            index,
            count,
            height_px,
        })
    }

    /// The whole film as one tile.
    pub fn whole(height_px: u32) -> TileSplit {
        TileSplit {
            index: 0,
            count: 1,
            height_px,
        }
    }

    /// Which tile this is, from 0.
    pub fn index(&self) -> u32 {
        self.index
    }

    /// How many tiles the film is split into.
    pub fn count(&self) -> u32 {
        self.count
    }

    /// The rows of this tile: `index·H/count .. (index+1)·H/count`, so the
    /// bands differ in height by at most one row and cover the film once.
    pub fn rows(&self) -> Range<u32> {
        let edge =
            |i: u32| (u64::from(i) * u64::from(self.height_px) / u64::from(self.count)) as u32;
        edge(self.index)..edge(self.index + 1)
    }
}

#[cfg(test)]
mod tests {
    use super::TileSplit;

    #[test]
    fn tiles_cover_every_row_once_in_order() {
        for height in [1u32, 2, 7, 32, 33, 1000] {
            for count in 1..=height.min(9) {
                let mut next = 0;
                for index in 0..count {
                    let rows = TileSplit::new(index, count, height).unwrap().rows();
                    assert_eq!(rows.start, next, "height {height}, tile {index}/{count}");
                    assert!(!rows.is_empty(), "height {height}, tile {index}/{count}");
                    next = rows.end;
                }
                assert_eq!(next, height);
            }
        }
    }

    #[test]
    fn impossible_splits_name_the_allowed_range() {
        let e = TileSplit::new(5, 4, 32).unwrap_err();
        assert!(e.contains("allowed 0 to 3"), "{e}");
        let e = TileSplit::new(0, 0, 32).unwrap_err();
        assert!(e.contains("allowed 1 to 32"), "{e}");
        let e = TileSplit::new(0, 40, 32).unwrap_err();
        assert!(e.contains("allowed 1 to 32"), "{e}");
        assert_eq!(TileSplit::whole(32).rows(), 0..32);
    }
}
