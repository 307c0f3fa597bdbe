//! How far apart two surfaces are: the largest distance from a point of either mesh to the
//! other (two-sided, a sampled Hausdorff distance). Points are taken on every triangle at most
//! `spacing` apart (its corners, its edges and a barycentric grid inside), and each is measured
//! to the nearest triangle of the other mesh exactly (closest point on a triangle, in f64),
//! found through a grid of cells that lists the triangles passing through each. The largest
//! distance wins, so the figure is the same whatever the thread count.

use rayon::prelude::*;

use super::Mesh;
use crate::stop::{Stop, Stopped};

/// Most sample points on one triangle side (a triangle gets at most about half its square).
const MAX_SPLITS: usize = 256;

/// The sampled two-sided distance between `a` and `b` in metres, points at most `spacing_m`
/// apart (or `MAX_SPLITS` per triangle side). 0 for two empty meshes, infinite when only one
/// is empty. `stop` is looked at between chunks of samples (a large mesh takes seconds).
pub fn max_deviation(a: &Mesh, b: &Mesh, spacing_m: f32, stop: Stop) -> Result<f32, Stopped> {
    match (a.indices.is_empty(), b.indices.is_empty()) {
        (true, true) => return Ok(0.0),
        (true, false) | (false, true) => return Ok(f32::INFINITY),
        _ => {}
    }
    let (ab, ba) = rayon::join(|| one_sided(a, b, spacing_m, stop), || one_sided(b, a, spacing_m, stop));
    stop.check()?;
    Ok(ab.max(ba) as f32)
}

/// The largest distance from a sample of `from` to the surface of `to`. A sample within the
/// largest distance found so far (by any thread) cannot raise it, so it is only checked against
/// that distance, stopping at the first triangle close enough; the others are measured exactly.
/// The maximum is the same whichever samples were only checked.
/// A stopped search returns early with what it found (the caller looks at `stop` again).
fn one_sided(from: &Mesh, to: &Mesh, spacing_m: f32, stop: Stop) -> f64 {
    use std::sync::atomic::{AtomicU64, Ordering};
    let Some(index) = TriangleIndex::new(to, stop) else { return 0.0 };
    let spacing = f64::from(spacing_m.max(1e-6));
    // Non-negative f64s order as their bits do.
    let found = AtomicU64::new(0f64.to_bits());
    let measure = |s: [f64; 3], hint: &mut u32| {
        let so_far = f64::from_bits(found.load(Ordering::Relaxed));
        if !index.any_within(s, so_far, hint) {
            let d = index.distance(s, so_far.max(index.cell));
            found.fetch_max(d.to_bits(), Ordering::Relaxed);
        }
    };
    // Triangles' centres first: on a coarse mesh they are the points farthest from the fine
    // one, so the largest distance is found early and most later samples are only checked.
    from.indices.par_chunks(3 * 256).for_each(|chunk| {
        if stop.requested() {
            return;
        }
        let mut hint = 0;
        for t in chunk.chunks_exact(3) {
            let [p, q, r] = [0, 1, 2].map(|k| point(from, t[k]));
            measure(std::array::from_fn(|k| (p[k] + q[k] + r[k]) / 3.0), &mut hint);
        }
    });
    // Every vertex once, then the points along and inside each triangle (not its corners).
    from.positions.par_chunks(1024).for_each(|chunk| {
        if stop.requested() {
            return;
        }
        let mut hint = 0;
        for v in chunk {
            measure(v.map(f64::from), &mut hint);
        }
    });
    from.indices.par_chunks_exact(3).for_each(|t| {
        if stop.requested() {
            return;
        }
        let [p, q, r] = [0, 1, 2].map(|k| point(from, t[k]));
        let longest = dist(p, q).max(dist(q, r)).max(dist(r, p));
        let n = ((longest / spacing).ceil() as usize).clamp(1, MAX_SPLITS);
        // Neighbouring samples are near the same triangles of `to`: the last one found close
        // enough is tried first.
        let mut hint = 0;
        for i in 0..=n {
            for j in 0..=n - i {
                if (i == 0 && (j == 0 || j == n)) || i == n {
                    continue;
                }
                let (u, v) = (i as f64 / n as f64, j as f64 / n as f64);
                measure(std::array::from_fn(|k| p[k] + u * (q[k] - p[k]) + v * (r[k] - p[k])), &mut hint);
            }
        }
    });
    f64::from_bits(found.into_inner())
}

