//! Hillslope transport as a physical process: soil creep whose flux grows without bound as the
//! slope nears the critical (talus) slope S_c, q = −κ∇z / (1 − (|∇z|/S_c)²) (Roering, Kirchner
//! & Dietrich 1999), and failure of anything steeper than S_c (the limit of that law, which no
//! creep rate reaches in finite time).
//!
//! **Creep** is solved implicitly for the whole time step, so its result does not depend on how
//! a span of years is cut into steps beyond the method's first-order error, whatever κ·Δt/Δx²:
//! the coefficient is frozen at the start of the step (Picard) and the two directions are split
//! (locally one-dimensional backward Euler: a tridiagonal solve along every row, then along
//! every column). Each solve is an M-matrix, so the step never overshoots and never makes a new
//! extremum; its fluxes are differences across faces, so material is conserved.
//!
//! **Failure** then moves material across every face whose slope exceeds S_c until none exceeds
//! it by more than [`FAIL_TOLERANCE`] (or [`MAX_FAIL_SWEEPS`] sweeps, the rest carried to the
//! next step): each sweep moves a quarter of a face's excess, where the excess is measured on
//! the face's *gradient* (its own difference and the mean of its cells' differences across it),
//! not on the drop to each neighbour, so a cone relaxes to a cone and not to an octagonal
//! pyramid, and a slope's facets do not line up with the grid.
//!
//! Both read the face's slope from one function of the face, called from either side, so the
//! flux leaving one cell is bit for bit the flux entering the other. Cells that are `fixed` (the
//! grid's border when it is base level) keep their height; what moves into them leaves the grid.

use rayon::prelude::*;

use super::flood::{key, ordered};
use super::grid::Grid;

/// S/S_c beyond which creep's coefficient stops growing (×10.3 of κ): failure takes over there,
/// and the implicit solve stays well conditioned.
const CREEP_CAP: f64 = 0.95;
/// Share of a face's excess one failure sweep moves: four faces a cell, so each update is a
/// convex combination of the cell and its neighbours (no overshoot).
const FAIL_RATE: f64 = 0.25;
/// Failure stops where no face is steeper than S_c·(1 + this).
pub const FAIL_TOLERANCE: f64 = 0.05;
/// Most failure sweeps one step runs; what is left over carries to the next step.
pub const MAX_FAIL_SWEEPS: usize = 256;
/// Metres a cell must stand above what the critical slope allows before it collapses: below
/// the rounding of f32 heights, above the solve's own.
const COLLAPSE_TOLERANCE_M: f64 = 1e-6;
/// Columns solved together in the column pass: one cache line of f64.
const BLOCK: usize = 8;

/// The hillslope process of one erosion.
pub struct Hillslope {
    /// Creep diffusivity κ, m²/yr.
    pub kappa: f64,
    /// Critical slope S_c = tan(talus angle), m/m.
    pub sc: f64,
    /// The grid's border keeps its height (the base level when rivers run).
    pub fixed_border: bool,
    /// The row pass's result, then the failure sweeps' changes.
    mid: Vec<f64>,
    /// The column pass's result, column block by column block.
    blocks: Vec<f64>,
}

/// Each side neighbour of [`super::grid::N8`] (its index) with the two corners beside it, in
/// the order the triangles are tried: east, west, south, north.
const SIDE_CORNERS: [(usize, [usize; 2]); 4] = [(4, [2, 7]), (3, [0, 5]), (6, [5, 7]), (1, [0, 2])];

impl Hillslope {
    pub fn new(grid: &Grid, kappa: f64, talus_angle_deg: f64, fixed_border: bool) -> Self {
        let sc = libm::tan(talus_angle_deg.to_radians());
        let cells = grid.cells();
        let blocks = if kappa > 0.0 { vec![0.0; grid.cols.div_ceil(BLOCK) * BLOCK * grid.rows] } else { Vec::new() };
        // The collapse (rivers on) needs neither buffer; creep needs both, the sweeps `mid`.
        let mid = if kappa > 0.0 || !fixed_border { vec![0.0; cells] } else { Vec::new() };
        Self { kappa, sc, fixed_border, mid, blocks }
    }

