use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde_json::json;

use super::*;
use crate::sims::deform_terrain::kernel::{apply, Kernel};
use crate::terrain::Heightfield;

fn terrain(cols: usize, rows: usize, phase: f32) -> Heightfield {
    Heightfield::from_fn(cols, rows, 1.0, |x, z| {
        20.0 * (x * 0.21 + phase).sin() * (z * 0.17).cos() + 7.0 * (x * 0.05 - z * 0.11 + phase).sin()
    })
}

fn every_constraint() -> Vec<Constraint> {
    let c = |v: serde_json::Value| serde_json::from_value::<Constraint>(v).unwrap();
    vec![
        c(
            json!({"shape_mask": {"mask": {"polygons_m": [[{"x": 5.0, "z": 5.0}, {"x": 30.0, "z": 8.0}, {"x": 20.0, "z": 28.0}]]}, "weight": 2.0}}),
        ),
        c(
            json!({"road": {"path": [{"x": 2.0, "z": 3.0}, {"x": 20.0, "z": 25.0}, {"x": 38.0, "z": 10.0}], "width_m": 3.0,
                 "height": {"profile": {"max_gradient_percent": 8.0}}}}),
        ),
        c(
            json!({"road": {"path": [{"x": 0.0, "z": 30.0}, {"x": 39.0, "z": 30.0}], "width_m": 2.0, "height": {"constant": 1.5}}}),
        ),
        c(
            json!({"edge_match": {"terrain": {"job": "0190a0f4-4a9e-7c3e-8000-000000000001"}, "edges": ["west", "north"], "band_cells": 6}}),
        ),
        c(json!({"tileable": {"edges": "both", "band_cells": 8, "weight": 3.0}})),
        c(
            json!({"points": {"points": [{"x": 10.0, "z": 10.0, "height": 5.0}, {"x": 33.0, "z": 20.0, "height": -4.0}]}}),
        ),
        c(json!({"preserve": {"weight": 0.5}})),
        c(json!({"terraces": {"regions": [
            {"polygon_m": [{"x": 3.0, "z": 3.0}, {"x": 15.0, "z": 3.0}, {"x": 15.0, "z": 15.0}], "level_m": 2.0},
            {"polygon_m": [{"x": 20.0, "z": 12.0}, {"x": 36.0, "z": 12.0}, {"x": 36.0, "z": 26.0}, {"x": 20.0, "z": 26.0}], "level_m": -1.0}
        ], "weight": 1.5}})),
        c(json!({"match_heightmap": {"target": {"job": "0190a0f4-4a9e-7c3e-8000-000000000001"}, "weight": 0.25}})),
    ]
}

fn fields_for(h0: &[f64], cols: usize, rows: usize) -> Vec<Field> {
    fields_of(every_constraint(), h0, cols, rows)
}

/// The fields of `constraints` on `h0`, the edge and match targets another terrain.
fn fields_of(constraints: Vec<Constraint>, h0: &[f64], cols: usize, rows: usize) -> Vec<Field> {
    let other = terrain(cols, rows, 1.3);
    let resolved: Vec<Resolved> = constraints
        .iter()
        .map(|c| matches!(c, Constraint::EdgeMatch(_) | Constraint::MatchHeightmap(_)).then(|| other.clone()))
        .collect();
    let grid = Grid {
        cols,
        rows,
        cell_m: 1.0,
        original: h0,
        relief: 40.0,
        slope_limit: f64::INFINITY,
        cut: f64::INFINITY,
        fill: f64::INFINITY,
    };
    build(&constraints, &resolved, &grid).unwrap()
}

fn total(fields: &[Field], h: &[f64], cols: usize, rows: usize) -> f64 {
    fields.iter().map(|f| f.weight * f.value(h, cols, rows)).sum()
}

