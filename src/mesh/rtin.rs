//! Right-triangulated irregular networks (RTIN; Evans, Kirkpatrick & Townsend 2001, as
//! Mapbox's martini builds them): an error-bounded triangulation of a heightfield's grid
//! straight from its heights, in a few milliseconds where simplifying and measuring the grid's
//! mesh takes a tenth of a second or more. Each right triangle of the hierarchy over the
//! smallest square of 2^k + 1 vertices a side that holds the grid splits at its hypotenuse's
//! midpoint while it lies farther than the bound from the grid's own mesh anywhere over its
//! plan, or a triangle below it must split. The grid's mesh is the hierarchy's finest level
//! ([`grid_triangles`] splits its cells as the hierarchy does), so every level's edges lie on
//! the mesh's and a bound of 0 gives the mesh back.
//!
//! Unlike martini, which bounds each split against its parent only (errors of nested levels
//! add), a triangle's error here is its exact largest vertical distance from the grid's mesh:
//! both are planes over the same cells, so the distance is linear between the grid vertices a
//! triangle covers and the cell centres where its diagonal sides cross the mesh's diagonals.
//! Both surfaces are graphs over the same rectangle, so a vertical gap of e puts every point of
//! either within e of the other: the figure bounds the two-sided distance, no sampling needed.
//! Triangles across the grid's edge (the square is larger than a grid not 2^k + 1 a side, or
//! not square) always split, and those beyond it are left out: the triangulation tiles the
//! grid's rectangle, without T-junctions (the hypotenuse's two triangles share one error, and a
//! parent's error holds its children's, as in martini).
//!
//! [`grid_triangles`]: super::heightfield_mesh

use rayon::prelude::*;

/// The error of each vertex of the square as a split point: the largest exact error of the
/// triangles whose hypotenuse it halves and of every split below them.
pub struct Rtin {
    size: usize,
    cols: usize,
    rows: usize,
    errors: Vec<f32>,
}

impl Rtin {
    /// The errors of a grid of `cols × rows` vertices (heights row by row, X along a row), as
    /// [`heightfield_mesh`](super::heightfield_mesh) lays them out with evenly spaced columns
    /// and rows; `None` for fewer than two a side or heights of another length.
    pub fn new(heights: &[f32], cols: usize, rows: usize) -> Option<Self> {
        if cols < 2 || rows < 2 || heights.len() != cols * rows {
            return None;
        }
        let tile = (cols.max(rows) - 1).next_power_of_two().max(2);
        let size = tile + 1;
        let triangles = tile * tile * 2 - 2;
        let parents = triangles - tile * tile;
        let grid = Grid { heights, cols, rows };
        // Each triangle's own error, in parallel (they are independent), then gathered up the
        // hierarchy in martini's order, finest first.
        let own: Vec<f32> = (0..triangles).into_par_iter().map(|i| grid.error(corners(i, tile))).collect();
        let mut errors = vec![0.0f32; size * size];
        for i in (0..triangles).rev() {
            let [ax, ay, bx, by, cx, cy] = corners(i, tile);
            let middle = ((ay + by) / 2) * size + (ax + bx) / 2;
            let mut error = own[i].max(errors[middle]);
            if i < parents {
                let left = ((ay + cy) / 2) * size + (ax + cx) / 2;
                let right = ((by + cy) / 2) * size + (bx + cx) / 2;
                error = error.max(errors[left]).max(errors[right]);
            }
            errors[middle] = error;
        }
        Some(Self { size, cols, rows, errors })
    }

