//! Right-triangulated irregular networks (RTIN; Evans, Kirkpatrick & Townsend 2001, as
//! Mapbox's martini builds them): an error-bounded triangulation of a square grid of
//! 2^k + 1 vertices a side straight from its heights, without meshing the full grid first.
//! Each right triangle splits at its hypotenuse's midpoint while the height there, or the error
//! of any split below it, lies farther than the bound from the line through the hypotenuse's
//! ends, measured vertically. That is martini's error, which bounds each split against its own
//! parent only: errors of nested levels can add, so a triangulation is measured afterwards like
//! the simplifier's levels. It is the alternative the issue asks to measure against simplifying
//! the full grid: see `benches/assets.rs`.

use super::Mesh;

/// The error of each grid vertex as a split point: how far (vertically) the coarser triangle
/// through it misses the heights it covers, at it and below it.
pub struct Rtin {
    size: usize,
    errors: Vec<f32>,
}

impl Rtin {
    /// The errors of a `size × size` grid (row-major heights); `None` unless `size` is
    /// 2^k + 1 with k ≥ 1.
    pub fn new(heights: &[f32], size: usize) -> Option<Self> {
        let tile = size.checked_sub(1)?;
        if tile == 0 || !tile.is_power_of_two() || heights.len() != size * size {
            return None;
        }
        let triangles = tile * tile * 2 - 2;
        let parents = triangles - tile * tile;
        let mut errors = vec![0.0f32; size * size];
        for i in (0..triangles).rev() {
            let [ax, ay, bx, by, cx, cy] = corners(i, tile);
            let (mx, my) = ((ax + bx) / 2, (ay + by) / 2);
            let middle = my * size + mx;
            let interpolated = 0.5 * (heights[ay * size + ax] + heights[by * size + bx]);
            let mut error = (interpolated - heights[middle]).abs().max(errors[middle]);
            if i < parents {
                let left = ((ay + cy) / 2) * size + (ax + cx) / 2;
                let right = ((by + cy) / 2) * size + (bx + cx) / 2;
                error = error.max(errors[left]).max(errors[right]);
            }
            errors[middle] = error;
        }
        Some(Self { size, errors })
    }

    /// The triangles (grid vertex indices, counter-clockwise seen from +Y with X along columns
    /// and Z along rows) within `bound` of the heights.
    pub fn triangles(&self, bound: f32) -> Vec<u32> {
        let max = self.size - 1;
        let mut out = Vec::new();
        let mut stack = vec![[0, 0, max, max, max, 0], [max, max, 0, 0, 0, max]];
        while let Some([ax, ay, bx, by, cx, cy]) = stack.pop() {
            let (mx, my) = ((ax + bx) / 2, (ay + by) / 2);
            if ax.abs_diff(cx) + ay.abs_diff(cy) > 1 && self.errors[my * self.size + mx] > bound {
                stack.push([bx, by, cx, cy, mx, my]);
                stack.push([cx, cy, ax, ay, mx, my]);
            } else {
                let index = |x: usize, y: usize| (y * self.size + x) as u32;
                // a, b, c as martini orders them turn counter-clockwise seen from +Y, as the
                // grid mesh's triangles do (negative in plan (x, z)).
                out.extend([index(ax, ay), index(bx, by), index(cx, cy)]);
            }
        }
        out
    }

    /// `grid` (a square grid mesh of this size, its vertices row by row) triangulated within
    /// `bound`, keeping only the vertices used.
    pub fn mesh(&self, grid: &Mesh, bound: f32) -> Mesh {
        super::types::compact(grid, &self.triangles(bound))
    }
}

