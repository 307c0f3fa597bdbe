//! `match_heightmap`: penalise the distance from a desired heightfield, (h − t)².

use serde_json::{json, Value};

use super::{rms, Anchors, Detail, Field, Grid, Quadratic};
use crate::sims::deform_terrain::params::MatchHeightmap;
use crate::terrain::Heightfield;

pub fn build(m: &MatchHeightmap, target: &Heightfield, grid: &Grid) -> Field {
    let n = grid.cells();
    let w = 1.0 / (n as f64 * grid.relief * grid.relief);
    let quadratic = Quadratic::from_terms(n, (0..n).map(|i| (i, w, target.heights_m[i] as f64)));
    Field {
        name: "match_heightmap",
        weight: m.weight,
        quadratic: Some(quadratic),
        one_sided: None,
        pairs: None,
        interest: vec![false; n],
        anchors: Anchors::None,
        detail: Detail::MatchHeightmap,
    }
}

/// RMS distance from the target as a share of the relief.
pub fn figures(field: &Field, h: &[f64], grid: &Grid) -> Value {
    let q = field.quadratic.as_ref().expect("quadratic");
    json!({ "rms_error_of_relief": rms(h.iter().zip(&q.t).map(|(a, t)| a - t)) / grid.relief })
}
