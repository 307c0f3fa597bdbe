//! The grid the erosion works on: f64 heights, the eight neighbours of a cell in one fixed
//! order, and which cells are outlets.

/// Row and column steps to the eight neighbours, in the order every loop visits them (row
/// above left to right, the row's two, row below): the order fixes every sum's rounding.
pub const N8: [(isize, isize); 8] = [(-1, -1), (0, -1), (1, -1), (-1, 0), (1, 0), (-1, 1), (0, 1), (1, 1)];

/// Whether neighbour `k` of [`N8`] is diagonal.
pub const DIAGONAL: [bool; 8] = [true, false, true, false, false, true, false, true];

/// A grid's shape and the distance to each neighbour.
#[derive(Clone, Copy, Debug)]
pub struct Grid {
    pub cols: usize,
    pub rows: usize,
    /// Metres between samples.
    pub cell: f64,
    /// Metres to each neighbour of [`N8`].
    pub length: [f64; 8],
    /// Index offset of each neighbour of [`N8`].
    pub offset: [isize; 8],
    /// The contour length water crosses towards each neighbour of [`N8`], in cells: ½ for the
    /// four sides, √2/4 for the corners (Quinn et al. 1991), so that flow on a plane splits by
    /// the plane's own direction rather than the grid's.
    pub contour: [f64; 8],
}

impl Grid {
    pub fn new(cols: usize, rows: usize, cell: f64) -> Self {
        let diagonal = cell * std::f64::consts::SQRT_2;
        let length = DIAGONAL.map(|d| if d { diagonal } else { cell });
        let offset = N8.map(|(dc, dr)| dr * cols as isize + dc);
        let contour = DIAGONAL.map(|d| if d { std::f64::consts::SQRT_2 / 4.0 } else { 0.5 });
        Self { cols, rows, cell, length, offset, contour }
    }

    pub fn cells(&self) -> usize {
        self.cols * self.rows
    }

    /// Whether cell `i` lies on the grid's edge (and so lacks some neighbours).
    pub fn on_border(&self, i: usize) -> bool {
        let (c, r) = (i % self.cols, i / self.cols);
        c == 0 || r == 0 || c + 1 == self.cols || r + 1 == self.rows
    }

    /// Neighbour `k` of cell `i`, if it is on the grid.
    #[inline]
    pub fn neighbour(&self, i: usize, k: usize) -> Option<usize> {
        let (c, r) = ((i % self.cols) as isize, (i / self.cols) as isize);
        let (dc, dr) = N8[k];
        let (nc, nr) = (c + dc, r + dr);
        (nc >= 0 && nr >= 0 && (nc as usize) < self.cols && (nr as usize) < self.rows)
            .then(|| (i as isize + self.offset[k]) as usize)
    }

    /// The lowest of cell `i`'s neighbours' heights (interior cells without the bounds checks).
    #[inline]
    pub fn lowest_neighbour(&self, heights: &[f64], i: usize) -> f64 {
        let (c, r) = (i % self.cols, i / self.cols);
        if c > 0 && r > 0 && c + 1 < self.cols && r + 1 < self.rows {
            (0..8).map(|k| heights[self.inner(i, k)]).fold(f64::INFINITY, f64::min)
        } else {
            (0..8).filter_map(|k| self.neighbour(i, k)).map(|n| heights[n]).fold(f64::INFINITY, f64::min)
        }
    }

    /// Neighbour `k` of an interior cell (not on the border), without the bounds check.
    #[inline]
    pub fn inner(&self, i: usize, k: usize) -> usize {
        (i as isize + self.offset[k]) as usize
    }
}

/// The outlets: the grid's border and every cell at or below `sea_level`. Water that reaches
/// one leaves the land; the fluvial step never changes them.
pub fn outlets(grid: &Grid, heights: &[f64], sea_level: f64) -> Vec<bool> {
    heights.iter().enumerate().map(|(i, &h)| h <= sea_level || grid.on_border(i)).collect()
}