/// The side of a square of the mesh's mean triangle area, metres (0 without triangles).
pub fn mean_triangle_side(mesh: &Mesh) -> f64 {
    let area: f64 = mesh
        .indices
        .chunks_exact(3)
        .map(|t| {
            let [p, q, r] = [0, 1, 2].map(|k| point(mesh, t[k]));
            0.5 * norm(cross(sub(q, p), sub(r, p)))
        })
        .sum();
    (2.0 * area / mesh.triangle_count().max(1) as f64).sqrt()
}

fn point(mesh: &Mesh, i: u32) -> [f64; 3] {
    mesh.positions[i as usize].map(f64::from)
}

fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>().sqrt()
}

/// A mesh's triangles by the cells of a regular grid they pass through (compressed: the
/// occupied cells' keys sorted, each with its range of triangle numbers).
struct TriangleIndex<'a> {
    mesh: &'a Mesh,
    origin: [f64; 3],
    cell: f64,
    dims: [i64; 3],
    keys: Vec<u64>,
    starts: Vec<u32>,
    triangles: Vec<u32>,
}

impl<'a> TriangleIndex<'a> {
    /// `None` once `stop` is raised: a million triangles take seconds to index.
    fn new(mesh: &'a Mesh, stop: Stop) -> Option<Self> {
        let (lo, hi) = mesh.bounds().expect("a mesh with triangles");
        let origin = lo.map(f64::from);
        let extent = (0..3).map(|k| f64::from(hi[k] - lo[k])).fold(0.0, f64::max).max(1e-6);
        // Cells about the size of the mean triangle, so a search reads a few triangles per cell
        // (only occupied cells are stored); at most 4096 along the longest side.
        let cell = (extent / 4096.0).max(mean_triangle_side(mesh));
        let dims: [i64; 3] = std::array::from_fn(|k| ((f64::from(hi[k] - lo[k]) / cell).floor() as i64 + 1).max(1));
        let key = |c: [i64; 3]| (c[0] + dims[0] * (c[1] + dims[1] * c[2])) as u64;
        let half_diagonal = 0.5 * cell * 3f64.sqrt();
        let mut pairs: Vec<(u64, u32)> = mesh
            .indices
            .par_chunks_exact(3)
            .enumerate()
            .flat_map_iter(|(n, t)| {
                let mut out = Vec::new();
                if stop.requested() {
                    return out;
                }
                let tri = [0, 1, 2].map(|k| point(mesh, t[k]));
                let cell_of = |v: f64, k: usize| (((v - origin[k]) / cell).floor() as i64).clamp(0, dims[k] - 1);
                let lo: [i64; 3] = std::array::from_fn(|k| cell_of(tri[0][k].min(tri[1][k]).min(tri[2][k]), k));
                let hi: [i64; 3] = std::array::from_fn(|k| cell_of(tri[0][k].max(tri[1][k]).max(tri[2][k]), k));
                let small = (0..3).all(|k| hi[k] - lo[k] <= 1);
                for z in lo[2]..=hi[2] {
                    for y in lo[1]..=hi[1] {
                        for x in lo[0]..=hi[0] {
                            let c = [x, y, z];
                            // A large triangle keeps only the cells its plane passes through.
                            let centre: [f64; 3] = std::array::from_fn(|k| origin[k] + (c[k] as f64 + 0.5) * cell);
                            if small || dist(centre, closest_on_triangle(centre, tri)) <= half_diagonal {
                                out.push((key(c), n as u32));
                            }
                        }
                    }
                }
                out
            })
            .collect();
        if stop.requested() {
            return None;
        }
        pairs.par_sort_unstable();
        let mut keys = Vec::new();
        let mut starts = Vec::new();
        for (i, &(k, _)) in pairs.iter().enumerate() {
            if keys.last() != Some(&k) {
                keys.push(k);
                starts.push(i as u32);
            }
        }
        starts.push(pairs.len() as u32);
        let triangles = pairs.into_iter().map(|(_, t)| t).collect();
        Some(Self { mesh, origin, cell, dims, keys, starts, triangles })
    }