    fn fixed(&self, grid: &Grid, r: usize, c: usize) -> bool {
        self.fixed_border && (r == 0 || c == 0 || r + 1 == grid.rows || c + 1 == grid.cols)
    }

    /// One step of `dt_years`: creep, then failure. With `rivers` (the outlets, and each cell's
    /// loss this iteration, m³), failure is the envelope of [`Hillslope::collapse`] and its debris
    /// joins the rivers' load; without, the conservative sweeps of [`Hillslope::fail`] pile it at
    /// the foot. Returns the volume that left the grid through its fixed border, m³.
    pub fn step(
        &mut self,
        grid: &Grid,
        heights: &mut [f64],
        dt_years: f64,
        rivers: Option<(&[bool], &mut [f64])>,
    ) -> f64 {
        let before = total(grid, heights);
        if self.kappa > 0.0 {
            self.creep(grid, heights, dt_years);
        }
        let exported = (before - total(grid, heights)) * grid.cell * grid.cell;
        match rivers {
            Some((outlets, debris)) => self.collapse(grid, heights, outlets, debris),
            None => {
                self.fail(grid, heights);
            }
        }
        exported
    }

    /// Failure where rivers run: every land cell standing more than S_c above the surface below
    /// it is lowered onto the cone of slope S_c that rises from that surface — the largest
    /// surface under the terrain whose gradient nowhere exceeds S_c, found by a fast-marching
    /// solve of |∇u| = S_c (Sethian 1996) from the cells that break it, lowest first, on the
    /// eight-neighbour upwind stencil of triangles (exact for a plane in any direction, so the
    /// cone is round and not an octagon, and troughs do not run along the rows). The volume each cell loses is added to `debris`, the rivers' load:
    /// the next iteration routes it downhill, and settles it where rivers slow or in the sea, as
    /// landslide debris is in threshold landscapes. Outlets are never lowered; only what moved
    /// is visited, so an iteration that steepened little costs little.
    fn collapse(&mut self, grid: &Grid, h: &mut [f64], outlets: &[bool], debris: &mut [f64]) {
        use std::cmp::Reverse;
        use std::collections::BinaryHeap;
        let (cols, rows) = (grid.cols, grid.rows);
        let d = self.sc * grid.cell;
        let area = grid.cell * grid.cell;
        // The height the upwind stencil allows cell i from its neighbours as they stand: the
        // least over the eight triangles (a side neighbour and the corner beside it) of the
        // plane of slope S_c through both, where the way down runs inside the triangle, and
        // otherwise S_c·ℓ above a single neighbour.
        let diagonal = d * std::f64::consts::SQRT_2;
        let allowed = |h: &[f64], i: usize| {
            // The eight neighbours' heights, N8's order (+∞ off the grid): read once each.
            let (r, c) = (i / cols, i % cols);
            let mut nb = [f64::INFINITY; 8];
            if r > 0 && c > 0 && r + 1 < rows && c + 1 < cols {
                for (k, n) in nb.iter_mut().enumerate() {
                    *n = h[grid.inner(i, k)];
                }
            } else {
                for (k, n) in nb.iter_mut().enumerate() {
                    if let Some(j) = grid.neighbour(i, k) {
                        *n = h[j];
                    }
                }
            }
            let mut best = f64::INFINITY;
            // Each side (N8 index) with the two corners beside it.
            for (side, corners) in SIDE_CORNERS {
                let a = nb[side];
                best = best.min(a + d);
                for corner in corners {
                    let b = nb[corner];
                    best = best.min(b + diagonal);
                    let drop = a - b;
                    if drop >= 0.0 && drop <= d * std::f64::consts::FRAC_1_SQRT_2 {
                        best = best.min(a + (d * d - drop * drop).sqrt());
                    }
                }
            }
            best
        };
        let frozen: &[f64] = h;
        // Every candidate above is at least S_c·Δx/√2 over the lowest neighbour: a cell no
        // higher than that (most of them) needs no closer look.
        let clear = d * std::f64::consts::FRAC_1_SQRT_2;
        let seeds: Vec<(usize, f64)> = (0..rows)
            .into_par_iter()
            .flat_map_iter(|r| {
                (r * cols..(r + 1) * cols).filter_map(move |i| {
                    if outlets[i] {
                        return None;
                    }
                    if frozen[i] <= grid.lowest_neighbour(frozen, i) + clear {
                        return None;
                    }
                    let u = allowed(frozen, i);
                    (u < frozen[i] - COLLAPSE_TOLERANCE_M).then_some((i, u))
                })
            })
            .collect();
        if seeds.is_empty() {
            return;
        }
        // The seeds in order (a parallel sort), beside a heap for the cells they lower: the
        // lowest of the two goes next, as from one heap, but the heap stays small.
        let mut sorted: Vec<(u64, u32)> = seeds.iter().map(|&(i, u)| (ordered(u), i as u32)).collect();
        sorted.par_sort_unstable();
        for (i, u) in seeds {
            debris[i] += (h[i] - u) * area;
            h[i] = u;
        }
        let mut heap: BinaryHeap<Reverse<(u64, u32)>> = BinaryHeap::new();
        let mut next_seed = 0;
        loop {
            let from_seeds = match (sorted.get(next_seed), heap.peek()) {
                (None, None) => break,
                (Some(_), None) => true,
                (None, Some(_)) => false,
                (Some(s), Some(Reverse(top))) => s < top,
            };
            let (k, i) = if from_seeds {
                next_seed += 1;
                sorted[next_seed - 1]
            } else {
                heap.pop().map(|Reverse(t)| t).unwrap_or_default()
            };
            let i = i as usize;
            if ordered(h[i]) != k {
                continue;
            }
            // Whatever this cell now allows a neighbour is at least `clear` above it.
            let floor = h[i] + clear;
            let interior = i >= cols && i + cols < h.len() && i % cols != 0 && i % cols != cols - 1;
            for k in 0..8 {
                let n = if interior {
                    grid.inner(i, k)
                } else {
                    let Some(n) = grid.neighbour(i, k) else { continue };
                    n
                };
                if outlets[n] || h[n] <= floor {
                    continue;
                }
                let u = allowed(h, n);
                if u < h[n] - COLLAPSE_TOLERANCE_M {
                    debris[n] += (h[n] - u) * area;
                    h[n] = u;
                    heap.push(key(u, n));
                }
            }
        }
    }