#[test]
fn the_windowed_change_equals_the_full_recomputation() {
    let (cols, rows) = (40, 33);
    let h0: Vec<f64> = terrain(cols, rows, 0.0).heights_m.iter().map(|&v| v as f64).collect();
    let fields = fields_for(&h0, cols, rows);
    let fitness = Fitness::new(&fields, cols, rows);
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let mut h = h0.clone();
    for trial in 0..300 {
        let radius = rng.random_range(1..12usize);
        let (col, row) = (rng.random_range(0..cols), rng.random_range(0..rows));
        let delta = rng.random_range(-8.0..8.0);
        let kernel = Kernel::new(radius);
        let before = total(&fields, &h, cols, rows);
        let best =
            fitness.best_change(&h, &fitness.residual(&h), col, row, &kernel, 1, &[delta], 8.0, false, None, ANY);
        let (change, d) = (best.change, best.delta);
        assert_eq!(d, delta);
        let mut after_h = h.clone();
        let amplitude = after_h[row * cols + col] + delta;
        apply(&mut after_h, cols, rows, col, row, amplitude, &kernel);
        let full = total(&fields, &after_h, cols, rows) - before;
        let tol = 1e-9 * before.abs().max(full.abs()) + 1e-12;
        assert!((change - full).abs() <= tol, "trial {trial}: windowed {change} vs full {full}");
        // The per-constraint window update agrees too.
        let rect = Rect::around(col, row, radius, cols, rows);
        for f in &fields {
            let windowed = f.window_value(&after_h, rect, cols) - f.window_value(&h, rect, cols);
            let full = f.value(&after_h, cols, rows) - f.value(&h, cols, rows);
            assert!((windowed - full).abs() <= 1e-9 * f.value(&h, cols, rows).abs() + 1e-12, "{}", f.name);
        }
        if trial % 3 == 0 {
            h = after_h;
        }
    }
}

#[test]
fn the_best_of_many_displacements_is_the_best_full_recomputation() {
    // The shape mask's one-sided penalties are summed over runs of the sorted displacements;
    // each displacement's change must still be what recomputing F from scratch gives, so the
    // best of the list is the best of the full recomputations.
    let (cols, rows) = (40, 33);
    let h0: Vec<f64> = terrain(cols, rows, 0.0).heights_m.iter().map(|&v| v as f64).collect();
    let fields = fields_for(&h0, cols, rows);
    let fitness = Fitness::new(&fields, cols, rows);
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    for trial in 0..120 {
        let radius = rng.random_range(1..12usize);
        let (col, row) = (rng.random_range(0..cols), rng.random_range(0..rows));
        let d_max = rng.random_range(0.5..30.0);
        let count = rng.random_range(1..30usize);
        let deltas: Vec<f64> = (0..count).map(|k| d_max * (2.0 * k as f64 / count as f64 - 1.0)).collect();
        let kernel = Kernel::new(radius);
        let before = total(&fields, &h0, cols, rows);
        let best =
            fitness.best_change(&h0, &fitness.residual(&h0), col, row, &kernel, 1, &deltas, d_max, false, None, ANY);
        let full = |delta: f64| {
            let mut h = h0.clone();
            let amplitude = h[row * cols + col] + delta;
            apply(&mut h, cols, rows, col, row, amplitude, &kernel);
            total(&fields, &h, cols, rows) - before
        };
        let expected = deltas.iter().map(|&d| full(d)).fold(f64::INFINITY, f64::min);
        let tol = 1e-9 * before.abs() + 1e-12;
        assert!((best.change - expected).abs() <= tol, "trial {trial}: {} vs {expected}", best.change);
        assert!((full(best.delta) - expected).abs() <= tol, "trial {trial}: displacement {}", best.delta);
    }
}

#[test]
fn the_closed_form_displacement_is_the_best_of_the_quadratic_part() {
    let (cols, rows) = (30, 30);
    let h0: Vec<f64> = terrain(cols, rows, 0.4).heights_m.iter().map(|&v| v as f64).collect();
    let grid = Grid {
        cols,
        rows,
        cell_m: 1.0,
        original: &h0,
        relief: 40.0,
        slope_limit: f64::INFINITY,
        cut: f64::INFINITY,
        fill: f64::INFINITY,
    };
    let c: Constraint =
        serde_json::from_value(json!({"points": {"points": [{"x": 15.0, "z": 15.0, "height": 50.0}]}})).unwrap();
    let fields = build(&[c], &[None], &grid).unwrap();
    let fitness = Fitness::new(&fields, cols, rows);
    let kernel = Kernel::new(5);
    // One point: the optimum moves it exactly onto its height, removing all of F; the step
    // taken is ω times that, which removes (2ω − ω²) of F.
    let (w, optimum) = (OVER_RELAXATION, 50.0 - h0[15 * cols + 15]);
    let best =
        fitness.best_change(&h0, &fitness.residual(&h0), 15, 15, &kernel, 1, &[-1.0, 1.0], 100.0, true, None, ANY);
    let (change, d) = (best.change, best.delta);
    assert!((d - w * optimum).abs() < 1e-9, "{d} vs {}", w * optimum);
    let f = fields[0].value(&h0, cols, rows);
    assert!((change + (2.0 * w - w * w) * f).abs() < 1e-12 * f.max(1.0), "{change} vs {f}");
}

