//! The erosion's state and one iteration of it: uplift, drainage, the stream-power step, the
//! sediment that reached the sea settled as deltas, hillslope transport, and the raise that
//! keeps every land cell draining — with every volume that enters, moves or leaves counted.

use rayon::prelude::*;
use sha2::{Digest, Sha256};

use super::flood::{fill, EPSILON_M};
use super::flow::Flow;
use super::grid::Grid;
use super::hillslope::Hillslope;
use super::marine::Marine;
use super::params::{BaseLevel, ErodeParams};
use super::stream_power::StreamPower;
use crate::terrain::Heightfield;

/// Most cell raises one iteration's pit repair makes before it floods the whole grid instead.
const PIT_RAISES_PER_CELL: usize = 4;

/// The fluvial half of an iteration.
struct Fluvial {
    power: StreamPower,
    /// Metres of uplift per iteration on land.
    uplift_m: f64,
    /// Painted uplift, metres per iteration on land, added to `uplift_m`.
    uplift_map: Option<Vec<f32>>,
    /// Painted erodibility: each cell's factor on k.
    k_factor: Option<Vec<f32>>,
    flow: Flow,
    /// Each cell's net loss in the last iteration, m³ (negative where it gained).
    eroded: Vec<f64>,
    /// The heights the step solves into.
    next: Vec<f64>,
    marine: Marine,
}

/// A terrain being eroded, iteration by iteration.
pub struct Erosion {
    pub grid: Grid,
    /// Heights, m; f64 while eroding, f32 only at the end (and in each checksum).
    pub heights: Vec<f64>,
    /// Where water leaves the land (the grid's border and the sea, at or below the sea level,
    /// by default), found again each iteration.
    outlets: Vec<bool>,
    base: Base,
    /// Rivers cut down to it, not to the sea floor.
    sea_level: f64,
    dt_years: f64,
    fluvial: Option<Fluvial>,
    hillslope: Option<Hillslope>,
    /// Ψ of the stream-power step.
    scratch: Vec<f64>,
    /// Kept cells: index, weight (0–1] and starting height.
    held: Vec<(u32, f32, f64)>,
    pub totals: Totals,
}

/// What the erosion moved, m³. Over a run, the volume under the terrain changes by
/// `lake_fill + drain_raise + uplift + unsettled + held − exported`: everything else only moved.
#[derive(Clone, Copy, Debug, Default)]
pub struct Totals {
    /// Filling the input's depressions before the first iteration.
    pub lake_fill_m3: f64,
    /// Sediment rivers carried into the sea and settled there.
    pub settled_in_sea_m3: f64,
    /// What left the grid: sediment carried into the border, creep and failure into it, and
    /// what a mouth's sea had no room for.
    pub exported_m3: f64,
    /// Raised to keep land cells draining after each iteration.
    pub drain_raise_m3: f64,
    /// Added by uplift.
    pub uplift_m3: f64,
    /// Net gains upstream of a mouth in one iteration (sediment settling from what an earlier
    /// iteration carried) that the mouth cannot hand back: counted, not taken from the sea.
    pub unsettled_m3: f64,
    /// Added (or, negative, taken) to hold kept areas at their starting heights.
    pub held_m3: f64,
    pub iterations: u32,
}

