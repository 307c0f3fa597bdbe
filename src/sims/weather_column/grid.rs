//! The voxel grid: indexing, the per-voxel state word, and which bedding layer a plane is in.

use super::params::WeatherColumnParams;

/// State of a voxel that is rock (weathering or not).
pub const ROCK: u16 = 0;
/// State of a voxel that never held rock. Any other state is the step that removed it.
pub const NEVER_ROCK: u16 = u16::MAX;

/// Offsets to the 26 voxels around one.
pub const NEIGHBOURS_26: [(i64, i64, i64); 26] = {
    let mut out = [(0, 0, 0); 26];
    let mut n = 0;
    let mut k = 0;
    while k < 27 {
        if k != 13 {
            out[n] = (k % 3 - 1, k / 9 - 1, (k / 3) % 3 - 1);
            n += 1;
        }
        k += 1;
    }
    out
};

/// How an exposed voxel touches air: how many of the 26 cells around it are air, and the sum
/// of their offsets (pointing out of the rock, the surface's normal at the scale of a voxel).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Exposure {
    pub air: u8,
    pub towards: [i8; 3],
}

/// Voxel `(x, y, z)` has its centre at `((x, y, z) + 0.5) × voxel_size_m`, Y up; index
/// `x + nx × (z + nz × y)`, so a horizontal plane is contiguous and planes go bottom to top.
#[derive(Clone, Debug, PartialEq)]
pub struct Grid {
    pub nx: usize,
    pub ny: usize,
    pub nz: usize,
    pub voxel_size_m: f32,
    /// No ground beneath: cells below the grid are air rather than rock.
    pub floating: bool,
}

impl Grid {
    pub fn new(params: &WeatherColumnParams) -> Self {
        Self {
            nx: params.grid.x as usize,
            ny: params.grid.y as usize,
            nz: params.grid.z as usize,
            voxel_size_m: params.voxel_size_m,
            floating: params.column.floating,
        }
    }

    pub fn len(&self) -> usize {
        self.nx * self.ny * self.nz
    }

    pub fn plane(&self) -> usize {
        self.nx * self.nz
    }

    pub fn index(&self, x: usize, y: usize, z: usize) -> usize {
        x + self.nx * (z + self.nz * y)
    }

    /// `(x, y, z)` of an index.
    pub fn coords(&self, i: usize) -> (usize, usize, usize) {
        let plane = self.plane();
        (i % self.nx, i / plane, (i % plane) / self.nx)
    }

    /// Whether a cell, possibly outside the grid, holds rock: outside is air, except the
    /// ground below the grid when the column stands on it.
    pub fn solid(&self, state: &[u16], x: i64, y: i64, z: i64) -> bool {
        if y < 0 {
            return !self.floating;
        }
        if x < 0 || z < 0 || x >= self.nx as i64 || y >= self.ny as i64 || z >= self.nz as i64 {
            return false;
        }
        state[self.index(x as usize, y as usize, z as usize)] == ROCK
    }

    /// How voxel `i` touches air among the 26 around it; `None` when it touches none. Only
    /// touching voxels weather: the paper centres its bubbles "on exposed voxels" (section 4).
    /// Voxels deeper within a bubble's reach keep their air count but do not decay until a
    /// removal exposes them.
    pub fn exposure(&self, state: &[u16], i: usize) -> Option<Exposure> {
        let (x, y, z) = self.coords(i);
        let (x, y, z) = (x as i64, y as i64, z as i64);
        let mut out = Exposure { air: 0, towards: [0; 3] };
        for &(dx, dy, dz) in &NEIGHBOURS_26 {
            if !self.solid(state, x + dx, y + dy, z + dz) {
                out.air += 1;
                for (t, d) in out.towards.iter_mut().zip([dx, dy, dz]) {
                    *t += d as i8;
                }
            }
        }
        (out.air > 0).then_some(out)
    }
}

/// The bedding layer of each plane of voxels, by the height of the voxels' centres; rock above
/// the last layer's top belongs to the last layer.
pub fn layer_of_plane(params: &WeatherColumnParams, grid: &Grid) -> Vec<u8> {
    (0..grid.ny)
        .map(|y| {
            let centre_m = (y as f32 + 0.5) * grid.voxel_size_m;
            let last = params.layers.len() - 1;
            params.layers.iter().position(|l| centre_m < l.top_m).unwrap_or(last) as u8
        })
        .collect()
}