    /// The triangles (grid vertex indices, counter-clockwise seen from +Y with X along columns
    /// and Z along rows) within `bound` of the grid's mesh.
    pub fn triangles(&self, bound: f32) -> Vec<u32> {
        let max = self.size - 1;
        let mut out = Vec::new();
        let mut stack = vec![[0, 0, max, max, max, 0], [max, max, 0, 0, 0, max]];
        while let Some([ax, ay, bx, by, cx, cy]) = stack.pop() {
            if ax.min(bx).min(cx) >= self.cols - 1 || ay.min(by).min(cy) >= self.rows - 1 {
                continue; // beyond the grid
            }
            let (mx, my) = ((ax + bx) / 2, (ay + by) / 2);
            // One across the grid's edge always splits (its error is infinite, but so may the
            // bound be).
            let across = ax.max(bx).max(cx) > self.cols - 1 || ay.max(by).max(cy) > self.rows - 1;
            let split = across || bound.is_nan() || self.errors[my * self.size + mx] > bound;
            if ax.abs_diff(cx) + ay.abs_diff(cy) > 1 && split {
                stack.push([bx, by, cx, cy, mx, my]);
                stack.push([cx, cy, ax, ay, mx, my]);
            } else {
                let index = |x: usize, y: usize| (y * self.cols + x) as u32;
                // a, b, c as martini orders them turn counter-clockwise seen from +Y, as the
                // grid mesh's triangles do (negative in plan (x, z)).
                out.extend([index(ax, ay), index(bx, by), index(cx, cy)]);
            }
        }
        out
    }
}

/// The largest vertical distance between the mesh of a `cols × rows` grid of `heights` (its
/// cells split as [`heightfield_mesh`](super::heightfield_mesh) splits them) and `triangles`
/// over the grid's vertices whose sides run along the grid's lines and diagonals (as
/// [`Rtin::triangles`] gives them): exact, not sampled.
pub fn vertical_deviation(heights: &[f32], cols: usize, rows: usize, triangles: &[u32]) -> f32 {
    let grid = Grid { heights, cols, rows };
    let at = |v: u32| (v as usize % cols, v as usize / cols);
    triangles
        .par_chunks_exact(3)
        .map(|t| {
            let ([ax, ay], [bx, by], [cx, cy]) = (at(t[0]).into(), at(t[1]).into(), at(t[2]).into());
            debug_assert!(
                [(ax, ay, bx, by), (bx, by, cx, cy), (cx, cy, ax, ay)]
                    .iter()
                    .all(|&(x0, z0, x1, z1)| x0 == x1 || z0 == z1 || x0.abs_diff(x1) == z0.abs_diff(z1)),
                "sides along the grid's lines and diagonals"
            );
            grid.error([ax, ay, bx, by, cx, cy])
        })
        .collect::<Vec<f32>>()
        .into_iter()
        .fold(0.0, f32::max)
}

/// A grid of heights, row by row.
struct Grid<'a> {
    heights: &'a [f32],
    cols: usize,
    rows: usize,
}

