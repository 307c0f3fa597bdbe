//! Taubin λ|μ smoothing: a shrinking Laplacian step then an inflating one, which removes the
//! staircase of voxel surfaces without the shrinkage of plain Laplacian smoothing (Taubin,
//! "A signal processing approach to fair surface design", SIGGRAPH 1995, §4).

use rayon::prelude::*;

use super::normals::recompute_normals;
use super::Mesh;
use crate::stop::{Stop, Stopped};

/// How much to smooth. Each iteration is one step with `lambda` (> 0, shrinks) and one with
/// `mu` (< −lambda, inflates); the pass band is set by `1/lambda + 1/mu` (≈ 0.1 with the
/// defaults), below which ripples are removed and above which the shape is kept.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Smoothing {
    pub iterations: u32,
    pub lambda: f32,
    pub mu: f32,
    /// Vertices with y <= floor_y + 1e-4 keep their y (slide on the ground)
    pub floor_y: Option<f32>,
}

impl Default for Smoothing {
    fn default() -> Self {
        Self { iterations: 10, lambda: 0.5, mu: -0.53, floor_y: None }
    }
}

/// Smooth the positions with umbrella (uniform-weight) Taubin steps over the triangles' edges,
/// then recompute the normals. Vertices on no triangle stay where they are. The triangles are
/// unchanged, so a closed mesh stays closed. Identical output whatever the thread count.
/// Looks at `stop` before each pass; once it is raised the mesh is left as it was.
pub fn smooth(mesh: &mut Mesh, s: &Smoothing, stop: Stop) -> Result<(), Stopped> {
    let n = mesh.positions.len();
    let neighbours = Neighbours::from_triangles(&mesh.indices, n);
    let on_floor: Vec<bool> = match s.floor_y {
        Some(floor_y) => mesh.positions.iter().map(|p| p[1] <= floor_y + 1e-4).collect(),
        None => vec![false; n],
    };
    let mut current = mesh.positions.clone();
    let mut next = vec![[0.0f32; 3]; n];
    for _ in 0..s.iterations {
        stop.check()?;
        for factor in [s.lambda, s.mu] {
            next.par_iter_mut().enumerate().for_each(|(v, out)| {
                let p = current[v];
                let around = neighbours.of(v);
                if around.is_empty() {
                    *out = p;
                    return;
                }
                let mut sum = [0.0f32; 3];
                for &u in around {
                    let q = current[u as usize];
                    for k in 0..3 {
                        sum[k] += q[k];
                    }
                }
                let inv = 1.0 / around.len() as f32;
                *out = std::array::from_fn(|k| p[k] + factor * (sum[k] * inv - p[k]));
                if on_floor[v] {
                    out[1] = p[1];
                }
            });
            std::mem::swap(&mut current, &mut next);
        }
    }
    mesh.positions = current;
    recompute_normals(mesh);
    Ok(())
}

/// Each vertex's distinct neighbours along triangle edges, in increasing index order
/// (compressed sparse rows).
struct Neighbours {
    start: Vec<u32>,
    list: Vec<u32>,
}

impl Neighbours {
    fn from_triangles(indices: &[u32], vertex_count: usize) -> Self {
        // Fill with duplicates in triangle order, then sort and deduplicate each row in place.
        let mut start = vec![0u32; vertex_count + 1];
        for &i in indices {
            start[i as usize + 1] += 2;
        }
        for v in 0..vertex_count {
            start[v + 1] += start[v];
        }
        let mut fill = start.clone();
        let mut list = vec![0u32; indices.len() * 2];
        for t in indices.chunks_exact(3) {
            for (a, b, c) in [(t[0], t[1], t[2]), (t[1], t[2], t[0]), (t[2], t[0], t[1])] {
                let at = &mut fill[a as usize];
                list[*at as usize] = b;
                list[*at as usize + 1] = c;
                *at += 2;
            }
        }
        let mut write = 0usize;
        let mut compact_start = Vec::with_capacity(vertex_count + 1);
        compact_start.push(0u32);
        for v in 0..vertex_count {
            let (row_start, row_end) = (start[v] as usize, start[v + 1] as usize);
            list[row_start..row_end].sort_unstable();
            let mut last = None;
            // Rows only shrink, so writing at `write <= k` never overwrites an unread entry.
            for k in row_start..row_end {
                let u = list[k];
                if Some(u) != last && u as usize != v {
                    list[write] = u;
                    write += 1;
                    last = Some(u);
                }
            }
            compact_start.push(write as u32);
        }
        list.truncate(write);
        Self { start: compact_start, list }
    }