#[test]
fn mask_polygons_are_metres_on_the_grid_and_the_cell_form_is_refused() {
    // 2 m cells: the square x, z in [9, 29] m holds the samples col, row 5..=14 (10 m .. 28 m).
    let (cols, rows) = (20, 20);
    let h0 = vec![0.0; cols * rows];
    let grid = Grid {
        cols,
        rows,
        cell_m: 2.0,
        original: &h0,
        relief: 10.0,
        slope_limit: f64::INFINITY,
        cut: f64::INFINITY,
        fill: f64::INFINITY,
    };
    let square = json!([{"x": 9.0, "z": 9.0}, {"x": 29.0, "z": 9.0}, {"x": 29.0, "z": 29.0}, {"x": 9.0, "z": 29.0}]);
    let c: Constraint = serde_json::from_value(json!({"shape_mask": {"mask": {"polygons_m": [square]}}})).unwrap();
    let f = &build(&[c], &[None], &grid).unwrap()[0];
    let side = &f.one_sided.as_ref().unwrap().side;
    for (i, &s) in side.iter().enumerate() {
        let (col, row) = (i % cols, i / cols);
        let inside = (5..=14).contains(&col) && (5..=14).contains(&row);
        assert_eq!(s > 0, inside, "({col}, {row})");
    }
    let old = json!({"shape_mask": {"mask": {"polygons": [[[4.5, 4.5], [14.5, 4.5], [14.5, 14.5]]]}}});
    let err = serde_json::from_value::<Constraint>(old).unwrap_err().to_string();
    assert!(err.contains("replaced by `polygons_m`") && err.contains("metres"), "{err}");
}

#[test]
fn the_shape_mask_counts_each_side_with_its_margin() {
    let (cols, rows) = (20, 20);
    let h0 = vec![0.0; cols * rows];
    let grid = Grid {
        cols,
        rows,
        cell_m: 1.0,
        original: &h0,
        relief: 10.0,
        slope_limit: f64::INFINITY,
        cut: f64::INFINITY,
        fill: f64::INFINITY,
    };
    let c: Constraint = serde_json::from_value(
        json!({"shape_mask": {"mask": {"polygons_m": [[{"x": 4.5, "z": 4.5}, {"x": 14.5, "z": 4.5}, {"x": 14.5, "z": 14.5}, {"x": 4.5, "z": 14.5}]]}, "water_level": 0.0, "margin": 1.0}}),
    )
    .unwrap();
    let f = &build(&[c], &[None], &grid).unwrap()[0];
    let land = f.one_sided.as_ref().unwrap().side.iter().filter(|&&s| s > 0).count();
    assert_eq!(land, 100);
    // Every land cell is 1 m short of water level + margin, every sea cell 1 m above water
    // level − margin.
    let expect = 400.0 / (400.0 * 100.0);
    assert!((f.value(&h0, cols, rows) - expect).abs() < 1e-15);
    let figures = f.figures(&h0, &grid);
    assert_eq!(figures["correct_side_share"], json!(0.0));
}

