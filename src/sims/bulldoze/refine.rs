//! Resolutions nested and combined (paper §3): a `refine` operation resamples the grid to a
//! finer resolution over the same extent and confines the operations after it to a window —
//! sketch the site coarse, then work a detail fine. The whole stays one grid (the coarse work
//! bilinearly resampled, exact at the coarse samples), so no seam can open where the detail
//! meets it; refines nest, each window inside the ones before.

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use super::params::{metres, Sign, Window};
use crate::validate::{Limits, Validate, Validator};

/// From here on: the grid at `resolution` metres, and operations only inside `window` (and
/// inside every earlier refine's window and the request's).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(as = BulldozeRefine)]
pub struct Refine {
    /// Metres between samples from here on; not coarser than the grid's. The resampled grid
    /// must hold at most the server's grid cap (4097 × 4097 samples by default; more is
    /// answered with 413).
    // 1e6 = MAX_METRES
    #[schema(exclusive_minimum = 0.0, maximum = 1e6)]
    pub resolution: f32,
    pub window: Window,
}

impl Validate for Refine {
    fn validate(&self, v: &mut Validator, limits: &Limits) {
        metres(v, "resolution", self.resolution, Sign::Positive);
        v.field("window", |v| self.window.validate(v, limits));
    }
}

/// The part two windows share (empty, min above max, when they do not meet).
pub fn intersect(a: Option<Window>, b: Window) -> Window {
    match a {
        None => b,
        Some(a) => Window {
            min_x: a.min_x.max(b.min_x),
            min_z: a.min_z.max(b.min_z),
            max_x: a.max_x.min(b.max_x),
            max_z: a.max_z.min(b.max_z),
        },
    }
}

#[cfg(test)]
mod tests {
    use serde_json::json;

    use super::super::{apply_operations, Bulldoze, BulldozeParams, Operation};
    use crate::jobs::Simulation;
    use crate::sims::test_support::{job_terrain, TestContext};
    use crate::terrain::Heightfield;

    fn plane() -> Heightfield {
        Heightfield::from_fn(97, 97, 1.0, |x, z| 5.0 + 0.05 * x + 0.02 * z)
    }

    fn ops(v: serde_json::Value) -> Vec<Operation> {
        serde_json::from_value(v).unwrap()
    }

    #[test]
    fn a_nested_window_matches_a_direct_fine_run_inside_and_the_coarse_run_outside() {
        // Sketch at 4 m (a mound away from the window), then work [10, 50]² m at 1 m (a cone).
        let coarse_start = plane().resampled(4.0);
        let mound = json!({"primitive": {"shape": {"mound": {"center": {"x": 80.0, "z": 80.0}, "radius_m": 12.0, "height_m": 6.0}}}});
        let cone = json!({"primitive": {"shape": {"cone": {"center": {"x": 30.0, "z": 30.0}, "radius_m": 8.0, "height_m": 3.0}}}});
        let refine = json!({"refine": {"resolution": 1.0, "window": {"min_x": 10.0, "min_z": 10.0, "max_x": 50.0, "max_z": 50.0}}});
        let mut nested = coarse_start.clone();
        apply_operations(&mut nested, &ops(json!([mound, refine, cone])), None);
        let mut coarse = coarse_start.clone();
        apply_operations(&mut coarse, &ops(json!([mound])), None);
        let mut direct = plane();
        apply_operations(&mut direct, &ops(json!([cone])), None);
        assert_eq!((nested.cols, nested.rows, nested.cell_size_m), (97, 97, 1.0));
        let mut inside = 0;
        for r in 0..97 {
            for c in 0..97 {
                let (x, z) = (c as f32, r as f32);
                let got = nested.get(c, r);
                if (10.0..=50.0).contains(&x) && (10.0..=50.0).contains(&z) {
                    // The plane resamples exactly, so inside is the direct run at 1 m.
                    assert!((got - direct.get(c, r)).abs() < 1e-4, "({x}, {z}): {got} vs {}", direct.get(c, r));
                    inside += (got != plane().get(c, r)) as usize;
                } else if c % 4 == 0 && r % 4 == 0 {
                    // Outside, on the coarse samples: exactly the coarse run.
                    assert_eq!(got.to_bits(), coarse.get(c / 4, r / 4).to_bits(), "({x}, {z})");
                } else {
                    // Between them: the coarse run, bilinear.
                    assert!((got - coarse.sample(x, z)).abs() < 1e-5, "({x}, {z})");
                }
            }
        }
        assert!(inside > 100, "the cone was worked inside the window ({inside} samples)");
        // The cone's rim outside the window is not cut: a refine confines what follows.
        let mut clipped = coarse_start;
        let big = json!({"primitive": {"shape": {"cone": {"center": {"x": 30.0, "z": 30.0}, "radius_m": 30.0, "height_m": 3.0}}}});
        apply_operations(&mut clipped, &ops(json!([refine, big])), None);
        assert_eq!(clipped.get(55, 30), plane().get(55, 30));
        assert!(clipped.get(45, 30) > plane().get(45, 30));
    }

    #[test]
    fn a_refined_job_replays_bit_for_bit_and_a_refine_too_fine_or_coarse_is_refused() {
        let t = TestContext::new(plane());
        let body = |res: f32| {
            json!({"terrain": job_terrain(), "resolution": 4.0, "operations": [
                {"primitive": {"shape": {"mound": {"center": {"x": 48.0, "z": 48.0}, "radius_m": 30.0, "height_m": 6.0}}}},
                {"refine": {"resolution": res, "window": {"min_x": 20.0, "min_z": 20.0, "max_x": 70.0, "max_z": 70.0}}},
                {"pass": {"path": [{"x": 25.0, "z": 48.0}, {"x": 68.0, "z": 48.0}], "blade": {"width_m": 4.0, "profile": [[-1.0, -1.0], [1.0, -1.0]]}}}
            ]})
        };
        let p: BulldozeParams = serde_json::from_value(body(0.5)).unwrap();
        let run = Bulldoze::run(&p, 1, &t.ctx()).unwrap();
        let stored = serde_json::from_slice(&serde_json::to_vec(&run.sequence).unwrap()).unwrap();
        let again = Bulldoze::replay(&p, &stored, None, &t.ctx()).unwrap();
        let bytes = |o: &crate::jobs::Outcome<super::super::BulldozeSequence>| {
            o.artifacts.iter().map(|a| (a.name.clone(), a.bytes.clone())).collect::<Vec<_>>()
        };
        assert_eq!(bytes(&run), bytes(&again));
        assert_eq!(run.result["grid"]["cell_size_m"], json!(0.5));
        // Coarser than the grid, or past the grid cap: a problem naming the refine.
        for res in [8.0, 0.0005] {
            let p: BulldozeParams = serde_json::from_value(body(res)).unwrap();
            match Bulldoze::run(&p, 1, &t.ctx()) {
                Err(crate::jobs::SimError::Invalid { field, .. }) => {
                    assert_eq!(field, "operations[1].refine.resolution")
                }
                other => panic!("{res}: {:?}", other.map(|o| o.result)),
            }
        }
    }
}
