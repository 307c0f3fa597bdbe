//! Fractal Brownian motion (fBm) terrain: `octaves` layers of Perlin gradient noise, each at
//! twice the frequency (lacunarity 2) and `roughness` times the amplitude (persistence) of the
//! one before.
//!
//! Conventions:
//! - The first octave has one noise-lattice cell across the whole grid, so the largest
//!   features span it. Noise is sampled in grid-index space, so the same `seed` and `size` give
//!   the same shape at any `cell_size`; only the horizontal scale changes.
//! - Heights are normalised by the octaves' theoretical amplitude sum, not by the samples'
//!   extremes: every height is a pure function of (parameters, sample index), and plain terrain
//!   lies in `[0, relief]` metres. Typical fBm fills the middle of that range, not all of it.
//! - `island`: a smooth radial falloff, warped by the noise, turns the middle into land and
//!   sinks the edges to a sea floor: heights lie in `[-0.2·relief, relief]`, every edge sample
//!   is at or below `-0.15·relief` and the centre at or above `0.1·relief`.
//! - Per-octave Perlin seeds, offsets and rotations come from a SplitMix64 stream of the u64
//!   seed, and rows are computed independently, so the output is identical for any number of
//!   threads (and uses no platform `sin`/`cos`, so it is the same on every machine).
//! - The noise is the `noise` crate's Perlin (its permutation tables, gradients, fade curve and
//!   scaling), evaluated by [`Perlin2`] without the crate's per-call overhead: bit-identical
//!   values at about a third of the cost.

use noise::permutationtable::{NoiseHasher, PermutationTable};
use rayon::prelude::*;

use super::{FractalParams, Heightfield};

/// Noise-lattice cells of the first octave across the grid.
const BASE_CELLS_ACROSS: f64 = 1.0;
/// More octaves than this would be finer than a sample on any grid (validation allows 16).
const MAX_OCTAVES: u32 = 32;
/// Frequency ratio between successive octaves.
const LACUNARITY: f64 = 2.0;
/// Perlin lattices in the `noise` crate repeat every 256 cells; octave offsets fall in one period.
const LATTICE_PERIOD: f64 = 256.0;

/// Island shaping. Heights are fractions of the relief, radii fractions of the grid's
/// half-width (1 = the middle of an edge).
const ISLAND_SEA_FLOOR: f64 = -0.2;
/// The sea floor rises by up to this much with the noise, so it is not dead flat.
const ISLAND_SEA_FLOOR_TEXTURE: f64 = 0.05;
/// Land is `ISLAND_LAND_BASE + (1 - ISLAND_LAND_BASE)·c`, c the contrast-stretched noise.
const ISLAND_LAND_BASE: f64 = 0.1;
/// fBm normalised by its theoretical amplitude rarely leaves [0.25, 0.75]; land stretches it.
const ISLAND_LAND_CONTRAST: f64 = 2.0;
/// The land share falls from 1 at this warped radius…
const ISLAND_PLATEAU_RADIUS: f64 = 0.2;
/// …to 0 at this one.
const ISLAND_SHORE_RADIUS: f64 = 0.95;
/// How strongly the noise warps the radius: high ground pushes the coast out (headlands), low
/// ground pulls it in (bays).
const ISLAND_COAST_WARP: f64 = 1.2;
/// Whatever the warp, the land share reaches 0 between this radius and the edge.
const ISLAND_OPEN_SEA_RADIUS: f64 = 0.8;

/// One layer of the fBm sum.
#[derive(Clone, Copy)]
struct Octave {
    noise: Perlin2,
    /// This octave's share of the amplitude sum (the shares' magnitudes add to 1).
    weight: f64,
    /// Lattice cells per grid sample.
    frequency: f64,
    /// Rotation of the sample grid against the lattice (unit vector), against axis-aligned
    /// artefacts lining up between octaves.
    cos: f64,
    sin: f64,
    offset: [f64; 2],
}

/// Generate an fBm heightfield: `size × size` samples, `cell_size` metres apart, by the
/// requested generator version.
///
/// Parameters are expected to be validated (`size² ≤` the grid cap, 1 to 16 octaves,
/// roughness in (0, 1], a known `generator`); octaves beyond 32 are ignored.
pub fn generate_fractal(p: &FractalParams) -> Heightfield {
    // One arm per released version; a new version is a new arm beside the old, never an edit
    // of one (the golden hashes in the tests below would fail). Validation admits only
    // FRACTAL_GENERATORS.
    #[allow(clippy::match_single_binding)]
    match p.generator {
        _ => generator_1(p),
    }
}