impl Erosion {
    /// Start from `hf`: depressions filled (when the fluvial step is on).
    pub fn new(hf: &Heightfield, params: &ErodeParams) -> Self {
        let grid = Grid::new(hf.cols, hf.rows, f64::from(hf.cell_size_m));
        let mut heights: Vec<f64> = hf.heights_m.par_iter().map(|&h| f64::from(h)).collect();
        let sea_level = f64::from(params.sea_level);
        let base = match params.base_level {
            BaseLevel::All => Base::BorderAndSea,
            BaseLevel::Sea => Base::Sea,
            // The lowest sample (the first of equals): the basin's floor.
            BaseLevel::None => {
                Base::Floor((0..heights.len()).fold(0, |best, i| if heights[i] < heights[best] { i } else { best }))
            }
        };
        let mut outlets = vec![false; grid.cells()];
        find_outlets(&grid, &heights, sea_level, base, &mut outlets);
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
                uplift_map: None,
                k_factor: None,
                flow: Flow::new(grid.cells()),
                eroded: vec![0.0; grid.cells()],
                next: vec![0.0; grid.cells()],
                marine: Marine::new(grid.cells()),
            }
        });
        let hillslope = params.thermal.on().map(|t| {
            let fixed_border = fluvial.is_some() && base == Base::BorderAndSea;
            Hillslope::new(&grid, t.diffusivity_m2_per_yr, t.talus_angle_deg, fixed_border)
        });
        let scratch = if fluvial.is_some() { vec![0.0; grid.cells()] } else { Vec::new() };
        Self {
            grid,
            heights,
            outlets,
            base,
            sea_level,
            dt_years: dt,
            fluvial,
            hillslope,
            scratch,
            held: Vec::new(),
            totals,
        }
    }

    /// Vary the fluvial step over the grid: each cell's factor on k, and each cell's painted
    /// uplift in m/yr (both on this grid; None leaves the request's single values).
    pub fn paint(&mut self, k_factor: Option<Vec<f32>>, uplift_m_per_yr: Option<Vec<f32>>) {
        let dt = self.dt_years;
        if let Some(f) = &mut self.fluvial {
            f.k_factor = k_factor;
            f.uplift_map = uplift_m_per_yr.map(|u| u.into_iter().map(|x| (f64::from(x) * dt) as f32).collect());
        }
    }

    /// Refuse a base level the terrain does not have: the sea only, on a terrain with no sea.
    pub fn check_base_level(&self) -> Result<(), crate::jobs::SimError> {
        if self.fluvial.is_some() && !self.outlets.iter().any(|&o| o) {
            return Err(crate::jobs::SimError::Invalid {
                field: "base_level".into(),
                message: format!(
                    "the terrain has no sample at or below sea_level ({} m) for its rivers to reach: lower the \
                     terrain or raise sea_level, or choose base_level all or none",
                    self.sea_level
                ),
            });
        }
        Ok(())
    }

    /// The uplift each land cell received over the run, m: one value when it is `uniform_m_per_yr`
    /// everywhere, else one a cell.
    pub fn uplift_total_m(&self, uniform_m_per_yr: f64) -> Vec<f32> {
        let years = self.dt_years * f64::from(self.totals.iterations);
        let n = f64::from(self.totals.iterations);
        match self.fluvial.as_ref().and_then(|f| f.uplift_map.as_ref()) {
            None => vec![(uniform_m_per_yr * years) as f32],
            Some(map) => map.iter().map(|&u| (uniform_m_per_yr * years + f64::from(u) * n) as f32).collect(),
        }
    }

    /// Hold the cells of `weights` (0–1 each, on this grid) at `start`'s heights: after every
    /// iteration a kept cell moves back towards its starting height by its weight.
    pub fn hold(&mut self, start: &Heightfield, weights: &[f32]) {
        self.held = weights
            .iter()
            .enumerate()
            .filter(|(_, &w)| w > 0.0)
            .map(|(i, &w)| (i as u32, w, f64::from(start.heights_m[i])))
            .collect();
    }

    /// One iteration.
    pub fn step(&mut self) {
        if self.fluvial.is_some() {
            find_outlets(&self.grid, &self.heights, self.sea_level, self.base, &mut self.outlets);
            self.totals.drain_raise_m3 += self.drain_pits();
            self.fluvial_step();
        }
        if let Some(h) = &mut self.hillslope {
            let rivers = self.fluvial.as_mut().map(|f| (&self.outlets[..], &mut f.eroded[..]));
            self.totals.exported_m3 += h.step(&self.grid, &mut self.heights, self.dt_years, rivers);
        }
        if let Some(f) = &self.fluvial {
            self.totals.drain_raise_m3 += f.flow.raise_to_drain(&self.grid, &mut self.heights, EPSILON_M);
        }
        if !self.held.is_empty() {
            let mut added = 0.0;
            for &(i, w, start) in &self.held {
                let h = &mut self.heights[i as usize];
                let next = if w >= 1.0 { start } else { *h + f64::from(w) * (start - *h) };
                added += next - *h;
                *h = next;
            }
            self.totals.held_m3 += added * self.grid.cell * self.grid.cell;
        }
        self.totals.iterations += 1;
    }

    /// Uplift, drainage, the stream-power step, and the sediment the last iteration sent to the
    /// outlets settled in the sea or sent off the grid.
    fn fluvial_step(&mut self) {
        let grid = &self.grid;
        let Some(f) = &mut self.fluvial else { return };
        if f.uplift_m > 0.0 || f.uplift_map.is_some() {
            let (u, map) = (f.uplift_m, f.uplift_map.as_deref());
            // Per row, then the rows in order: the same sum with any thread count.
            let rows: Vec<f64> = self
                .heights
                .par_chunks_mut(grid.cols)
                .zip(self.outlets.par_chunks(grid.cols))
                .enumerate()
                .map(|(r, (hs, os))| {
                    let mut raised = 0.0;
                    for (c, (h, &o)) in hs.iter_mut().zip(os).enumerate() {
                        if !o {
                            let du = u + map.map_or(0.0, |m| f64::from(m[r * grid.cols + c]));
                            *h += du;
                            raised += du;
                        }
                    }
                    raised
                })
                .collect();
            self.totals.uplift_m3 += rows.iter().sum::<f64>() * grid.cell * grid.cell;
        }
        // Outlets stand at least at the sea level while the step runs: the base level rivers
        // cut down to, not the sea floor below it. They never erode, so their entries of
        // `eroded` keep their real heights meanwhile.
        let sea = self.sea_level;
        // A cell that was land last iteration and is an outlet now (cut to the sea, or drowned
        // by a collapse) still holds what it lost then: it arrives where it stands.
        let own: Vec<(usize, f64)> = collect_arrivals(&self.outlets, &f.eroded);
        self.heights.par_iter_mut().zip(&mut f.eroded).zip(&self.outlets).for_each(|((h, e), &o)| {
            if o {
                *e = *h;
                *h = h.max(sea);
            }
        });
        f.flow.route(grid, &self.heights, &self.outlets, &f.eroded, f.power.flow_exponent);
        // What reaches each outlet, in index order: settled after the step, on the real heights.
        let mut arrivals: Vec<(usize, f64)> = collect_arrivals(&self.outlets, &f.flow.sediment);
        merge_arrivals(&mut arrivals, &own);
        f.power.psi(&f.flow.area, &self.outlets, grid.cell * grid.cell, f.k_factor.as_deref(), &mut self.scratch);
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
        deliver(grid, &mut self.heights, sea, self.base, &self.outlets, &mut f.marine, &arrivals, &mut self.totals);
    }

    /// Carry the last iteration's sediment to the outlets and settle it, so that nothing is left
    /// in transit when the run ends.
    pub fn flush(&mut self) {
        let grid = &self.grid;
        let Some(f) = &mut self.fluvial else { return };
        find_outlets(grid, &self.heights, self.sea_level, self.base, &mut self.outlets);
        let own = collect_arrivals(&self.outlets, &f.eroded);
        f.flow.route(grid, &self.heights, &self.outlets, &f.eroded, f.power.flow_exponent);
        let mut arrivals = collect_arrivals(&self.outlets, &f.flow.sediment);
        merge_arrivals(&mut arrivals, &own);
        f.eroded.iter_mut().for_each(|e| *e = 0.0);
        let (sea, base) = (self.sea_level, self.base);
        deliver(grid, &mut self.heights, sea, base, &self.outlets, &mut f.marine, &arrivals, &mut self.totals);
    }

    /// Raise every land cell that has no lower neighbour (land the hillslope raised from the
    /// sea, say) until it drains: a few local raises, or a flood of the whole grid when there
    /// are many. Returns the volume added, m³.
    fn drain_pits(&mut self) -> f64 {
        let (grid, h, outlets) = (&self.grid, &mut self.heights, &self.outlets);
        let cols = grid.cols;
        let pit = |h: &[f64], i: usize| !outlets[i] && grid.lowest_neighbour(h, i) >= h[i];
        let frozen: &[f64] = h;
        let mut stack: Vec<usize> = (0..grid.rows)
            .into_par_iter()
            .flat_map_iter(|r| (r * cols..(r + 1) * cols).filter(move |&i| pit(frozen, i)))
            .collect();
        if stack.is_empty() {
            return 0.0;
        }
        stack.reverse();
        let before: f64 = h.iter().sum();
        let mut budget = PIT_RAISES_PER_CELL * grid.cells();
        while let Some(i) = stack.pop() {
            if !pit(h, i) {
                continue;
            }
            if budget == 0 {
                // Too deep for local raises: flood (it raises only what does not drain).
                fill(grid, h, outlets, EPSILON_M);
                break;
            }
            budget -= 1;
            h[i] = grid.lowest_neighbour(h, i) + EPSILON_M;
            stack.extend((0..8).rev().filter_map(|k| grid.neighbour(i, k)).filter(|&n| !outlets[n]));
        }
        (h.iter().sum::<f64>() - before) * grid.cell * grid.cell
    }

    /// The heights as a heightfield of `cell_size_m`.
    pub fn heightfield(&self) -> Heightfield {
        let mut hf = Heightfield::flat(self.grid.cols, self.grid.rows, self.grid.cell as f32, 0.0);
        hf.heights_m.par_iter_mut().zip(&self.heights).for_each(|(o, &h)| *o = h as f32);
        hf
    }

    /// The share of faces steeper than the talus slope beyond the failure's tolerance (None
    /// without hillslope transport).
    pub fn steep_share(&self) -> Option<f64> {
        self.hillslope.as_ref().map(|h| h.steep_share(&self.grid, &self.heights))
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

/// Where water leaves the land, from the request's `base_level`.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Base {
    /// The grid's border and every cell at or below the sea level.
    BorderAndSea,
    /// Every cell at or below the sea level.
    Sea,
    /// This one cell, the lowest of the input: a closed basin's floor.
    Floor(usize),
}