    /// The creep coefficient κ·Δt/Δx² / (1 − (S/S_c)²) at a face of slope `s`.
    #[inline]
    fn coefficient(&self, scale: f64, s: f64) -> f64 {
        let r = (s / self.sc).min(CREEP_CAP);
        scale / (1.0 - r * r)
    }

    /// Creep for `dt` years: rows, then columns, each an implicit solve.
    fn creep(&mut self, grid: &Grid, h: &mut [f64], dt: f64) {
        let (cols, rows) = (grid.cols, grid.rows);
        let scale = self.kappa * dt / (grid.cell * grid.cell);
        let mut mid = std::mem::take(&mut self.mid);
        let mut blocks = std::mem::take(&mut self.blocks);
        let this = &*self;
        let frozen: &[f64] = h;
        // Rows: from `h` into `mid`.
        mid.par_chunks_mut(cols).enumerate().for_each_init(
            || (vec![0.0; cols], vec![0.0; cols], vec![0.0; cols]),
            |(cp, dp, off), (r, out)| {
                // off[c]: the coefficient of the face between c and c + 1.
                for (c, o) in off[..cols - 1].iter_mut().enumerate() {
                    *o = this.coefficient(scale, face_x(grid, frozen, r, c));
                }
                let at = |c: usize| frozen[r * cols + c];
                solve(cols, |c| this.fixed(grid, r, c), |c| off[c], at, cp, dp, |c, x| out[c] = x);
            },
        );
        // Columns: coefficients from `h` as it was, right-hand sides from `mid`, into `blocks`
        // (block-major: the rows of BLOCK columns side by side).
        let mid_ref: &[f64] = &mid;
        blocks.par_chunks_mut(BLOCK * rows).enumerate().for_each_init(
            || (vec![0.0; rows], vec![0.0; rows], vec![0.0; rows]),
            |(cp, dp, off), (b, out)| {
                for j in 0..BLOCK {
                    let c = b * BLOCK + j;
                    if c >= cols {
                        break;
                    }
                    for (r, o) in off[..rows - 1].iter_mut().enumerate() {
                        *o = this.coefficient(scale, face_y(grid, frozen, r, c));
                    }
                    solve(
                        rows,
                        |r| this.fixed(grid, r, c),
                        |r| off[r],
                        |r| mid_ref[r * cols + c],
                        cp,
                        dp,
                        |r, x| out[r * BLOCK + j] = x,
                    );
                }
            },
        );
        h.par_chunks_mut(cols).enumerate().for_each(|(r, row)| {
            for (c, x) in row.iter_mut().enumerate() {
                *x = blocks[(c / BLOCK) * BLOCK * rows + r * BLOCK + c % BLOCK];
            }
        });
        self.mid = mid;
        self.blocks = blocks;
    }

