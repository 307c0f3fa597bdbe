//! Rasterising one operation onto the grid: only the rows and columns of its footprint's
//! bounding box (clipped to the window and the grid) are visited, rows in parallel.

use rayon::prelude::*;

use super::combine::Operator;
use super::params::Window;
use crate::terrain::Heightfield;

/// An axis-aligned plan rectangle in metres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bounds {
    pub min_x: f64,
    pub min_z: f64,
    pub max_x: f64,
    pub max_z: f64,
}

impl Bounds {
    /// The smallest rectangle holding every point.
    pub fn around(points: impl IntoIterator<Item = (f64, f64)>) -> Self {
        let mut b =
            Bounds { min_x: f64::INFINITY, min_z: f64::INFINITY, max_x: f64::NEG_INFINITY, max_z: f64::NEG_INFINITY };
        for (x, z) in points {
            b.min_x = b.min_x.min(x);
            b.min_z = b.min_z.min(z);
            b.max_x = b.max_x.max(x);
            b.max_z = b.max_z.max(z);
        }
        b
    }

    /// A square of half-side `r` around a point.
    pub fn square(cx: f64, cz: f64, r: f64) -> Self {
        Bounds { min_x: cx - r, min_z: cz - r, max_x: cx + r, max_z: cz + r }
    }

    /// The smallest rectangle holding both.
    pub fn union(&self, o: &Bounds) -> Bounds {
        Bounds {
            min_x: self.min_x.min(o.min_x),
            min_z: self.min_z.min(o.min_z),
            max_x: self.max_x.max(o.max_x),
            max_z: self.max_z.max(o.max_z),
        }
    }

    #[cfg(test)]
    pub fn contains(&self, x: f64, z: f64) -> bool {
        x >= self.min_x && x <= self.max_x && z >= self.min_z && z <= self.max_z
    }

    fn clip(&self, w: &Window) -> Bounds {
        Bounds {
            min_x: self.min_x.max(w.min_x as f64),
            min_z: self.min_z.max(w.min_z as f64),
            max_x: self.max_x.min(w.max_x as f64),
            max_z: self.max_z.min(w.max_z as f64),
        }
    }
}

/// A local frame in plan: origin, unit tangent `t`, and the right-hand normal `n` — the
/// tangent turned −90° about +Y, so for a tangent along +X the normal is +Z.
#[derive(Clone, Copy, Debug)]
pub struct Frame {
    pub ox: f64,
    pub oz: f64,
    pub tx: f64,
    pub tz: f64,
}

impl Frame {
    /// A frame at (ox, oz) heading `direction_rad` from +X toward +Z.
    pub fn heading(ox: f64, oz: f64, direction_rad: f64) -> Self {
        let (sin, cos) = direction_rad.sin_cos();
        Frame { ox, oz, tx: cos, tz: sin }
    }

    /// A frame at `from` heading toward `to`, and the distance between them.
    pub fn between(from: (f64, f64), to: (f64, f64)) -> (Self, f64) {
        let (dx, dz) = (to.0 - from.0, to.1 - from.1);
        let length = dx.hypot(dz);
        (Frame { ox: from.0, oz: from.1, tx: dx / length, tz: dz / length }, length)
    }

    /// (along, across) coordinates of a plan point; across is positive to the right.
    #[inline]
    pub fn local(&self, x: f64, z: f64) -> (f64, f64) {
        let (dx, dz) = (x - self.ox, z - self.oz);
        (dx * self.tx + dz * self.tz, dz * self.tx - dx * self.tz)
    }

    /// The plan point at (along, across).
    #[inline]
    pub fn world(&self, along: f64, across: f64) -> (f64, f64) {
        (self.ox + along * self.tx - across * self.tz, self.oz + along * self.tz + across * self.tx)
    }
}

/// An operation's shape in plan: where it acts and what it puts there.
pub trait Footprint: Sync {
    /// A rectangle holding the whole footprint.
    fn bounds(&self) -> Bounds;
    /// `(base_m, relief_m)` at a plan point, or `None` outside the footprint.
    fn sample(&self, x: f64, z: f64) -> Option<(f64, f64)>;
}

/// Index range `lo..=hi` of the samples `i * cell` that lie in `[min, max]`, clipped to `n`.
fn index_range(min: f64, max: f64, cell: f64, n: usize) -> Option<(usize, usize)> {
    if n == 0 || min.is_nan() || max.is_nan() || min > max {
        return None;
    }
    let last = (n - 1) as f64;
    let mut lo = (min / cell).ceil().clamp(0.0, last + 1.0);
    let mut hi = (max / cell).floor().clamp(-1.0, last);
    // Division rounds; settle the ends on the exact positions the samples are evaluated at.
    while lo > 0.0 && (lo - 1.0) * cell >= min {
        lo -= 1.0;
    }
    while lo <= last && lo * cell < min {
        lo += 1.0;
    }
    while hi < last && (hi + 1.0) * cell <= max {
        hi += 1.0;
    }
    while hi >= 0.0 && hi * cell > max {
        hi -= 1.0;
    }
    (lo <= hi).then_some((lo as usize, hi as usize))
}

/// Grid cells `((first col, last col), (first row, last row))`, inclusive.
pub type Cells = ((usize, usize), (usize, usize));

/// The grid rows and columns an operation may touch: its bounds clipped to window and grid.
pub fn affected_cells(hf: &Heightfield, bounds: Bounds, window: Option<&Window>) -> Option<Cells> {
    cells_within(hf.cols, hf.rows, hf.cell_size_m as f64, bounds, window)
}