    fn of(&self, v: usize) -> &[u32] {
        &self.list[self.start[v] as usize..self.start[v + 1] as usize]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::isosurface::tests::consistently_wound;
    use crate::mesh::{extract_isosurface, ScalarField};

    /// A voxelized ball: 1.0 at samples within `radius` of the centre, else 0.0, meshed at 0.5.
    fn voxel_ball(n: usize, center: [f32; 3], radius: f32) -> Mesh {
        let mut values = vec![0.0f32; n * n * n];
        for y in 0..n {
            for z in 0..n {
                for x in 0..n {
                    let d = [x as f32 - center[0], y as f32 - center[1], z as f32 - center[2]];
                    if (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt() <= radius {
                        values[x + n * (z + n * y)] = 1.0;
                    }
                }
            }
        }
        extract_isosurface(
            &ScalarField { dims: [n; 3], origin_m: [0.0; 3], spacing_m: 1.0, values: &values },
            0.5,
            Stop::NEVER,
        )
        .unwrap()
    }

    fn rms_radius_error(mesh: &Mesh, center: [f32; 3], radius: f32) -> f64 {
        let sum: f64 = mesh
            .positions
            .iter()
            .map(|p| {
                let d = (0..3).map(|k| (p[k] - center[k]).powi(2)).sum::<f32>().sqrt();
                ((d - radius) as f64).powi(2)
            })
            .sum();
        (sum / mesh.positions.len() as f64).sqrt()
    }

    #[test]
    fn voxel_ball_gets_rounder_without_losing_volume() {
        let (center, radius) = ([12.3, 12.6, 11.8], 10.0);
        let mut mesh = voxel_ball(26, center, radius);
        let (before_rms, before_volume) = (rms_radius_error(&mesh, center, radius), mesh.signed_volume());
        smooth(&mut mesh, &Smoothing::default(), Stop::NEVER).unwrap();
        let (after_rms, after_volume) = (rms_radius_error(&mesh, center, radius), mesh.signed_volume());
        // Ten default iterations take about a third off the staircase (0.28 → 0.20 samples).
        assert!(after_rms < 0.8 * before_rms, "RMS radius error {before_rms} → {after_rms}");
        assert!((after_volume / before_volume - 1.0).abs() < 0.03, "volume {before_volume} → {after_volume}");
        assert!(mesh.is_closed() && consistently_wound(&mesh));
        mesh.check().unwrap();
    }

    #[test]
    fn floor_vertices_keep_their_height() {
        // A ball cut by the grid's bottom: its flat base sits half a sample below y = 0.
        let mut mesh = voxel_ball(20, [10.0, 2.0, 10.0], 8.0);
        let floor_y = -0.5;
        let base: Vec<usize> = (0..mesh.vertex_count()).filter(|&v| mesh.positions[v][1] <= floor_y + 1e-4).collect();
        assert!(base.len() > 50);
        let before = mesh.positions.clone();
        smooth(&mut mesh, &Smoothing { floor_y: Some(floor_y), ..Smoothing::default() }, Stop::NEVER).unwrap();
        for &v in &base {
            assert_eq!(mesh.positions[v][1], before[v][1]);
        }
        let moved = base.iter().filter(|&&v| mesh.positions[v] != before[v]).count();
        assert!(moved > 0, "base vertices slide on the floor");
        let rose = (0..mesh.vertex_count()).filter(|v| !base.contains(v)).any(|v| mesh.positions[v][1] != before[v][1]);
        assert!(rose);
    }

    #[test]
    fn same_positions_on_one_thread_or_two() {
        let mesh = voxel_ball(22, [10.5, 10.2, 11.0], 8.0);
        let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
        let two = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
        let run = |pool: &rayon::ThreadPool| {
            let mut m = mesh.clone();
            pool.install(|| smooth(&mut m, &Smoothing::default(), Stop::NEVER).unwrap());
            m
        };
        assert_eq!(run(&one), run(&two));
    }

    #[test]
    fn zero_iterations_only_recompute_normals() {
        let mut mesh = voxel_ball(12, [6.0; 3], 4.0);
        let before = mesh.clone();
        smooth(&mut mesh, &Smoothing { iterations: 0, ..Smoothing::default() }, Stop::NEVER).unwrap();
        assert_eq!(mesh, before);
    }
}
