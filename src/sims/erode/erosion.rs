//! The erosion's state and one iteration of it: uplift, drainage, the stream-power step,
//! thermal sweeps, and the raise that keeps every land cell draining.

use rayon::prelude::*;
use sha2::{Digest, Sha256};

use super::flood::{fill, EPSILON_M};
use super::flow::Flow;
use super::grid::{outlets, Grid};
use super::params::ErodeParams;
use super::stream_power::StreamPower;
use super::thermal::Talus;
use crate::terrain::Heightfield;

/// The fluvial half of an iteration.
struct Fluvial {
    power: StreamPower,
    /// Metres of uplift per iteration on land.
    uplift_m: f64,
    flow: Flow,
    /// Each cell's net loss in the last iteration, m³ (negative where it gained).
    eroded: Vec<f64>,
    /// The heights the step solves into.
    next: Vec<f64>,
}

/// The thermal half of an iteration.
struct Relax {
    talus: Talus,
    sweeps: u32,
}

/// A terrain being eroded, iteration by iteration.
pub struct Erosion {
    pub grid: Grid,
    /// Heights, m; f64 while eroding, f32 only at the end (and in each checksum).
    pub heights: Vec<f64>,
    outlets: Vec<bool>,
    /// Rivers cut down to it, not to the sea floor.
    sea_level: f64,
    fluvial: Option<Fluvial>,
    relax: Option<Relax>,
    /// Ψ of the stream-power step, then the second buffer of the thermal sweeps.
    scratch: Vec<f64>,
    pub totals: Totals,
}

/// What the erosion moved, m³.
#[derive(Clone, Copy, Debug, Default)]
pub struct Totals {
    /// Filling the input's depressions before the first iteration.
    pub lake_fill_m3: f64,
    /// Sediment carried into outlets (sea and the grid's border).
    pub sediment_to_outlets_m3: f64,
    /// Raised to keep land cells draining after each iteration.
    pub drain_raise_m3: f64,
    pub iterations: u32,
}

impl Erosion {
    /// Start from `hf`: outlets fixed from its heights and `sea_level`, depressions filled
    /// (when the fluvial step is on).
    pub fn new(hf: &Heightfield, params: &ErodeParams) -> Self {
        let grid = Grid::new(hf.cols, hf.rows, f64::from(hf.cell_size_m));
        let mut heights: Vec<f64> = hf.heights_m.par_iter().map(|&h| f64::from(h)).collect();
        let outlets = outlets(&grid, &heights, f64::from(params.sea_level));
        let mut totals = Totals::default();
        let dt = params.time_step_years;
        let fluvial = params.hydraulic.on().map(|h| {
            // Before the large arrays, so the flood's heap never overlaps them.
            totals.lake_fill_m3 = fill(&grid, &mut heights, &outlets, EPSILON_M);
            Fluvial {
                power: StreamPower {
                    k_dt: h.k * dt,
                    m: h.m,
                    n: h.n,
                    deposition_g: h.deposition_g,
                    flow_exponent: h.flow_exponent,
                },
                uplift_m: h.uplift_m_per_yr * dt,
                flow: Flow::new(grid.cells()),
                eroded: vec![0.0; grid.cells()],
                next: vec![0.0; grid.cells()],
            }
        });
        let relax = params
            .thermal
            .on()
            .map(|t| Relax { talus: Talus::new(&grid, t.talus_angle_deg, t.rate), sweeps: t.sweeps });
        let scratch = vec![0.0; grid.cells()];
        Self { grid, heights, outlets, sea_level: f64::from(params.sea_level), fluvial, relax, scratch, totals }
    }

    /// One iteration.
    pub fn step(&mut self) {
        let grid = &self.grid;
        if let Some(f) = &mut self.fluvial {
            if f.uplift_m > 0.0 {
                let u = f.uplift_m;
                self.heights.par_iter_mut().zip(&self.outlets).for_each(|(h, &o)| {
                    if !o {
                        *h += u;
                    }
                });
            }
            // Outlets stand at least at the sea level while the step runs: the base level rivers
            // cut down to, not the sea floor below it. They never erode, so their entries of
            // `eroded` keep their real heights meanwhile.
            let sea = self.sea_level;
            self.heights.par_iter_mut().zip(&mut f.eroded).zip(&self.outlets).for_each(|((h, e), &o)| {
                if o {
                    *e = *h;
                    *h = h.max(sea);
                }
            });
            f.flow.route(grid, &self.heights, &self.outlets, &f.eroded, f.power.flow_exponent);
            self.totals.sediment_to_outlets_m3 +=
                self.outlets.iter().zip(&f.flow.sediment).filter(|(&o, _)| o).map(|(_, &v)| v.max(0.0)).sum::<f64>();
            f.power.psi(&f.flow.area, &mut self.scratch);
            f.power.solve(grid, &self.heights, &self.outlets, &f.flow, &self.scratch, &mut f.next);
            let area = grid.cell * grid.cell;
            f.eroded.par_iter_mut().zip(&mut f.next).zip(&self.heights).zip(&self.outlets).for_each(
                |(((e, n), &h), &o)| {
                    if o {
                        *n = *e;
                        *e = 0.0;
                    } else {
                        *e = area * (h - *n);
                    }
                },
            );
            std::mem::swap(&mut self.heights, &mut f.next);
        }
        if let Some(r) = &self.relax {
            for _ in 0..r.sweeps {
                r.talus.sweep(grid, &self.heights, &mut self.scratch, self.fluvial.is_some());
                std::mem::swap(&mut self.heights, &mut self.scratch);
            }
        }
        if let Some(f) = &self.fluvial {
            self.totals.drain_raise_m3 += f.flow.raise_to_drain(grid, &mut self.heights, EPSILON_M);
        }
        self.totals.iterations += 1;
    }

    /// The heights as a heightfield of `cell_size_m`.
    pub fn heightfield(&self) -> Heightfield {
        let mut hf = Heightfield::flat(self.grid.cols, self.grid.rows, self.grid.cell as f32, 0.0);
        hf.heights_m.par_iter_mut().zip(&self.heights).for_each(|(o, &h)| *o = h as f32);
        hf
    }

    /// The largest drop beyond the talus slope between neighbours, m (None without the thermal
    /// step).
    pub fn talus_excess(&self) -> Option<f64> {
        self.relax.as_ref().map(|r| r.talus.max_excess(&self.grid, &self.heights))
    }

    /// The first 16 hex digits of the sha256 of the heights as little-endian f32s: what the
    /// sequence records after each iteration.
    pub fn checksum(&self) -> String {
        hex::encode(&sha256_f32(self.heights.iter().map(|&h| h as f32))[..8])
    }
}

/// The sha256 of a heightfield's heights (little-endian f32s), hex: the input a sequence
/// names.
pub fn input_sha256(hf: &Heightfield) -> String {
    hex::encode(sha256_f32(hf.heights_m.iter().copied()))
}

/// The sha256 of f32s as little-endian bytes, hashed 4096 at a time.
fn sha256_f32(values: impl Iterator<Item = f32>) -> [u8; 32] {
    let mut hasher = Sha256::new();
    let mut buf = Vec::with_capacity(4 * 4096);
    let mut values = values.peekable();
    while values.peek().is_some() {
        buf.clear();
        buf.extend(values.by_ref().take(4096).flat_map(f32::to_le_bytes));
        hasher.update(&buf);
    }
    hasher.finalize().into()
}