/// Version 1: the generator of every job before versions were named.
fn generator_1(p: &FractalParams) -> Heightfield {
    let size = p.size as usize;
    let cell_size_m = p.cell_size;
    if size == 0 {
        return Heightfield { cols: 0, rows: 0, cell_size_m, heights_m: Vec::new() };
    }
    let octaves = octaves(p.seed, p.octaves.clamp(1, MAX_OCTAVES), p.roughness as f64, size);
    let relief = p.relief as f64;
    let span = (size - 1).max(1) as f64;

    let mut heights_m = vec![0.0f32; size * size];
    heights_m.par_chunks_mut(size).enumerate().for_each(|(row, out)| {
        let z = row as f64;
        for (col, h) in out.iter_mut().enumerate() {
            let x = col as f64;
            // fbm ∈ [-1, 1] (Perlin output is clamped to it), u ∈ [0, 1].
            let u = 0.5 + 0.5 * fbm(&octaves, x, z);
            let height = if p.island {
                let dx = 2.0 * x / span - 1.0;
                let dz = 2.0 * z / span - 1.0;
                island_height(u, (dx * dx + dz * dz).sqrt())
            } else {
                u
            };
            *h = (height * relief) as f32;
        }
    });
    Heightfield { cols: size, rows: size, cell_size_m, heights_m }
}

fn octaves(seed: u64, count: u32, roughness: f64, size: usize) -> Vec<Octave> {
    let mut rng = SplitMix64(seed);
    let base_frequency = BASE_CELLS_ACROSS / (size - 1).max(1) as f64;
    // Running products rather than `powi`, whose rounding may differ between builds.
    let raw: Vec<(f64, f64)> = (0..count)
        .scan((1.0, base_frequency), |state, _| {
            let this = *state;
            *state = (state.0 * roughness, state.1 * LACUNARITY);
            Some(this)
        })
        .collect();
    // Absolute values: the weights' magnitudes sum to 1 whatever the roughness, so the sum of
    // octaves stays in [-1, 1].
    let total: f64 = raw.iter().map(|(amplitude, _)| amplitude.abs()).sum();
    raw.iter()
        .map(|&(amplitude, frequency)| {
            let noise = Perlin2::new((rng.next() >> 32) as u32);
            // Offsets use all 64 bits of the seed, so seeds equal in their Perlin u32 still differ.
            let offset = [rng.unit() * LATTICE_PERIOD, rng.unit() * LATTICE_PERIOD];
            let (cos, sin) = rng.direction();
            Octave { noise, weight: if total > 0.0 { amplitude / total } else { 0.0 }, frequency, cos, sin, offset }
        })
        .collect()
}

/// The weighted octave sum at a sample, in [-1, 1].
#[inline]
fn fbm(octaves: &[Octave], col: f64, row: f64) -> f64 {
    let mut sum = 0.0;
    for o in octaves {
        let x = col * o.frequency;
        let z = row * o.frequency;
        let point = [x * o.cos - z * o.sin + o.offset[0], x * o.sin + z * o.cos + o.offset[1]];
        sum += o.weight * o.noise.get(point[0], point[1]);
    }
    sum
}

/// `noise::Perlin`'s 2-D noise (noise 0.9, `core::perlin::perlin_2d`) re-stated for speed:
/// the crate evaluates it through generic vector types, slice hashing and checked numeric
/// casts, ~2.5–3.5× slower on the octaves' sample points (`time_a_1025_grid`); this is the
/// same arithmetic in the same order, so values are bit-identical
/// (`perlin2_matches_the_noise_crate` checks it), and it cannot panic on any input.
#[derive(Clone, Copy)]
struct Perlin2 {
    /// The crate's permutation for the seed.
    perm: [u8; 256],
}

impl Perlin2 {
    fn new(seed: u32) -> Self {
        let table = PermutationTable::new(seed);
        let mut perm = [0u8; 256];
        for (i, p) in perm.iter_mut().enumerate() {
            // A one-coordinate hash is a plain table lookup.
            *p = table.hash(&[i as isize]) as u8;
        }
        Self { perm }
    }