    /// Whether some triangle lies within `radius` of `p`: the cells next to `p` first (where a
    /// close triangle usually is), then every cell within `radius`, stopping at the first.
    /// `hint` is a triangle to try first, and becomes the one found.
    fn any_within(&self, p: [f64; 3], radius: f64, hint: &mut u32) -> bool {
        let r2 = radius * radius;
        if (*hint as usize) < self.mesh.triangle_count() && self.triangle_within(*hint, p, r2) {
            return true;
        }
        let mut search = |radius: f64| {
            self.cells_around(p, radius).any(|key| {
                match self.cell_triangles(key).iter().find(|&&t| self.triangle_within(t, p, r2)) {
                    Some(&t) => {
                        *hint = t;
                        true
                    }
                    None => false,
                }
            })
        };
        search(self.cell.min(radius)) || (radius > self.cell && search(radius))
    }

    /// The keys of the grid's cells within `radius` of `p` along every axis.
    fn cells_around(&self, p: [f64; 3], radius: f64) -> impl Iterator<Item = u64> + Clone + '_ {
        let range = |k: usize| {
            let lo = (((p[k] - radius - self.origin[k]) / self.cell).floor() as i64).max(0);
            let hi = (((p[k] + radius - self.origin[k]) / self.cell).floor() as i64).min(self.dims[k] - 1);
            lo..=hi
        };
        let (xs, ys, zs) = (range(0), range(1), range(2));
        zs.flat_map(move |z| {
            let xs = xs.clone();
            ys.clone().flat_map(move |y| xs.clone().map(move |x| (x + self.dims[0] * (y + self.dims[1] * z)) as u64))
        })
    }

    /// Whether triangle `t` lies within √`r2` of `p` (its bounding box first).
    fn triangle_within(&self, t: u32, p: [f64; 3], r2: f64) -> bool {
        let tri = self.triangle(t);
        let box_gap: f64 = (0..3)
            .map(|k| {
                let lo = tri[0][k].min(tri[1][k]).min(tri[2][k]);
                let hi = tri[0][k].max(tri[1][k]).max(tri[2][k]);
                (lo - p[k]).max(p[k] - hi).max(0.0).powi(2)
            })
            .sum();
        box_gap <= r2 && {
            let d = closest_on_triangle(p, tri);
            (0..3).map(|k| (d[k] - p[k]).powi(2)).sum::<f64>() <= r2
        }
    }

    /// The distance from `p` to the nearest triangle, searching cells within `radius` first and
    /// doubling it until a triangle closer than the searched radius turns up.
    fn distance(&self, p: [f64; 3], radius: f64) -> f64 {
        let mut radius = radius.max(self.cell);
        loop {
            let best = self
                .cells_around(p, radius)
                .flat_map(|key| self.cell_triangles(key))
                .map(|&t| dist(p, closest_on_triangle(p, self.triangle(t))))
                .fold(f64::INFINITY, f64::min);
            // Every triangle within `radius` of p passes through a searched cell.
            let whole = (0..3).all(|k| {
                p[k] - radius <= self.origin[k] && p[k] + radius >= self.origin[k] + self.dims[k] as f64 * self.cell
            });
            if best <= radius || whole {
                return best;
            }
            radius *= 2.0;
        }
    }

    /// The triangles listed in cell `key` (none for an empty cell).
    fn cell_triangles(&self, key: u64) -> &[u32] {
        match self.keys.binary_search(&key) {
            Ok(at) => &self.triangles[self.starts[at] as usize..self.starts[at + 1] as usize],
            Err(_) => &[],
        }
    }

    /// Triangle `t`'s corners.
    fn triangle(&self, t: u32) -> [[f64; 3]; 3] {
        let i = &self.mesh.indices[3 * t as usize..][..3];
        [0, 1, 2].map(|k| point(self.mesh, i[k]))
    }
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