/// The outlets of `base`: water that reaches one leaves the land, and the fluvial step does not
/// cut it.
fn find_outlets(grid: &Grid, heights: &[f64], sea_level: f64, base: Base, outlets: &mut [bool]) {
    let cols = grid.cols;
    outlets.par_chunks_mut(cols).enumerate().for_each(|(r, row)| {
        for (c, o) in row.iter_mut().enumerate() {
            let i = r * cols + c;
            *o = match base {
                Base::BorderAndSea => heights[i] <= sea_level || grid.on_border(i),
                Base::Sea => heights[i] <= sea_level,
                Base::Floor(floor) => i == floor,
            };
        }
    });
}

/// The sediment that reached each outlet, m³, in index order (nonzero only).
fn collect_arrivals(outlets: &[bool], sediment: &[f64]) -> Vec<(usize, f64)> {
    outlets.iter().zip(sediment).enumerate().filter(|(_, (&o, &v))| o && v != 0.0).map(|(i, (_, &v))| (i, v)).collect()
}

/// Add `more` into `arrivals` (both in index order), keeping index order.
fn merge_arrivals(arrivals: &mut Vec<(usize, f64)>, more: &[(usize, f64)]) {
    if more.is_empty() {
        return;
    }
    arrivals.extend_from_slice(more);
    arrivals.sort_by_key(|&(i, _)| i);
    arrivals.dedup_by(|b, a| {
        if a.0 == b.0 {
            a.1 += b.1;
            true
        } else {
            false
        }
    });
}

