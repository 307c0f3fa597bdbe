//! The erosion's own maps — where water runs, where material went and where it settled — and
//! the splat map weights made from them.

use rayon::prelude::*;

use super::flow::Flow;
use super::grid::{outlets, Grid};
use crate::export::{scalar_png16, Artifact};
use crate::terrain::Heightfield;

/// Metres of deposit where sediment starts to show in the splat map's material channel, and
/// where it is all sediment.
const SEDIMENT_M: (f64, f64) = (0.05, 0.5);
/// Shares of the deepest wear where bare rock starts to show, and where it is all rock: the
/// most deeply cut valleys and gorges, whatever the terrain's scale (a rule in metres would
/// paint a whole island lowered by a few metres as rock).
const WEAR_SHARE: (f64, f64) = (0.5, 0.9);

/// The maps of an eroded terrain against its input (same grid).
pub struct Maps {
    /// Material removed, m.
    pub wear: Vec<f32>,
    /// Material deposited, m (filled lakes included).
    pub deposition: Vec<f32>,
    /// log10 of the drainage area in cells, multiple flow directions on the final surface.
    pub flow: Vec<f32>,
}

impl Maps {
    /// Wear and deposition are measured from the input raised on land by `uplift_m` (each
    /// cell's, or one for all; the rock the rivers had to cut), so a rising range shows its
    /// valleys, not its rise.
    pub fn new(
        input: &Heightfield,
        output: &Heightfield,
        sea_level: f32,
        flow_exponent: f64,
        uplift_m: &[f32],
    ) -> Self {
        let grid = Grid::new(output.cols, output.rows, f64::from(output.cell_size_m));
        let (wear, deposition) = (0..grid.cells())
            .into_par_iter()
            .map(|i| {
                let a = f64::from(input.heights_m[i]);
                let land = a > f64::from(sea_level) && !grid.on_border(i);
                let u = f64::from(if uplift_m.len() == 1 { uplift_m[0] } else { uplift_m[i] });
                let reference = if land { a + u } else { a };
                let b = f64::from(output.heights_m[i]);
                ((reference - b).max(0.0) as f32, (b - reference).max(0.0) as f32)
            })
            .unzip();
        let heights: Vec<f64> = output.heights_m.par_iter().map(|&h| f64::from(h)).collect();
        let outlets = outlets(&grid, &heights, f64::from(sea_level));
        let mut route = Flow::new(grid.cells());
        let none = vec![0.0; grid.cells()];
        route.route(&grid, &heights, &outlets, &none, flow_exponent);
        let cell_area = grid.cell * grid.cell;
        let flow = route.area.par_iter().map(|&a| (a / cell_area).log10() as f32).collect();
        Self { wear, deposition, flow }
    }

    /// `flow.png`, `wear.png`, `deposition.png`.
    pub fn artifacts(&self, cols: usize, rows: usize) -> Vec<Artifact> {
        let png = |values: &[f32], unit: &str, what: &str| scalar_png16(cols, rows, values, unit, what);
        vec![
            Artifact::new(
                "flow.png",
                "image/png",
                png(&self.flow, "log10 cells", "drainage area, log10 of the cells draining through each"),
            ),
            Artifact::new("wear.png", "image/png", png(&self.wear, "m", "material removed, metres")),
            Artifact::new("deposition.png", "image/png", png(&self.deposition, "m", "material deposited, metres")),
        ]
    }

    /// The splat map's material (sediment) and rock (worn bedrock) weights, 0–255.
    pub fn splat(&self) -> (Vec<u8>, Vec<u8>) {
        let weight = |edges: (f64, f64), x: f32| {
            let t = ((f64::from(x) - edges.0) / (edges.1 - edges.0)).clamp(0.0, 1.0);
            (t * t * (3.0 - 2.0 * t) * 255.0).round() as u8
        };
        let deepest = f64::from(self.wear.iter().copied().fold(0.0f32, f32::max));
        let rock = if deepest > 0.0 {
            let edges = (WEAR_SHARE.0 * deepest, WEAR_SHARE.1 * deepest);
            self.wear.par_iter().map(|&w| weight(edges, w)).collect()
        } else {
            vec![0; self.wear.len()]
        };
        (self.deposition.par_iter().map(|&d| weight(SEDIMENT_M, d)).collect(), rock)
    }
}