#[test]
fn a_sum_brought_up_to_date_equals_one_summed_again() {
    // With only quadratic penalties the search keeps each entry's sum b and adds the kernel's
    // lattice sum over each deformed window's residual change; that must equal summing b again
    // on the deformed terrain, on the full window and on every estimate lattice, near the
    // border (where the lattice is the full window) and inside.
    let (cols, rows) = (48, 41);
    let h0: Vec<f64> = terrain(cols, rows, 0.4).heights_m.iter().map(|&v| v as f64).collect();
    let quadratic: Vec<Constraint> = every_constraint()
        .into_iter()
        .filter(|c| !matches!(c, Constraint::ShapeMask(_) | Constraint::Tileable(_)))
        .collect();
    let fields = fields_of(quadratic, &h0, cols, rows);
    let fitness = Fitness::new(&fields, cols, rows);
    assert!(fitness.residual_only());
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let deltas: Vec<f64> = (0..24).map(|k| 6.0 * (2.0 * k as f64 / 23.0 - 1.0)).collect();
    for trial in 0..200 {
        let mut h = h0.clone();
        let kernel = Kernel::new(rng.random_range(1..14usize));
        let (col, row) = (rng.random_range(0..cols), rng.random_range(0..rows));
        let stride = rng.random_range(1..5usize);
        let before =
            fitness.best_change(&h, &fitness.residual(&h), col, row, &kernel, stride, &deltas, 6.0, true, None, ANY);
        let mut residual = fitness.residual(&h);
        let mut b = before.b;
        // Two deformations near the entry, each its own change, as in one iteration's batch.
        for _ in 0..2 {
            let op = Kernel::new(rng.random_range(1..9usize));
            let (c, r) = (
                (col as i64 + rng.random_range(-12..=12i64)).clamp(0, cols as i64 - 1) as usize,
                (row as i64 + rng.random_range(-12..=12i64)).clamp(0, rows as i64 - 1) as usize,
            );
            let rect = Rect::around(c, r, op.radius, cols, rows);
            let old: Vec<f64> = cells(rect).map(|(x, y)| residual[y * cols + x]).collect();
            let amplitude = h[r * cols + c] + rng.random_range(-5.0..5.0);
            apply(&mut h, cols, rows, c, r, amplitude, &op);
            let mut change = Vec::new();
            fitness.refresh_residual(&mut residual, &h, rect, Some(&mut change));
            let now = fitness.residual(&h);
            let expected: Vec<f64> = cells(rect).zip(&old).map(|((x, y), o)| now[y * cols + x] - o).collect();
            assert_eq!(change, expected, "trial {trial}: the change refresh_residual reports");
            b += fitness.lattice_sum(&change, rect, col, row, &kernel, stride);
        }
        let again =
            fitness.best_change(&h, &fitness.residual(&h), col, row, &kernel, stride, &deltas, 6.0, true, None, ANY);
        let tol = 1e-9 * (again.b.abs() + before.b.abs() + 1.0);
        assert!((b - again.b).abs() <= tol, "trial {trial}: {b} vs {}", again.b);
        let from_sums = fitness.change_from_sums(again.curvature, b, &deltas, 6.0, true, ANY);
        assert!((from_sums.change - again.change).abs() <= 1e-9 * (again.change.abs() + 1e-12), "trial {trial}");
    }
}

/// The cells of `rect`, row by row.
fn cells(rect: Rect) -> impl Iterator<Item = (usize, usize)> {
    (rect.r0..=rect.r1).flat_map(move |y| (rect.c0..=rect.c1).map(move |x| (x, y)))
}

#[test]
fn the_interpolated_search_finds_what_bisection_finds() {
    // Evenly spread (the sampled displacements, zero left out), uneven, with repeats, short.
    let even: Vec<f64> = crate::sims::deform_terrain::search::unit_displacements(25).iter().map(|u| u * 3.5).collect();
    let uneven = vec![-9.0, -8.5, -1.0, -0.99, 0.0, 0.0, 0.0, 2.0, 40.0];
    for sorted in [even, uneven, vec![1.0], vec![], vec![2.0, 2.0]] {
        let mut probes: Vec<f64> = sorted.iter().flat_map(|&d| [d, d - 1e-9, d + 1e-9]).collect();
        probes.extend([-100.0, 100.0, 0.3, -0.3, f64::NAN, f64::INFINITY, f64::NEG_INFINITY]);
        for v in probes {
            assert_eq!(first_at_or_above(&sorted, v), sorted.partition_point(|&d| d < v), "{v} in {sorted:?}");
        }
    }
}