    /// Failure sweeps until no face is steeper than S_c·(1 + [`FAIL_TOLERANCE`]); returns the
    /// sweeps run. Each sweep finds every face's flux once (x faces into `mid`, y faces into
    /// `blocks`), then applies them; only rows within two of a row that changed are looked at
    /// again (a face's slope reads the rows on either side of it).
    fn fail(&mut self, grid: &Grid, h: &mut [f64]) -> usize {
        let (cols, rows) = (grid.cols, grid.rows);
        let cells = grid.cells();
        let limit = self.sc * (1.0 + FAIL_TOLERANCE);
        let mut look = vec![true; rows];
        let mut changed = vec![false; rows];
        let mut fx = std::mem::take(&mut self.mid);
        let mut fy = std::mem::take(&mut self.blocks);
        fy.resize(fy.len().max(cells), 0.0);
        let mut sweeps = 0;
        while sweeps < MAX_FAIL_SWEEPS {
            let this = &*self;
            let frozen: &[f64] = h;
            // The flux across each face of the rows looked at, from the first cell to the second.
            let flux = |s: f64, from: f64, to: f64| {
                if s > limit {
                    FAIL_RATE * (1.0 - this.sc / s) * (from - to)
                } else {
                    0.0
                }
            };
            fx.par_chunks_mut(cols).zip(fy[..cells].par_chunks_mut(cols)).enumerate().for_each(|(r, (x, y))| {
                if !look[r] {
                    return;
                }
                for c in 0..cols {
                    let i = r * cols + c;
                    x[c] = if c + 1 < cols { flux(face_x(grid, frozen, r, c), frozen[i], frozen[i + 1]) } else { 0.0 };
                    y[c] =
                        if r + 1 < rows { flux(face_y(grid, frozen, r, c), frozen[i], frozen[i + cols]) } else { 0.0 };
                }
            });
            let (fx_ref, fy_ref) = (&fx[..], &fy[..cells]);
            h.par_chunks_mut(cols).zip(changed.par_iter_mut()).enumerate().for_each(|(r, (row, moved))| {
                *moved = false;
                let above = r > 0 && look[r - 1];
                if !look[r] && !above {
                    return;
                }
                for (c, x) in row.iter_mut().enumerate() {
                    if this.fixed(grid, r, c) {
                        continue;
                    }
                    let i = r * cols + c;
                    let mut d = 0.0;
                    if look[r] {
                        d -= fx_ref[i] + fy_ref[i];
                        if c > 0 {
                            d += fx_ref[i - 1];
                        }
                    }
                    if above {
                        d += fy_ref[i - cols];
                    }
                    if d != 0.0 {
                        *x += d;
                        *moved = true;
                    }
                }
            });
            if !changed.iter().any(|&c| c) {
                break;
            }
            for (r, l) in look.iter_mut().enumerate() {
                *l = changed[r.saturating_sub(2)..(r + 3).min(rows)].iter().any(|&c| c);
            }
            sweeps += 1;
        }
        self.mid = fx;
        self.blocks = fy;
        sweeps
    }