    /// The crate's `PermutationTable::hash(&[x, y])`.
    #[inline(always)]
    fn hash(&self, x: isize, y: isize) -> usize {
        self.perm[self.perm[(x & 0xff) as usize] as usize ^ (y & 0xff) as usize] as usize
    }

    #[inline(always)]
    fn get(&self, x: f64, y: f64) -> f64 {
        // 1 / (sqrt(N) / 2) for N = 2: scales the unscaled range to (-1, 1).
        const SCALE_FACTOR: f64 = 2.0 / std::f64::consts::SQRT_2;
        let (cx, cy) = (lattice_floor(x), lattice_floor(y));
        let (dx, dy) = (x - cx as f64, y - cy as f64);
        let gradient = |ox: isize, oy: isize| {
            let (px, py) = (dx - ox as f64, dy - oy as f64);
            match self.hash(cx + ox, cy + oy) & 0b11 {
                0 => px + py,
                1 => -px + py,
                2 => px - py,
                _ => -px - py,
            }
        };
        let g00 = gradient(0, 0);
        let g10 = gradient(1, 0);
        let g01 = gradient(0, 1);
        let g11 = gradient(1, 1);
        let (qx, qy) = (quintic(dx), quintic(dy));
        let result = lerp(lerp(g00, g01, qy), lerp(g10, g11, qy), qx) * SCALE_FACTOR;
        result.clamp(-1.0, 1.0)
    }
}

/// The crate's `floor_to_isize`: whole numbers ≤ 0 go to the cell below (the value is the same
/// either way; matching it keeps the bits the same). Saturates instead of panicking.
#[inline(always)]
fn lattice_floor(v: f64) -> isize {
    if v <= 0.0 {
        (v as isize).saturating_sub(1)
    } else {
        v as isize
    }
}

#[inline(always)]
fn quintic(t: f64) -> f64 {
    let t = t.clamp(0.0, 1.0);
    t * t * t * (t * (t * 6.0 - 15.0) + 10.0)
}

/// The crate's `interpolate::linear`, operand order included.
#[inline(always)]
fn lerp(a: f64, b: f64, alpha: f64) -> f64 {
    b * alpha + a * (1.0 - alpha)
}

/// Island height as a fraction of relief, from the fBm value `u` ∈ [0, 1] and the distance `d`
/// from the centre (1 at the middle of an edge): a blend of land and sea floor by a radial
/// land share that is 1 at the centre and 0 from the edges outward, so heights stay in
/// `[ISLAND_SEA_FLOOR, 1]`, the centre is at least `ISLAND_LAND_BASE` and the edges at most
/// `ISLAND_SEA_FLOOR + ISLAND_SEA_FLOOR_TEXTURE`.
fn island_height(u: f64, d: f64) -> f64 {
    let warped = d * (1.0 + ISLAND_COAST_WARP * (0.5 - u));
    let land_share = (1.0 - smoothstep(ISLAND_PLATEAU_RADIUS, ISLAND_SHORE_RADIUS, warped))
        * (1.0 - smoothstep(ISLAND_OPEN_SEA_RADIUS, 1.0, d));
    let contrast = (0.5 + ISLAND_LAND_CONTRAST * (u - 0.5)).clamp(0.0, 1.0);
    let land = ISLAND_LAND_BASE + (1.0 - ISLAND_LAND_BASE) * contrast;
    let sea = ISLAND_SEA_FLOOR + ISLAND_SEA_FLOOR_TEXTURE * u;
    land_share * land + (1.0 - land_share) * sea
}