impl Grid<'_> {
    fn height(&self, x: usize, z: usize) -> f64 {
        f64::from(self.heights[z * self.cols + x])
    }

    /// The largest vertical distance between the plane through the corners of triangle
    /// `[ax, ay, bx, by, cx, cy]` (grid coordinates) and the grid's mesh over it: 0 wholly
    /// beyond the grid, infinite across its edge.
    fn error(&self, [ax, ay, bx, by, cx, cy]: [usize; 6]) -> f32 {
        let (x0, x1) = (ax.min(bx).min(cx), ax.max(bx).max(cx));
        let (z0, z1) = (ay.min(by).min(cy), ay.max(by).max(cy));
        if x0 >= self.cols - 1 || z0 >= self.rows - 1 {
            return 0.0;
        }
        if x1 > self.cols - 1 || z1 > self.rows - 1 {
            return f32::INFINITY;
        }
        let p = [(ax, ay), (bx, by), (cx, cy)].map(|(x, z)| (x as i64, z as i64));
        let h = [(ax, ay), (bx, by), (cx, cy)].map(|(x, z)| self.height(x, z));
        // Twice the signed areas against each side: barycentric weights times `area`.
        let side =
            |i: usize, j: usize, x: i64, z: i64| (p[j].0 - p[i].0) * (z - p[i].1) - (p[j].1 - p[i].1) * (x - p[i].0);
        let area = side(0, 1, p[2].0, p[2].1);
        let plane = |x: i64, z: i64| {
            let w = [side(1, 2, x, z), side(2, 0, x, z), side(0, 1, x, z)];
            (w[0] as f64 * h[0] + w[1] as f64 * h[1] + w[2] as f64 * h[2]) / area as f64
        };
        let mut worst = 0.0f64;
        for z in z0..=z1 {
            for x in x0..=x1 {
                let (xi, zi) = (x as i64, z as i64);
                let inside = [side(1, 2, xi, zi), side(2, 0, xi, zi), side(0, 1, xi, zi)]
                    .iter()
                    .all(|&w| w == 0 || (w > 0) == (area > 0));
                if inside {
                    worst = worst.max((plane(xi, zi) - self.height(x, z)).abs());
                }
            }
        }
        // A side crossing a cell whose mesh diagonal runs the other way (never, for the
        // triangles of an RTIN: their sides lie on the mesh's edges) crosses that diagonal at
        // the cell's centre: the mesh's height there is the mean of its diagonal's ends, the
        // triangle's the mean of the side's.
        for (i, j) in [(0, 1), (1, 2), (2, 0)] {
            let ((xa, za), (xb, zb)) = (p[i], p[j]);
            if xa == xb || za == zb {
                continue;
            }
            let (sx, sz) = ((xb - xa).signum(), (zb - za).signum());
            for k in 0..(xb - xa).abs() {
                let (x, z) = (xa + k * sx, za + k * sz);
                let (cx, cz) = (x.min(x + sx), z.min(z + sz));
                let mesh_main = (cx + cz) % 2 == 0;
                if mesh_main == (sx == sz) {
                    continue;
                }
                let corner = |x: i64, z: i64| self.height(x as usize, z as usize);
                let mesh = if mesh_main {
                    0.5 * (corner(cx, cz) + corner(cx + 1, cz + 1))
                } else {
                    0.5 * (corner(cx + 1, cz) + corner(cx, cz + 1))
                };
                let level = 0.5 * (plane(x, z) + plane(x + sx, z + sz));
                worst = worst.max((mesh - level).abs());
            }
        }
        worst as f32
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

    fn grid(cols: usize, rows: usize, h: impl Fn(f64, f64) -> f64) -> Vec<f32> {
        (0..cols * rows).map(|i| h((i % cols) as f64, (i / cols) as f64) as f32).collect()
    }

    /// The height of the grid's own mesh at plan point (x, z), from its cell's two triangles
    /// (cell (i, j) split from (i, j) to (i + 1, j + 1) when i + j is even, else the other way).
    fn mesh_height(h: &[f32], cols: usize, x: f64, z: f64) -> f64 {
        let rows = h.len() / cols;
        let (i, j) = ((x.floor() as usize).min(cols - 2), (z.floor() as usize).min(rows - 2));
        let (u, v) = (x - i as f64, z - j as f64);
        let at = |x: usize, z: usize| f64::from(h[z * cols + x]);
        let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i, j + 1), at(i + 1, j + 1));
        if (i + j) % 2 == 0 {
            if u >= v {
                a + u * (b - a) + v * (d - b)
            } else {
                a + v * (c - a) + u * (d - c)
            }
        } else if u + v <= 1.0 {
            a + u * (b - a) + v * (c - a)
        } else {
            d + (1.0 - u) * (c - d) + (1.0 - v) * (b - d)
        }
    }

    #[test]
    fn grids_of_any_size_from_two_a_side() {
        assert!(Rtin::new(&[0.0; 4], 2, 2).is_some());
        assert!(Rtin::new(&[0.0; 12], 4, 3).is_some());
        assert!(Rtin::new(&[0.0; 3], 3, 1).is_none());
        assert!(Rtin::new(&[0.0; 5], 2, 2).is_none());
    }

    #[test]
    fn a_plane_is_two_triangles() {
        let h = grid(33, 33, |x, z| 0.5 * x - 0.25 * z + 3.0);
        let t = Rtin::new(&h, 33, 33).unwrap().triangles(1e-3);
        assert_eq!(t.len(), 6);
        assert_eq!(vertical_deviation(&h, 33, 33, &t), 0.0);
    }

    /// A flat grid with one vertex raised 1 m: kept under a 0.5 m bound, gone under 2 m, where
    /// the level is flat and misses the peak by exactly its height.
    #[test]
    fn one_raised_vertex_is_kept_or_missed_by_its_height() {
        let (cols, rows) = (17, 17);
        let mut h = vec![0.0f32; cols * rows];
        h[5 * cols + 7] = 1.0;
        let rtin = Rtin::new(&h, cols, rows).unwrap();
        let kept = rtin.triangles(0.5);
        assert!(kept.contains(&((5 * cols + 7) as u32)));
        assert!(vertical_deviation(&h, cols, rows, &kept) <= 0.5);
        let flat = rtin.triangles(2.0);
        assert_eq!(flat.len(), 6);
        assert_eq!(vertical_deviation(&h, cols, rows, &flat), 1.0);
    }

    /// One cell whose heights twist, split by the mesh from (0, 0) to (1, 1): triangles along
    /// its other diagonal, whose ends are 1 m up, miss the mesh's 0 m at its centre by 1 m.
    #[test]
    fn a_cell_split_the_other_way_misses_by_half_its_twist() {
        let h = vec![0.0, 1.0, 1.0, 0.0];
        let rtin = Rtin::new(&h, 2, 2).unwrap();
        assert_eq!(vertical_deviation(&h, 2, 2, &rtin.triangles(10.0)), 0.0, "the mesh's own split");
        let across = [0, 2, 1, 1, 2, 3];
        assert_eq!(vertical_deviation(&h, 2, 2, &across), 1.0);
        let flat = vec![2.0; 4];
        assert_eq!(vertical_deviation(&flat, 2, 2, &across), 0.0);
    }

    /// At bound 0 a rough grid's triangulation is its mesh, triangle for triangle: the hierarchy's
    /// finest level and the mesh's split agree.
    #[test]
    fn bound_zero_gives_the_grids_own_mesh() {
        for (cols, rows) in [(9, 9), (12, 7), (2, 5)] {
            let h = grid(cols, rows, |x, z| ((x * 12.9898 + z * 78.233).sin() * 43758.5453).fract());
            let mut got: Vec<[u32; 3]> =
                Rtin::new(&h, cols, rows).unwrap().triangles(0.0).chunks_exact(3).map(turned).collect();
            let mut mesh: Vec<[u32; 3]> =
                super::super::heightfield_mesh::grid_triangles(cols, rows).chunks_exact(3).map(turned).collect();
            got.sort_unstable();
            mesh.sort_unstable();
            assert_eq!(got, mesh, "{cols}×{rows}");
        }
    }

    /// A triangle's corners turned to start at its least, keeping their order.
    fn turned(t: &[u32]) -> [u32; 3] {
        let k = (0..3).min_by_key(|&k| t[k]).unwrap();
        [t[k], t[(k + 1) % 3], t[(k + 2) % 3]]
    }

    /// On rough grids of sizes no square of 2^k + 1 fits: the triangles tile the rectangle once,
    /// turn the grid's way, meet without T-junctions, and the exact figure is at most the bound
    /// and at least what dense sampling of both surfaces finds (a second method).
    #[test]
    fn rectangles_are_tiled_once_without_t_junctions_within_the_bound() {
        for (cols, rows) in [(33, 21), (20, 37), (65, 65)] {
            let h = grid(cols, rows, |x, z| {
                (x * 0.37).sin() * 6.0 + (z * 0.23).cos() * 4.0 + ((x * 7.1 + z * 3.3).sin() * 0.8)
            });
            let rtin = Rtin::new(&h, cols, rows).unwrap();
            let mut counts = Vec::new();
            for bound in [0.05f32, 0.5, 2.0, 8.0] {
                let t = rtin.triangles(bound);
                counts.push(t.len() / 3);
                let mut area = 0.0;
                let plan = |v: u32| ((v as usize % cols) as i64, (v as usize / cols) as i64);
                for tri in t.chunks_exact(3) {
                    let p = [plan(tri[0]), plan(tri[1]), plan(tri[2])];
                    let cross = (p[1].0 - p[0].0) * (p[2].1 - p[0].1) - (p[1].1 - p[0].1) * (p[2].0 - p[0].0);
                    assert!(cross < 0, "triangle {tri:?} turns the wrong way");
                    area -= cross as f64 / 2.0;
                }
                assert_eq!(area, ((cols - 1) * (rows - 1)) as f64, "{cols}×{rows} at {bound}: the rectangle, once");
                // No used vertex lies inside another triangle's side.
                let used: std::collections::BTreeSet<u32> = t.iter().copied().collect();
                for tri in t.chunks_exact(3) {
                    for k in 0..3 {
                        let (a, b) = (plan(tri[k]), plan(tri[(k + 1) % 3]));
                        let steps = (b.0 - a.0).abs().max((b.1 - a.1).abs());
                        for s in 1..steps {
                            let (dx, dz) = ((b.0 - a.0) / steps, (b.1 - a.1) / steps);
                            let inner = ((a.1 + s * dz) as usize * cols + (a.0 + s * dx) as usize) as u32;
                            assert!(!used.contains(&inner), "T-junction at {inner} on {tri:?}");
                        }
                    }
                }
                let exact = vertical_deviation(&h, cols, rows, &t);
                // Every level triangle sampled on a lattice of quarter cells (it holds the grid's
                // vertices and the cells' centres, where the difference of two planes over
                // cells turns), by barycentric weights.
                let mut sampled = 0.0f64;
                let n = 4;
                for tri in t.chunks_exact(3) {
                    let p = [tri[0], tri[1], tri[2]].map(|v| {
                        let (x, z) = plan(v);
                        (x as f64, z as f64, f64::from(h[v as usize]))
                    });
                    let d = (p[1].1 - p[2].1) * (p[0].0 - p[2].0) + (p[2].0 - p[1].0) * (p[0].1 - p[2].1);
                    let (lo_x, hi_x) =
                        (p.iter().map(|q| q.0).fold(f64::MAX, f64::min), p.iter().map(|q| q.0).fold(0.0, f64::max));
                    let (lo_z, hi_z) =
                        (p.iter().map(|q| q.1).fold(f64::MAX, f64::min), p.iter().map(|q| q.1).fold(0.0, f64::max));
                    for zi in (lo_z as usize * n)..=(hi_z as usize * n) {
                        for xi in (lo_x as usize * n)..=(hi_x as usize * n) {
                            let (x, z) = (xi as f64 / n as f64, zi as f64 / n as f64);
                            let l0 = ((p[1].1 - p[2].1) * (x - p[2].0) + (p[2].0 - p[1].0) * (z - p[2].1)) / d;
                            let l1 = ((p[2].1 - p[0].1) * (x - p[2].0) + (p[0].0 - p[2].0) * (z - p[2].1)) / d;
                            let l2 = 1.0 - l0 - l1;
                            if l0 >= -1e-12 && l1 >= -1e-12 && l2 >= -1e-12 {
                                let level = l0 * p[0].2 + l1 * p[1].2 + l2 * p[2].2;
                                sampled = sampled.max((level - mesh_height(&h, cols, x, z)).abs());
                            }
                        }
                    }
                }
                assert!(
                    (f64::from(exact) - sampled).abs() < 1e-4,
                    "{cols}×{rows} at {bound}: exact {exact}, sampled {sampled}"
                );
                // Within the bound, but where a single cell split the other way twists more.
                let twist = (0..(rows - 1) * (cols - 1))
                    .map(|c| {
                        let (x, z) = (c % (cols - 1), c / (cols - 1));
                        let at = |x: usize, z: usize| h[z * cols + x];
                        (at(x, z) + at(x + 1, z + 1) - at(x + 1, z) - at(x, z + 1)).abs() / 2.0
                    })
                    .fold(0.0f32, f32::max);
                assert!(exact <= bound.max(twist) + 1e-5, "{cols}×{rows} at {bound}: {exact} (twist {twist})");
            }
            assert!(counts.windows(2).all(|w| w[1] <= w[0]), "{counts:?}");
            assert!(counts[3] * 10 < counts[0], "{cols}×{rows}: {counts:?}");
        }
    }
}