fn norm(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}

/// The point of triangle `[a, b, c]` closest to `p` (Ericson, Real-Time Collision Detection,
/// 5.1.5: by the Voronoi region of the triangle `p` falls in).
fn closest_on_triangle(p: [f64; 3], [a, b, c]: [[f64; 3]; 3]) -> [f64; 3] {
    let along = |o: [f64; 3], d: [f64; 3], t: f64| [o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2]];
    let (ab, ac, ap) = (sub(b, a), sub(c, a), sub(p, a));
    let (d1, d2) = (dot(ab, ap), dot(ac, ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = sub(p, b);
    let (d3, d4) = (dot(ab, bp), dot(ac, bp));
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return along(a, ab, d1 / (d1 - d3));
    }
    let cp = sub(p, c);
    let (d5, d6) = (dot(ab, cp), dot(ac, cp));
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return along(a, ac, d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return along(b, sub(c, b), (d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let denom = va + vb + vc;
    if denom.abs() < 1e-300 {
        // A degenerate triangle: its nearest corner.
        return [a, b, c].into_iter().min_by(|x, y| dist(p, *x).total_cmp(&dist(p, *y))).expect("three corners");
    }
    let (v, w) = (vb / denom, vc / denom);
    [a[0] + ab[0] * v + ac[0] * w, a[1] + ab[1] * v + ac[1] * w, a[2] + ab[2] * v + ac[2] * w]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::heightfield_mesh;
    use crate::terrain::Heightfield;

    fn plane(n: usize, height: impl Fn(f32, f32) -> f32) -> Mesh {
        heightfield_mesh(&Heightfield::from_fn(n, n, 1.0, height), 4097, None).mesh
    }

    #[test]
    fn closest_points_by_hand() {
        let tri = [[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 0.0, 2.0]];
        assert_eq!(closest_on_triangle([0.5, 3.0, 0.5], tri), [0.5, 0.0, 0.5]);
        assert_eq!(closest_on_triangle([-1.0, 0.0, -1.0], tri), [0.0, 0.0, 0.0]);
        assert_eq!(closest_on_triangle([1.0, 1.0, -5.0], tri), [1.0, 0.0, 0.0]);
        assert_eq!(closest_on_triangle([2.0, 0.0, 2.0], tri), [1.0, 0.0, 1.0]);
    }

    #[test]
    fn a_lifted_copy_deviates_by_the_lift_and_a_bump_by_its_height() {
        let flat = plane(33, |_, _| 0.0);
        let lifted = plane(33, |_, _| 0.75);
        assert!((max_deviation(&flat, &lifted, 0.5, Stop::NEVER).unwrap() - 0.75).abs() < 1e-6);
        // A cone 2 m high at (16, 16): the flat plane's farthest point from the cone's surface
        // is the tip's foot, but the cone's tip is 2 m from the plane: two-sided, 2 m.
        let cone = plane(33, |x, z| (2.0 - ((x - 16.0).powi(2) + (z - 16.0).powi(2)).sqrt()).max(0.0));
        assert!((max_deviation(&flat, &cone, 0.5, Stop::NEVER).unwrap() - 2.0).abs() < 1e-6);
        assert!(max_deviation(&cone, &cone, 0.5, Stop::NEVER).unwrap() < 1e-6);
    }

    #[test]
    fn one_sided_parts_differ_where_one_mesh_covers_less() {
        // A 10 m square against its left half: every point of the half lies on the square, but
        // the square's right edge is 5 m from the half.
        let whole = plane(11, |_, _| 0.0);
        let half = heightfield_mesh(&Heightfield::from_fn(6, 11, 1.0, |_, _| 0.0), 4097, None).mesh;
        assert!(one_sided(&half, &whole, 0.5, Stop::NEVER) < 1e-9);
        assert!((one_sided(&whole, &half, 0.5, Stop::NEVER) - 5.0).abs() < 1e-9);
        assert!((max_deviation(&whole, &half, 0.5, Stop::NEVER).unwrap() - 5.0).abs() < 1e-6);
    }
}