    /// The share of faces steeper than S_c·(1 + [`FAIL_TOLERANCE`]) (0 once failure has run to
    /// its end).
    pub fn steep_share(&self, grid: &Grid, h: &[f64]) -> f64 {
        let limit = self.sc * (1.0 + FAIL_TOLERANCE);
        let (cols, rows) = (grid.cols, grid.rows);
        let steep: usize = (0..rows)
            .into_par_iter()
            .map(|r| {
                let mut n = 0;
                for c in 0..cols {
                    n += usize::from(c + 1 < cols && face_x(grid, h, r, c) > limit);
                    n += usize::from(r + 1 < rows && face_y(grid, h, r, c) > limit);
                }
                n
            })
            .sum();
        steep as f64 / (2 * cols * rows - cols - rows) as f64
    }
}

/// The volume under the heights, m³/cell² (rows summed in order, so it does not depend on the
/// thread count).
fn total(grid: &Grid, h: &[f64]) -> f64 {
    let rows: Vec<f64> = h.par_chunks(grid.cols).map(|row| row.iter().sum::<f64>()).collect();
    rows.iter().sum()
}

/// Central difference along the columns (y) at (r, c), one-sided at the first and last row.
#[inline]
fn dy(grid: &Grid, h: &[f64], r: usize, c: usize) -> f64 {
    let cols = grid.cols;
    let (a, b) = (r.saturating_sub(1), (r + 1).min(grid.rows - 1));
    (h[b * cols + c] - h[a * cols + c]) / ((b - a) as f64 * grid.cell)
}

/// Central difference along the rows (x) at (r, c), one-sided at the first and last column.
#[inline]
fn dx(grid: &Grid, h: &[f64], r: usize, c: usize) -> f64 {
    let cols = grid.cols;
    let (a, b) = (c.saturating_sub(1), (c + 1).min(cols - 1));
    (h[r * cols + b] - h[r * cols + a]) / ((b - a) as f64 * grid.cell)
}

/// The slope (gradient magnitude) at the face between (r, c) and (r, c + 1).
#[inline]
pub fn face_x(grid: &Grid, h: &[f64], r: usize, c: usize) -> f64 {
    let i = r * grid.cols + c;
    let gx = (h[i + 1] - h[i]) / grid.cell;
    let gy = 0.5 * (dy(grid, h, r, c) + dy(grid, h, r, c + 1));
    (gx * gx + gy * gy).sqrt()
}

/// The slope at the face between (r, c) and (r + 1, c).
#[inline]
pub fn face_y(grid: &Grid, h: &[f64], r: usize, c: usize) -> f64 {
    let i = r * grid.cols + c;
    let gy = (h[i + grid.cols] - h[i]) / grid.cell;
    let gx = 0.5 * (dx(grid, h, r, c) + dx(grid, h, r + 1, c));
    (gx * gx + gy * gy).sqrt()
}

/// Solve one line of `n` cells of the implicit creep step (Thomas's algorithm):
/// (1 + a₋ + a₊)·xⱼ − a₋·xⱼ₋₁ − a₊·xⱼ₊₁ = rhsⱼ, with `off(j)` the coefficient of the face between
/// j and j + 1; a fixed cell keeps its right-hand side. `cp` and `dp` are scratch of length n.
#[inline]
fn solve(
    n: usize,
    fixed: impl Fn(usize) -> bool,
    off: impl Fn(usize) -> f64,
    rhs: impl Fn(usize) -> f64,
    cp: &mut [f64],
    dp: &mut [f64],
    mut out: impl FnMut(usize, f64),
) {
    let (mut cprev, mut dprev) = (0.0, 0.0);
    for j in 0..n {
        let (a, b, c) = if fixed(j) {
            (0.0, 1.0, 0.0)
        } else {
            let w = if j > 0 { off(j - 1) } else { 0.0 };
            let e = if j + 1 < n { off(j) } else { 0.0 };
            (-w, 1.0 + w + e, -e)
        };
        let m = b - a * cprev;
        cprev = c / m;
        dprev = (rhs(j) - a * dprev) / m;
        cp[j] = cprev;
        dp[j] = dprev;
    }
    let mut x = 0.0;
    for j in (0..n).rev() {
        x = if j + 1 < n { dp[j] - cp[j] * x } else { dp[j] };
        out(j, x);
    }
}
