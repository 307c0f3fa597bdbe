//! The deformation operator (paper §3): a truncated Gaussian kernel centred on a vertex that
//! moves the vertex exactly to a chosen amplitude and fades to nothing at its radius.

/// Kernel weights of one integer radius `r` (cells) over its `(2r + 1)²` window, row-major.
///
/// σ = r / 3 and K(d) = (exp(−d²/2σ²) − exp(−r²/2σ²)) / (1 − exp(−r²/2σ²)) for d < r, 0
/// beyond: exactly 1 at the centre and exactly 0 at the radius, so no seam at the rim.
#[derive(Clone, Debug, PartialEq)]
pub struct Kernel {
    pub radius: usize,
    pub weights: Vec<f64>,
}

impl Kernel {
    pub fn new(radius: usize) -> Self {
        let r = radius as f64;
        let sigma = r / 3.0;
        let two_s2 = 2.0 * sigma * sigma;
        let rim = (-(r * r) / two_s2).exp();
        let side = 2 * radius + 1;
        let mut weights = Vec::with_capacity(side * side);
        for dz in -(radius as i64)..=radius as i64 {
            for dx in -(radius as i64)..=radius as i64 {
                let d2 = (dx * dx + dz * dz) as f64;
                let w = if d2 == 0.0 {
                    1.0
                } else if d2 < r * r {
                    ((-d2 / two_s2).exp() - rim) / (1.0 - rim)
                } else {
                    0.0
                };
                weights.push(w);
            }
        }
        Self { radius, weights }
    }

    /// Side of the window in cells.
    pub fn side(&self) -> usize {
        2 * self.radius + 1
    }

    /// The weight at offset (dx, dz) from the centre; 0 outside the window.
    #[inline]
    pub fn at(&self, dx: i64, dz: i64) -> f64 {
        let r = self.radius as i64;
        if dx.abs() > r || dz.abs() > r {
            return 0.0;
        }
        self.weights[((dz + r) as usize) * self.side() + (dx + r) as usize]
    }
}

/// The cells a deformation can change: inclusive column and row ranges clipped to the grid.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Rect {
    pub c0: usize,
    pub c1: usize,
    pub r0: usize,
    pub r1: usize,
}

impl Rect {
    pub fn around(col: usize, row: usize, radius: usize, cols: usize, rows: usize) -> Self {
        Self {
            c0: col.saturating_sub(radius),
            c1: (col + radius).min(cols - 1),
            r0: row.saturating_sub(radius),
            r1: (row + radius).min(rows - 1),
        }
    }

    pub fn intersects(&self, other: &Rect) -> bool {
        self.c0 <= other.c1 && other.c0 <= self.c1 && self.r0 <= other.r1 && other.r0 <= self.r1
    }

    pub fn contains(&self, col: usize, row: usize) -> bool {
        (self.c0..=self.c1).contains(&col) && (self.r0..=self.r1).contains(&row)
    }
}

/// Apply one deformation to row-major `heights`: h'(p) = h(p) + (a − h(v))·K(|p − v|). The
/// search and the replay both go through here, so their heights are bit-identical.
pub fn apply(heights: &mut [f64], cols: usize, rows: usize, col: usize, row: usize, amplitude: f64, kernel: &Kernel) {
    let delta = amplitude - heights[row * cols + col];
    let rect = Rect::around(col, row, kernel.radius, cols, rows);
    let r = kernel.radius as i64;
    for rr in rect.r0..=rect.r1 {
        let krow = ((rr as i64 - row as i64 + r) as usize) * kernel.side();
        for cc in rect.c0..=rect.c1 {
            let k = kernel.weights[krow + (cc as i64 - col as i64 + r) as usize];
            heights[rr * cols + cc] += delta * k;
        }
    }
    // The centre weight is exactly 1, but h + (a − h) need not round to a; pin it.
    heights[row * cols + col] = amplitude;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_kernel_is_one_at_the_centre_and_zero_at_the_radius() {
        for radius in [1, 3, 7, 32] {
            let k = Kernel::new(radius);
            assert_eq!(k.at(0, 0), 1.0);
            let r = radius as i64;
            assert_eq!(k.at(r, 0), 0.0);
            assert_eq!(k.at(0, -r), 0.0);
            assert_eq!(k.at(r, r), 0.0);
            if radius > 1 {
                let inner = k.at(r - 1, 0);
                assert!(inner > 0.0 && inner < 0.2, "{inner}");
                assert!(k.at(1, 0) > 0.9 || radius < 4);
            }
            assert!(k.weights.iter().all(|&w| (0.0..=1.0).contains(&w)));
        }
    }

    #[test]
    fn applying_moves_the_vertex_exactly_to_the_amplitude_and_nothing_beyond_the_radius() {
        let (cols, rows) = (20, 15);
        let mut h: Vec<f64> = (0..cols * rows).map(|i| (i as f64 * 0.37).sin() * 10.0).collect();
        let before = h.clone();
        let k = Kernel::new(4);
        apply(&mut h, cols, rows, 3, 5, 42.125, &k);
        assert_eq!(h[5 * cols + 3], 42.125);
        for r in 0..rows {
            for c in 0..cols {
                let d2 = (c as i64 - 3).pow(2) + (r as i64 - 5).pow(2);
                if d2 >= 16 {
                    assert_eq!(h[r * cols + c], before[r * cols + c], "({c}, {r})");
                }
            }
        }
    }
}