/// Settle each arrival in the sea at its outlet (a delta), on a closed basin's floor (a level
/// lake bed), or send it off the grid at the border; a negative arrival (a net gain upstream)
/// is counted, not taken back.
#[allow(clippy::too_many_arguments)]
fn deliver(
    grid: &Grid,
    heights: &mut [f64],
    sea_level: f64,
    base: Base,
    outlets: &[bool],
    marine: &mut Marine,
    arrivals: &[(usize, f64)],
    totals: &mut Totals,
) {
    for &(i, v) in arrivals {
        if v < 0.0 {
            totals.unsettled_m3 -= v;
        } else if let Base::Floor(_) = base {
            fill_basin(grid, heights, i, v);
        } else if grid.on_border(i) {
            totals.exported_m3 += v;
        } else {
            let left = marine.settle(grid, heights, |n| outlets[n], sea_level, i, v);
            totals.settled_in_sea_m3 += v - left;
            totals.exported_m3 += left;
        }
    }
}

/// Spread `volume` m³ over the basin around `floor` as a level bed: the cells the water would
/// reach first (lowest first, outwards from the floor) are raised to the one level that holds
/// the volume.
fn fill_basin(grid: &Grid, heights: &mut [f64], floor: usize, volume: f64) {
    use std::cmp::Reverse;
    use std::collections::BinaryHeap;
    let depth = volume / (grid.cell * grid.cell);
    let mut seen = std::collections::HashSet::from([floor]);
    let mut heap = BinaryHeap::from([super::flood::key(heights[floor], floor)]);
    // The cells taken so far and the sum of their heights: they fill to level L with
    // n·L − sum of depth; the next cell's height caps L until the depth runs out.
    let (mut taken, mut sum) = (Vec::new(), 0.0);
    let mut level = heights[floor];
    while let Some(Reverse((_, c))) = heap.pop() {
        let c = c as usize;
        let next = heights[c];
        if !taken.is_empty() && next * taken.len() as f64 - sum >= depth {
            break;
        }
        taken.push(c);
        sum += next;
        level = (depth + sum) / taken.len() as f64;
        for k in 0..8 {
            if let Some(n) = grid.neighbour(c, k) {
                if seen.insert(n) {
                    heap.push(super::flood::key(heights[n], n));
                }
            }
        }
    }
    for c in taken {
        heights[c] = level;
    }
}
