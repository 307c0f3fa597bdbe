//! Priority-Flood+ε (Barnes, Lehman & Mulla 2014, Computers & Geosciences 62:117, Alg. 3):
//! every depression is filled to its spill height plus a small rise per cell, so that water on
//! any land cell has a strictly lower neighbour to run to and reaches an outlet.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use super::grid::Grid;

/// Metres each cell of a filled depression stands above the one it drains to: large enough
/// to survive the f32 the heights are stored in (1e-5 m at 100 m), small beside any relief.
pub const EPSILON_M: f64 = 1e-4;

/// A height as a key that orders like the float (heights are finite), ties broken by index so
/// the fill does not depend on the heap's internals.
pub fn key(h: f64, i: usize) -> Reverse<(u64, u32)> {
    Reverse((ordered(h), i as u32))
}

/// An order-preserving map of an f64's bits onto u64.
pub fn ordered(h: f64) -> u64 {
    let bits = h.to_bits();
    if bits >> 63 == 1 {
        !bits
    } else {
        bits | (1 << 63)
    }
}

/// Fill `heights` in place from the `outlets` inwards, each cell at least `epsilon` above the
/// cell it was reached from; outlets are never changed. Returns the volume added, m³.
pub fn fill(grid: &Grid, heights: &mut [f64], outlets: &[bool], epsilon: f64) -> f64 {
    let mut closed = outlets.to_vec();
    let mut heap = BinaryHeap::new();
    for i in 0..grid.cells() {
        if outlets[i] && (0..8).any(|k| grid.neighbour(i, k).is_some_and(|n| !outlets[n])) {
            heap.push(key(heights[i], i));
        }
    }
    let mut added = 0.0;
    // The cell popped is the lowest on the flood's front, so what it reaches drains through it.
    while let Some(Reverse((_, c))) = heap.pop() {
        let c = c as usize;
        let hc = heights[c];
        for k in 0..8 {
            let Some(n) = grid.neighbour(c, k) else { continue };
            if closed[n] {
                continue;
            }
            closed[n] = true;
            let floor = hc + epsilon;
            if heights[n] < floor {
                added += floor - heights[n];
                heights[n] = floor;
            }
            heap.push(key(heights[n], n));
        }
    }
    added * grid.cell * grid.cell
}