/// Corners a, b, c of triangle `i` of the hierarchy over a `tile`-cell square (martini's
/// numbering: a and b end the hypotenuse, c is the right angle).
fn corners(i: usize, tile: usize) -> [usize; 6] {
    let mut id = i + 2;
    let [mut ax, mut ay, mut bx, mut by, mut cx, mut cy] = [0usize; 6];
    if id & 1 == 1 {
        (bx, by, cx) = (tile, tile, tile);
    } else {
        (ax, ay, cy) = (tile, tile, tile);
    }
    loop {
        id >>= 1;
        if id <= 1 {
            break;
        }
        let (mx, my) = ((ax + bx) / 2, (ay + by) / 2);
        if id & 1 == 1 {
            (bx, by, ax, ay) = (ax, ay, cx, cy);
        } else {
            (ax, ay, bx, by) = (bx, by, cx, cy);
        }
        (cx, cy) = (mx, my);
    }
    [ax, ay, bx, by, cx, cy]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(size: usize, h: impl Fn(f32, f32) -> f32) -> Vec<f32> {
        (0..size * size).map(|i| h((i % size) as f32, (i / size) as f32)).collect()
    }

    /// The height the triangles give at grid point (x, z), by barycentric interpolation in
    /// the one triangle whose plan holds it.
    fn interpolated(triangles: &[u32], heights: &[f32], size: usize, x: f64, z: f64) -> Option<f64> {
        let at = |i: u32| ((i as usize % size) as f64, (i as usize / size) as f64, f64::from(heights[i as usize]));
        triangles.chunks_exact(3).find_map(|t| {
            let [(x0, z0, h0), (x1, z1, h1), (x2, z2, h2)] = [at(t[0]), at(t[1]), at(t[2])];
            let d = (z1 - z2) * (x0 - x2) + (x2 - x1) * (z0 - z2);
            let l0 = ((z1 - z2) * (x - x2) + (x2 - x1) * (z - z2)) / d;
            let l1 = ((z2 - z0) * (x - x2) + (x0 - x2) * (z - z2)) / d;
            let l2 = 1.0 - l0 - l1;
            (l0 >= -1e-9 && l1 >= -1e-9 && l2 >= -1e-9).then_some(l0 * h0 + l1 * h1 + l2 * h2)
        })
    }

    #[test]
    fn only_square_grids_of_two_to_the_k_plus_one() {
        assert!(Rtin::new(&[0.0; 9], 3).is_some());
        assert!(Rtin::new(&[0.0; 16], 4).is_none());
        assert!(Rtin::new(&[0.0; 1], 1).is_none());
    }

    #[test]
    fn a_plane_is_two_triangles() {
        let h = grid(33, |x, z| 0.5 * x - 0.25 * z + 3.0);
        let t = Rtin::new(&h, 33).unwrap().triangles(1e-3);
        assert_eq!(t.len(), 6);
    }

    #[test]
    fn the_plan_is_covered_once_the_turn_is_the_grids_and_bound_zero_is_exact() {
        let size = 65;
        let h = grid(size, |x, z| {
            (x * 0.21).sin() * 6.0 + (z * 0.13).cos() * 4.0 + ((x - 30.0).powi(2) + (z - 20.0).powi(2)).sqrt() * 0.1
        });
        let rtin = Rtin::new(&h, size).unwrap();
        for bound in [0.0f32, 0.05, 0.5, 2.0] {
            let t = rtin.triangles(bound);
            // Counter-clockwise seen from +Y (X right, Z towards the viewer): negative in (x, z).
            let mut area = 0.0;
            for tri in t.chunks_exact(3) {
                let p: [(f64, f64); 3] =
                    std::array::from_fn(|k| ((tri[k] as usize % size) as f64, (tri[k] as usize / size) as f64));
                let cross = (p[1].0 - p[0].0) * (p[2].1 - p[0].1) - (p[1].1 - p[0].1) * (p[2].0 - p[0].0);
                assert!(cross < 0.0, "triangle {tri:?} turns the wrong way");
                area -= cross / 2.0;
            }
            assert_eq!(area, 64.0 * 64.0, "the triangles tile the square");
            let mut worst = 0.0f64;
            for z in 0..size {
                for x in 0..size {
                    let got = interpolated(&t, &h, size, x as f64, z as f64).expect("covered");
                    worst = worst.max((got - f64::from(h[z * size + x])).abs());
                }
            }
            if bound == 0.0 {
                assert!(worst < 1e-5, "bound 0 keeps every height: {worst}");
            } else {
                // Martini's error bounds each split against its parent: nested errors add, but
                // not past a few bounds on a smooth field.
                assert!(worst <= 3.0 * f64::from(bound), "bound {bound}: {worst}");
            }
            if bound == 2.0 {
                assert!(t.len() / 3 < 64 * 64 * 2 / 4, "{} triangles at 2 m", t.len() / 3);
            }
        }
    }
}
