//! Resistance to weathering: the layer's value varied by coherent noise within the layer
//! (paper section 3: "less extreme variations exist within each layer").

use noise::{NoiseFn, Perlin};

use super::params::WeatherColumnParams;

#[derive(Clone)]
pub struct ResistanceField {
    layers: Vec<LayerResistance>,
    voxel_size_m: f32,
}

#[derive(Clone)]
struct LayerResistance {
    resistance: f32,
    amplitude: f32,
    frequency_per_m: f64,
    noise: Perlin,
}

impl ResistanceField {
    /// Each layer draws its own noise from the job's seed.
    pub fn new(params: &WeatherColumnParams, seed: u64) -> Self {
        let layers = params
            .layers
            .iter()
            .enumerate()
            .map(|(i, l)| LayerResistance {
                resistance: l.resistance,
                amplitude: l.noise.amplitude,
                frequency_per_m: l.noise.frequency_per_m as f64,
                noise: Perlin::new(layer_noise_seed(seed, i)),
            })
            .collect();
        Self { layers, voxel_size_m: params.voxel_size_m }
    }

    /// Resistance at a point in metres within `layer`.
    pub fn at_m(&self, layer: u8, p: [f32; 3]) -> f32 {
        let l = &self.layers[layer as usize];
        if l.amplitude == 0.0 || l.frequency_per_m == 0.0 {
            return l.resistance;
        }
        let n = l.noise.get(lattice(p, l.frequency_per_m)).clamp(-1.0, 1.0) as f32;
        l.resistance * (1.0 + l.amplitude * n)
    }

    /// Resistance of voxel `(x, y, z)` in `layer`, at its centre.
    pub fn at_voxel(&self, layer: u8, x: usize, y: usize, z: usize) -> f32 {
        let s = self.voxel_size_m;
        self.at_m(layer, [(x as f32 + 0.5) * s, (y as f32 + 0.5) * s, (z as f32 + 0.5) * s])
    }

    /// Lowest and highest resistance any voxel can have.
    pub fn range(&self) -> (f32, f32) {
        let lo = self.layers.iter().map(|l| l.resistance * (1.0 - l.amplitude)).fold(f32::INFINITY, f32::min);
        let hi = self.layers.iter().map(|l| l.resistance * (1.0 + l.amplitude)).fold(0.0, f32::max);
        (lo, hi)
    }
}

/// Where a point in metres reads the noise: scaled by the frequency, turned by a fixed rotation
/// (1 radian about (1, 2, 3)/√14) and offset by golden-ratio fractions. Gradient noise is zero
/// at its integer lattice; unrotated, a frequency of whole cycles per voxel put every voxel
/// centre there and silently removed all in-layer variation.
fn lattice(p: [f32; 3], frequency: f64) -> [f64; 3] {
    const R: [[f64; 3]; 3] = [
        [0.573_137_855_448_987, -0.609_006_642_137_393, 0.548_291_809_608_600],
        [0.740_348_840_460_782, 0.671_644_504_191_528, -0.027_879_282_947_946],
        [-0.351_278_512_123_517, 0.421_905_877_918_112, 0.835_822_252_095_764],
    ];
    const OFFSET: [f64; 3] = [0.381_966_011_250_105, 0.618_033_988_749_895, 0.236_067_977_499_790];
    let q = p.map(|c| c as f64 * frequency);
    [0, 1, 2].map(|i| R[i][0] * q[0] + R[i][1] * q[1] + R[i][2] * q[2] + OFFSET[i])
}

/// A 32-bit noise seed per (job seed, layer): splitmix64 of the pair.
fn layer_noise_seed(seed: u64, layer: usize) -> u32 {
    let mut z = seed ^ (layer as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    (z ^ (z >> 31)) as u32
}
