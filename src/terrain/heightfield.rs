use glam::Vec3;

/// A regular grid of heights in metres.
///
/// Row `r` lies at `z = r * cell_size_m`, column `c` at `x = c * cell_size_m`; heights are
/// along +Y. Samples are stored row-major: `heights_m[r * cols + c]`.
#[derive(Clone, Debug, PartialEq)]
pub struct Heightfield {
    pub cols: usize,
    pub rows: usize,
    pub cell_size_m: f32,
    pub heights_m: Vec<f32>,
}

impl Heightfield {
    pub fn flat(cols: usize, rows: usize, cell_size_m: f32, height_m: f32) -> Self {
        Self { cols, rows, cell_size_m, heights_m: vec![height_m; cols * rows] }
    }

    pub fn from_fn(cols: usize, rows: usize, cell_size_m: f32, f: impl Fn(f32, f32) -> f32) -> Self {
        let mut heights_m = Vec::with_capacity(cols * rows);
        for r in 0..rows {
            for c in 0..cols {
                heights_m.push(f(c as f32 * cell_size_m, r as f32 * cell_size_m));
            }
        }
        Self { cols, rows, cell_size_m, heights_m }
    }

    #[inline]
    pub fn index(&self, col: usize, row: usize) -> usize {
        row * self.cols + col
    }

    #[inline]
    pub fn get(&self, col: usize, row: usize) -> f32 {
        self.heights_m[row * self.cols + col]
    }

    #[inline]
    pub fn set(&mut self, col: usize, row: usize, height_m: f32) {
        self.heights_m[row * self.cols + col] = height_m;
    }

    /// Extent along X in metres (first to last column).
    pub fn width_m(&self) -> f32 {
        (self.cols.saturating_sub(1)) as f32 * self.cell_size_m
    }

    /// Extent along Z in metres (first to last row).
    pub fn depth_m(&self) -> f32 {
        (self.rows.saturating_sub(1)) as f32 * self.cell_size_m
    }

    /// World position of a sample.
    #[inline]
    pub fn position(&self, col: usize, row: usize) -> Vec3 {
        Vec3::new(col as f32 * self.cell_size_m, self.get(col, row), row as f32 * self.cell_size_m)
    }

    /// Bilinear height at a point in metres; points outside the grid take the nearest edge.
    pub fn sample(&self, x_m: f32, z_m: f32) -> f32 {
        let fx = (x_m / self.cell_size_m).clamp(0.0, (self.cols - 1) as f32);
        let fz = (z_m / self.cell_size_m).clamp(0.0, (self.rows - 1) as f32);
        let c0 = (fx.floor() as usize).min(self.cols.saturating_sub(2));
        let r0 = (fz.floor() as usize).min(self.rows.saturating_sub(2));
        let c1 = (c0 + 1).min(self.cols - 1);
        let r1 = (r0 + 1).min(self.rows - 1);
        let tx = fx - c0 as f32;
        let tz = fz - r0 as f32;
        let top = self.get(c0, r0) * (1.0 - tx) + self.get(c1, r0) * tx;
        let bottom = self.get(c0, r1) * (1.0 - tx) + self.get(c1, r1) * tx;
        top * (1.0 - tz) + bottom * tz
    }

    /// Lowest and highest height; `(0, 0)` for an empty grid.
    pub fn min_max(&self) -> (f32, f32) {
        let mut lo = f32::INFINITY;
        let mut hi = f32::NEG_INFINITY;
        for &h in &self.heights_m {
            lo = lo.min(h);
            hi = hi.max(h);
        }
        if lo > hi {
            (0.0, 0.0)
        } else {
            (lo, hi)
        }
    }

    /// Height gradient (dh/dx, dh/dz) by central differences (one-sided at the edges).
    pub fn gradient(&self, col: usize, row: usize) -> (f32, f32) {
        let c0 = col.saturating_sub(1);
        let c1 = (col + 1).min(self.cols - 1);
        let r0 = row.saturating_sub(1);
        let r1 = (row + 1).min(self.rows - 1);
        let dx =
            if c1 > c0 { (self.get(c1, row) - self.get(c0, row)) / ((c1 - c0) as f32 * self.cell_size_m) } else { 0.0 };
        let dz =
            if r1 > r0 { (self.get(col, r1) - self.get(col, r0)) / ((r1 - r0) as f32 * self.cell_size_m) } else { 0.0 };
        (dx, dz)
    }

    /// Unit surface normal (Y up).
    pub fn normal(&self, col: usize, row: usize) -> Vec3 {
        let (dx, dz) = self.gradient(col, row);
        Vec3::new(-dx, 1.0, -dz).normalize()
    }

    /// Slope angle in degrees from horizontal.
    pub fn slope_deg(&self, col: usize, row: usize) -> f32 {
        let (dx, dz) = self.gradient(col, row);
        (dx * dx + dz * dz).sqrt().atan().to_degrees()
    }

    /// The same surface sampled every `cell_size_m` metres (bilinear), covering the same extent.
    pub fn resampled(&self, cell_size_m: f32) -> Heightfield {
        let cols = (self.width_m() / cell_size_m).floor() as usize + 1;
        let rows = (self.depth_m() / cell_size_m).floor() as usize + 1;
        let mut out = Heightfield::flat(cols, rows, cell_size_m, 0.0);
        for r in 0..rows {
            for c in 0..cols {
                out.heights_m[r * cols + c] = self.sample(c as f32 * cell_size_m, r as f32 * cell_size_m);
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bilinear_sample_is_exact_on_a_plane() {
        let hf = Heightfield::from_fn(5, 4, 2.0, |x, z| 3.0 * x - 0.5 * z + 1.0);
        let h = hf.sample(3.3, 4.1);
        assert!((h - (3.0 * 3.3 - 0.5 * 4.1 + 1.0)).abs() < 1e-4);
    }

    #[test]
    fn normal_of_a_slope_leans_downhill() {
        let hf = Heightfield::from_fn(5, 5, 1.0, |x, _| x);
        let n = hf.normal(2, 2);
        assert!(n.x < 0.0 && n.y > 0.0 && n.z.abs() < 1e-6);
        assert!((hf.slope_deg(2, 2) - 45.0).abs() < 1e-3);
    }
}
