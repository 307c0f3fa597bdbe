//! `preserve`: divergence from the original terrain everywhere, (h − original)²; and the
//! request's `keep_weight`, the same pull on the samples no constraint asks about.

use serde_json::{json, Value};

use super::{rms, Anchors, Detail, Field, Grid, Quadratic};
use crate::sims::deform_terrain::params::Preserve;

pub fn build(p: &Preserve, grid: &Grid) -> Field {
    let n = grid.cells();
    let w = 1.0 / (n as f64 * grid.relief * grid.relief);
    Field {
        name: "preserve",
        weight: p.weight,
        quadratic: Some(Quadratic::from_terms(n, (0..n).map(|i| (i, w, grid.original[i])))),
        one_sided: None,
        pairs: None,
        interest: vec![false; n],
        anchors: Anchors::None,
        detail: Detail::Preserve,
    }
}

/// RMS and largest divergence from the original as shares of the relief.
pub fn figures(h: &[f64], grid: &Grid) -> Value {
    let diff = || h.iter().zip(grid.original).map(|(a, o)| a - o);
    json!({
        "rms_change_of_relief": rms(diff()) / grid.relief,
        "max_change_of_relief": diff().fold(0.0f64, |m, d| m.max(d.abs())) / grid.relief,
    })
}

/// The pull back to the original of every sample not `asked` about, weighted `weight` over their
/// count × relief² (a mean square in units of relief², as each constraint is), and of every
/// other sample but the `targets` at `inside` times that weight; `None` when there is none.
///
/// The pull inside the footprints is what keeps the search from stacking kernels there: a
/// kernel centred beside a road or in a mask's shallows that fixes a target in its tail
/// otherwise moves its own centre by the residual over the tail's weight, again and again
/// (300 m on a 22 m relief in `limit_tests`), and the projection after the search then has a
/// wreck to lay back.
pub fn keep(asked: &[bool], targets: &[bool], grid: &Grid, weight: f64, inside: f64) -> Option<Quadratic> {
    let free = asked.iter().filter(|&&a| !a).count().max(1);
    if weight <= 0.0 {
        return None;
    }
    let w = weight / (free as f64 * grid.relief * grid.relief);
    let terms = (0..grid.cells()).filter(|&i| !targets[i]).filter_map(|i| {
        let wi = if asked[i] { w * inside } else { w };
        (wi > 0.0).then(|| (i, wi, grid.original[i]))
    });
    Some(Quadratic::from_terms(grid.cells(), terms))
}
