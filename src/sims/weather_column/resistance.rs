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
        let f = l.frequency_per_m;
        let n = l.noise.get([p[0] as f64 * f, p[1] as f64 * f, p[2] as f64 * f]).clamp(-1.0, 1.0) as f32;
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

/// A 32-bit noise seed per (job seed, layer): splitmix64 of the pair.
fn layer_noise_seed(seed: u64, layer: usize) -> u32 {
    let mut z = seed ^ (layer as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    (z ^ (z >> 31)) as u32
}