fn smoothstep(edge0: f64, edge1: f64, x: f64) -> f64 {
    let t = ((x - edge0) / (edge1 - edge0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// SplitMix64 (Steele, Lea & Flood 2014): a tiny, well-mixed stream for deriving sub-seeds.
struct SplitMix64(u64);

impl SplitMix64 {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// A uniformly distributed unit vector, by rejection (sqrt is exactly rounded everywhere).
    fn direction(&mut self) -> (f64, f64) {
        loop {
            let a = 2.0 * self.unit() - 1.0;
            let b = 2.0 * self.unit() - 1.0;
            let r2 = a * a + b * b;
            if r2 > 1e-6 && r2 <= 1.0 {
                let r = r2.sqrt();
                return (a / r, b / r);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use noise::{NoiseFn, Perlin};

    use super::*;

    #[test]
    fn perlin2_matches_the_noise_crate() {
        let mut rng = SplitMix64(99);
        for seed in [0u32, 1, 7, 0xDEAD_BEEF, u32::MAX] {
            let reference = Perlin::new(seed);
            let fast = Perlin2::new(seed);
            let mut points = vec![[0.0, 0.0], [-0.0, 3.0], [-1.0, -2.0], [255.0, 256.0], [1e6 + 0.5, -3e5 - 0.25]];
            points.extend((0..2000).map(|_| [(rng.unit() - 0.5) * 1200.0, (rng.unit() - 0.5) * 1200.0]));
            for [x, y] in points {
                assert_eq!(fast.get(x, y).to_bits(), reference.get([x, y]).to_bits(), "seed {seed} at ({x}, {y})");
            }
        }
    }

    fn params(size: u32, seed: u64, island: bool) -> FractalParams {
        FractalParams { size, seed, island, ..FractalParams::default() }
    }

    #[test]
    fn the_same_seed_gives_the_same_heights_and_another_seed_differs() {
        let a = generate_fractal(&params(129, 7, false));
        let b = generate_fractal(&params(129, 7, false));
        let c = generate_fractal(&params(129, 8, false));
        assert_eq!(a, b);
        let differing = a.heights_m.iter().zip(&c.heights_m).filter(|(x, y)| x != y).count();
        assert!(differing > a.heights_m.len() * 9 / 10, "only {differing} samples differ");
        // Seeds that agree in their low 32 bits still give different terrain.
        let d = generate_fractal(&params(129, 7 + (1 << 32), false));
        assert_ne!(a.heights_m, d.heights_m);
    }

    #[test]
    fn output_does_not_depend_on_the_thread_count() {
        let p = FractalParams { octaves: 10, island: true, ..params(200, 42, true) };
        let many = generate_fractal(&p);
        let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap().install(|| generate_fractal(&p));
        assert_eq!(many, one);
    }

    #[test]
    fn heights_stay_in_zero_to_relief_and_use_a_good_part_of_it() {
        for seed in 0..8 {
            let p = FractalParams { relief: 250.0, roughness: 0.7, ..params(97, seed, false) };
            let hf = generate_fractal(&p);
            let (lo, hi) = hf.min_max();
            assert!(lo >= 0.0 && hi <= 250.0, "seed {seed}: {lo}..{hi}");
            assert!(hi - lo > 0.2 * 250.0, "seed {seed}: flat terrain {lo}..{hi}");
        }
    }

    #[test]
    fn an_island_has_sea_at_every_edge_and_land_in_the_middle() {
        for seed in 0..8 {
            let relief = 100.0;
            let size = 129;
            let hf = generate_fractal(&FractalParams { relief, roughness: 0.6, ..params(size, seed, true) });
            let n = size as usize;
            let (lo, hi) = hf.min_max();
            assert!(lo >= -0.2 * relief && hi <= relief, "seed {seed}: {lo}..{hi}");
            for i in 0..n {
                for (c, r) in [(i, 0), (i, n - 1), (0, i), (n - 1, i)] {
                    assert!(hf.get(c, r) <= -0.15 * relief, "seed {seed}: edge ({c}, {r}) at {}", hf.get(c, r));
                }
            }
            assert!(hf.get(n / 2, n / 2) >= 0.1 * relief, "seed {seed}: centre at {}", hf.get(n / 2, n / 2));
            let land = hf.heights_m.iter().filter(|&&h| h > 0.0).count();
            assert!(land > n * n / 8 && land < n * n * 3 / 4, "seed {seed}: {land} land samples");
        }
    }

    #[test]
    fn island_shaping_keeps_its_documented_bounds_for_any_noise_value() {
        for i in 0..=100 {
            let u = i as f64 / 100.0;
            assert!(island_height(u, 0.0) >= ISLAND_LAND_BASE, "centre at u = {u}");
            for d in [1.0, 1.2, std::f64::consts::SQRT_2] {
                assert!(island_height(u, d) <= ISLAND_SEA_FLOOR + ISLAND_SEA_FLOOR_TEXTURE, "edge at u = {u}");
            }
            for j in 0..=150 {
                let h = island_height(u, j as f64 / 100.0);
                assert!((ISLAND_SEA_FLOOR..=1.0).contains(&h), "u = {u}, d = {}: {h}", j as f64 / 100.0);
            }
        }
    }

    #[test]
    fn size_and_cell_size_are_respected_and_cell_size_only_scales() {
        let fine = generate_fractal(&FractalParams { cell_size: 0.5, ..params(65, 3, false) });
        let coarse = generate_fractal(&FractalParams { cell_size: 4.0, ..params(65, 3, false) });
        assert_eq!((fine.cols, fine.rows, fine.heights_m.len()), (65, 65, 65 * 65));
        assert_eq!(fine.cell_size_m, 0.5);
        assert_eq!(coarse.cell_size_m, 4.0);
        assert_eq!(fine.width_m(), 32.0);
        assert_eq!(fine.heights_m, coarse.heights_m);
    }

    #[test]
    fn more_roughness_gives_a_rougher_surface() {
        let mean_step = |roughness: f32| {
            let hf = generate_fractal(&FractalParams { roughness, ..params(129, 11, false) });
            let steps = (0..hf.rows).flat_map(|r| (1..hf.cols).map(move |c| (c, r)));
            steps.clone().map(|(c, r)| (hf.get(c, r) - hf.get(c - 1, r)).abs()).sum::<f32>() / steps.count() as f32
        };
        assert!(mean_step(0.8) > 2.0 * mean_step(0.3));
    }

    #[test]
    fn degenerate_sizes_do_not_panic() {
        assert!(generate_fractal(&params(0, 1, false)).heights_m.is_empty());
        assert_eq!(generate_fractal(&params(1, 1, true)).heights_m.len(), 1);
        let flat = generate_fractal(&FractalParams { relief: 0.0, ..params(9, 1, false) });
        assert!(flat.heights_m.iter().all(|&h| h == 0.0));
    }
}

/// Golden hashes: every released generator version, pinned. A failure here means a stored
/// sequence would no longer replay to its terrain — add a new version instead of editing one.
#[cfg(test)]
mod golden {
    use super::*;
    use sha2::{Digest, Sha256};

    /// sha256 of the heights as little-endian f32, row by row.
    pub(crate) fn heights_sha256(hf: &Heightfield) -> String {
        let mut sha = Sha256::new();
        for h in &hf.heights_m {
            sha.update(h.to_le_bytes());
        }
        hex::encode(sha.finalize())
    }

    fn version_1(json: serde_json::Value) -> String {
        let p: FractalParams = serde_json::from_value(json).unwrap();
        assert_eq!(p.generator, 1, "absent means version 1");
        heights_sha256(&generate_fractal(&p))
    }

    #[test]
    fn version_1_gives_the_heights_it_always_gave() {
        let cases = [
            (serde_json::json!({}), "a7e3ab9881cf79d5621fa760647a860724e807a7f0b732cb062180890cd70af7"),
            (
                serde_json::json!({"size": 129, "seed": 3, "island": true, "relief": 60.0}),
                "36b69d258aefab0337b4f7f0374eae32bfebe8e6fa484b2ac31067694086bb9a",
            ),
            (
                serde_json::json!({"size": 65, "octaves": 3, "roughness": 0.8, "seed": 123456789012_u64}),
                "baa6cec18d7bb13955bf551f461d6db1765088dce343fd41d612a26022a48fff",
            ),
            (
                serde_json::json!({"size": 33, "cell_size": 2.5, "octaves": 16, "roughness": 1.0, "generator": 1}),
                "9193946b1352f21cbe049ad350f0495975e7ddfdff1561bc6399c45a8e36bd3e",
            ),
            (
                serde_json::json!({"size": 2, "seed": 0}),
                "fd4c31340d77cc93b8cb88f77d1396c65d92fcf6be50eec390dc6629d26edb6c",
            ),
        ];
        let got: Vec<(String, String)> = cases.iter().map(|(j, _)| (j.to_string(), version_1(j.clone()))).collect();
        let want: Vec<(String, String)> = cases.iter().map(|(j, w)| (j.to_string(), w.to_string())).collect();
        assert_eq!(got, want);
    }
}