/// [`affected_cells`] of a `cols × rows` grid `cell_m` apart, before the grid exists (for the
/// cost estimate).
pub fn cells_within(cols: usize, rows: usize, cell_m: f64, bounds: Bounds, window: Option<&Window>) -> Option<Cells> {
    let b = match window {
        Some(w) => bounds.clip(w),
        None => bounds,
    };
    Some((index_range(b.min_x, b.max_x, cell_m, cols)?, index_range(b.min_z, b.max_z, cell_m, rows)?))
}

/// A copy of a rectangle of the grid's heights: the surface a group of operations reads
/// while they write the grid.
pub struct Patch {
    cells: Cells,
    heights_m: Vec<f32>,
}

impl Patch {
    /// The grid's heights over `cells`, rows copied in parallel.
    pub fn copy(hf: &Heightfield, cells: Cells) -> Self {
        let ((c0, c1), (r0, r1)) = cells;
        let width = c1 - c0 + 1;
        let mut heights_m = vec![0.0; width * (r1 - r0 + 1)];
        let rows = hf.heights_m[r0 * hf.cols..(r1 + 1) * hf.cols].par_chunks(hf.cols);
        heights_m.par_chunks_mut(width).zip(rows).for_each(|(copy, row)| copy.copy_from_slice(&row[c0..=c1]));
        Self { cells, heights_m }
    }

    /// Row `row`'s heights over columns `c0..=c1`, which must lie inside the patch.
    fn span(&self, row: usize, c0: usize, c1: usize) -> &[f32] {
        let ((p0, p1), (r0, _)) = self.cells;
        let start = (row - r0) * (p1 - p0 + 1) + (c0 - p0);
        &self.heights_m[start..=start + (c1 - c0)]
    }
}

/// Combine `shape` with the surface by `operator` at every sample of its footprint inside
/// the window. Each sample depends only on its own previous height, so the result does not
/// depend on how rows are split among threads.
pub fn apply(hf: &mut Heightfield, shape: &(impl Footprint + ?Sized), operator: Operator, window: Option<&Window>) {
    rasterise(hf, None, shape, operator, window);
}

/// As [`apply`], but combining `shape` with the heights in `before` rather than the grid's
/// own; `before` must hold every cell the shape may touch.
pub fn apply_over(
    hf: &mut Heightfield,
    before: &Patch,
    shape: &(impl Footprint + ?Sized),
    operator: Operator,
    window: Option<&Window>,
) {
    rasterise(hf, Some(before), shape, operator, window);
}

fn rasterise(
    hf: &mut Heightfield,
    before: Option<&Patch>,
    shape: &(impl Footprint + ?Sized),
    operator: Operator,
    window: Option<&Window>,
) {
    let Some(((c0, c1), (r0, r1))) = affected_cells(hf, shape.bounds(), window) else {
        return;
    };
    let cols = hf.cols;
    let cell = hf.cell_size_m as f64;
    hf.heights_m[r0 * cols..(r1 + 1) * cols].par_chunks_mut(cols).enumerate().for_each(|(i, row)| {
        let z = (r0 + i) as f64 * cell;
        let row = &mut row[c0..=c1];
        let from = before.map(|p| p.span(r0 + i, c0, c1));
        for (k, (h, c)) in row.iter_mut().zip(c0..).enumerate() {
            if let Some((base, relief)) = shape.sample(c as f64 * cell, z) {
                let prior = from.map_or(*h, |from| from[k]);
                *h = operator.combine(prior as f64, base, relief) as f32;
            }
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    struct Disc {
        r: f64,
    }

    impl Footprint for Disc {
        fn bounds(&self) -> Bounds {
            Bounds::square(0.0, 0.0, self.r)
        }
        fn sample(&self, x: f64, z: f64) -> Option<(f64, f64)> {
            (x * x + z * z <= self.r * self.r).then_some((0.0, 1.0))
        }
    }

    #[test]
    fn index_ranges_are_exact_at_the_edges() {
        assert_eq!(index_range(0.3, 0.75, 0.1, 100), Some((3, 7)));
        // 7 × 0.1 is 0.7000000000000001, past 0.7.
        assert_eq!(index_range(0.3, 0.7, 0.1, 100), Some((3, 6)));
        assert_eq!(index_range(-5.0, 2.5, 1.0, 10), Some((0, 2)));
        assert_eq!(index_range(2.1, 2.9, 1.0, 10), None);
        assert_eq!(index_range(20.0, 30.0, 1.0, 10), None);
        assert_eq!(index_range(-3.0, -1.0, 1.0, 10), None);
        assert_eq!(index_range(8.5, 30.0, 1.0, 10), Some((9, 9)));
    }

    #[test]
    fn frame_normal_points_right_of_travel() {
        let f = Frame::heading(1.0, 2.0, 0.0);
        let (s, d) = f.local(3.0, 5.0);
        assert!((s - 2.0).abs() < 1e-12 && (d - 3.0).abs() < 1e-12);
        let (x, z) = f.world(s, d);
        assert!((x - 3.0).abs() < 1e-12 && (z - 5.0).abs() < 1e-12);
    }

    #[test]
    fn apply_changes_only_the_footprint_and_the_window() {
        let mut hf = Heightfield::flat(21, 21, 1.0, 0.0);
        let window = Window { min_x: 0.0, min_z: 0.0, max_x: 2.0, max_z: 20.0 };
        apply(&mut hf, &Disc { r: 4.0 }, Operator::Add, Some(&window));
        for r in 0..21 {
            for c in 0..21 {
                let inside = c <= 2 && c * c + r * r <= 16;
                assert_eq!(hf.get(c, r), if inside { 1.0 } else { 0.0 }, "at ({c}, {r})");
            }
        }
    }
}
