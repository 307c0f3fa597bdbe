//! Constraints as fitness functions (paper §3.1–3.2): each a sum of per-vertex penalties,
//! computable in constant time per vertex, divided by (constrained vertices × relief²) so that
//! F_c is a mean-square error in units of relief² and constraints combine by weight.
//!
//! Every penalty is one of three forms: quadratic `w (h − t)²` against a fixed target,
//! one-sided (the shape mask's margin, equation 3), or a coupled pair `w (h_i − h_j)²` (a
//! tileable terrain's opposite edges). The search sums them into one [`Fitness`] whose change
//! under a deformation is evaluated over the kernel's window only.

mod edge_match;
mod hinges;

use super::projection::Held;
use hinges::Hinges;

pub use edge_match::seam_filter;
mod match_heightmap;
mod points;
mod preserve;

pub use preserve::keep;
mod road;
mod shape_mask;
mod terraces;
mod tileable;

use serde_json::{json, Map, Value};

use super::kernel::{Kernel, Rect};
use super::params::Constraint;
use crate::terrain::Heightfield;

/// The grid the constraints are built on, with its starting heights.
pub struct Grid<'a> {
    pub cols: usize,
    pub rows: usize,
    pub cell_m: f64,
    pub original: &'a [f64],
    /// Max − min of the original heights (1 for a flat terrain), metres.
    pub relief: f64,
    /// The steepest slope the result may have, metres per metre ([`super::bounds`]).
    pub slope_limit: f64,
    /// The earthworks' cut and fill slopes, metres per metre.
    pub cut: f64,
    pub fill: f64,
}

impl Grid<'_> {
    pub fn cells(&self) -> usize {
        self.cols * self.rows
    }

    /// The nearest vertex to a point in metres, clamped to the grid.
    pub fn nearest(&self, x: f64, z: f64) -> (usize, usize) {
        let c = (x / self.cell_m).round().clamp(0.0, (self.cols - 1) as f64) as usize;
        let r = (z / self.cell_m).round().clamp(0.0, (self.rows - 1) as f64) as usize;
        (c, r)
    }
}

/// Per-cell quadratic penalties `w_i (h_i − t_i)² + c_i`, already normalised.
#[derive(Clone, Debug)]
pub struct Quadratic {
    pub w: Vec<f64>,
    pub t: Vec<f64>,
    pub c: Vec<f64>,
}

impl Quadratic {
    /// Build from accumulated terms: several targets on one cell add up to one quadratic
    /// plus a constant, so the sum is exact.
    fn from_terms(cells: usize, terms: impl IntoIterator<Item = (usize, f64, f64)>) -> Self {
        let (mut w, mut s, mut s2) = (vec![0.0; cells], vec![0.0; cells], vec![0.0; cells]);
        for (i, wi, ti) in terms {
            w[i] += wi;
            s[i] += wi * ti;
            s2[i] += wi * ti * ti;
        }
        let mut t = vec![0.0; cells];
        let mut c = vec![0.0; cells];
        for i in 0..cells {
            if w[i] > 0.0 {
                t[i] = s[i] / w[i];
                c[i] = (s2[i] - s[i] * s[i] / w[i]).max(0.0);
            }
        }
        Self { w, t, c }
    }

    #[inline]
    fn at(&self, i: usize, h: f64) -> f64 {
        let d = h - self.t[i];
        self.w[i] * d * d + self.c[i]
    }
}

/// The shape mask's one-sided penalties (equation 3 with a margin): land wants h ≥ `lo`, sea
/// h ≤ `hi`; the penalty is the squared shortfall times `scale`.
#[derive(Clone, Debug)]
pub struct OneSided {
    /// +1 land, −1 sea, 0 unconstrained.
    pub side: Vec<i8>,
    pub lo: f64,
    pub hi: f64,
    pub scale: f64,
}

impl OneSided {
    #[inline]
    fn at(&self, i: usize, h: f64) -> f64 {
        let short = match self.side[i] {
            1 => (self.lo - h).max(0.0),
            -1 => (h - self.hi).max(0.0),
            _ => 0.0,
        };
        self.scale * short * short
    }
}

/// Coupled pairs `scale (h_i − h_j)²`: each cell's partner across the grid in X and in Z
/// (`u32::MAX` for none). A pair is counted from its lower-index cell.
///
/// With them, the slope terms of a C¹ wrap, `kink_scale (h_a + h_b − h_c − h_d)²` — the
/// first step in from one edge against the last step out to the other, (h₁ − h₀) −
/// (h_{N−1} − h_{N−2}) — one per row (`kinks_x`, members in that row) and per column
/// (`kinks_z`); empty where the axis does not wrap.
#[derive(Clone, Debug)]
pub struct Pairs {
    pub partner_x: Vec<u32>,
    pub partner_z: Vec<u32>,
    pub scale: f64,
    pub kinks_x: Vec<[usize; 4]>,
    pub kinks_z: Vec<[usize; 4]>,
    pub kink_scale: f64,
}

/// The signs of a slope term's members.
const KINK_SIGNS: [f64; 4] = [1.0, 1.0, -1.0, -1.0];

impl Pairs {
    /// The slope terms with a member in `rect`.
    fn kinks_in<'a>(&'a self, rect: Rect, cols: usize, rows: usize) -> impl Iterator<Item = &'a [usize; 4]> + 'a {
        let meets = |lo: usize, hi: usize, n: usize| [0, 1, n - 2, n - 1].iter().any(|&l| (lo..=hi).contains(&l));
        let x = (!self.kinks_x.is_empty() && cols >= 2 && meets(rect.c0, rect.c1, cols))
            .then(|| &self.kinks_x[rect.r0..=rect.r1]);
        let z = (!self.kinks_z.is_empty() && rows >= 2 && meets(rect.r0, rect.r1, rows))
            .then(|| &self.kinks_z[rect.c0..=rect.c1]);
        x.into_iter().flatten().chain(z.into_iter().flatten())
    }

    /// A slope term's value.
    fn kink(m: &[usize; 4], h: &[f64]) -> f64 {
        m.iter().zip(KINK_SIGNS).map(|(&i, s)| s * h[i]).sum()
    }
}

pub const NO_PARTNER: u32 = u32::MAX;

impl Pairs {
    fn partners(&self, i: usize) -> [u32; 2] {
        [self.partner_x[i], self.partner_z[i]]
    }
}

/// One constraint's penalties and what its figures need.
pub struct Field {
    pub name: &'static str,
    pub weight: f64,
    pub quadratic: Option<Quadratic>,
    pub one_sided: Option<OneSided>,
    pub pairs: Option<Pairs>,
    /// Cells that drive candidate refinement (Figure 2) and define "far" cells.
    pub interest: Vec<bool>,
    /// Which cells of interest are candidate vertices themselves (Figure 2's path vertices).
    pub anchors: Anchors,
    pub detail: Detail,
}

/// Which cells of interest anchor small deformations of their own.
pub enum Anchors {
    /// None: the lattice of centres fits the constraint.
    None,
    /// Every one, with every small radius: narrow features (roads, seams, points) that a
    /// coarser lattice of centres cannot fit cell by cell.
    Interest,
    /// Every one, but only those marked (a region's edge) with every small radius, the rest
    /// with the smallest few: areas whose edges must come out sharp, while their inside is
    /// fitted by the lattice's centres and needs only the finest detail cell by cell.
    Edges(Vec<bool>),
}

/// What a constraint's figures are computed from.
pub enum Detail {
    MatchHeightmap,
    /// `shore`: per sample, the share of the margin the projection holds it by.
    ShapeMask {
        water_level: f64,
        margin: f64,
        shore: Vec<f64>,
    },
    Road(road::RoadDetail),
    EdgeMatch(edge_match::EdgeDetail),
    Tileable {
        x: bool,
        z: bool,
    },
    Points(Vec<(usize, f64)>),
    Preserve,
    Terraces(terraces::TerraceDetail),
}

/// The inputs a constraint reads besides the request: resolved terrains (match target, mask
/// image, edge neighbour), in the order of the constraints, `None` where there is none.
pub type Resolved = Option<Heightfield>;

/// Why a constraint cannot be built: the JSON path of the field and the reason.
#[derive(Debug)]
pub struct BuildError {
    pub field: String,
    pub message: String,
}

/// Build every constraint's field. `resolved[i]` is constraint i's terrain input.
pub fn build(constraints: &[Constraint], resolved: &[Resolved], grid: &Grid) -> Result<Vec<Field>, BuildError> {
    constraints
        .iter()
        .zip(resolved)
        .enumerate()
        .map(|(i, (c, input))| {
            let at = |leaf: &str| format!("constraints[{i}].{}.{leaf}", c.name());
            let size_check = |leaf: &str, hf: &Heightfield| {
                if hf.cols != grid.cols || hf.rows != grid.rows {
                    Err(BuildError {
                        field: at(leaf),
                        message: format!(
                            "is {}×{} samples; the terrain is {}×{}",
                            hf.cols, hf.rows, grid.cols, grid.rows
                        ),
                    })
                } else {
                    Ok(())
                }
            };
            Ok(match c {
                Constraint::MatchHeightmap(m) => {
                    let target = input.as_ref().expect("resolved target");
                    size_check("target", target)?;
                    match_heightmap::build(m, target, grid)
                }
                Constraint::ShapeMask(m) => {
                    if let Some(image) = input {
                        size_check("mask.image", image)?;
                    }
                    shape_mask::build(m, input.as_ref(), grid)
                }
                Constraint::Road(r) => road::build(r, grid, constraints.len() > 1),
                Constraint::EdgeMatch(e) => {
                    let other = input.as_ref().expect("resolved neighbour");
                    size_check("terrain", other)?;
                    edge_match::build(e, other, grid)
                }
                Constraint::Tileable(t) => tileable::build(t, grid),
                Constraint::Points(p) => points::build(p, grid),
                Constraint::Preserve(p) => preserve::build(p, grid),
                Constraint::Terraces(t) => terraces::build(t, grid),
            })
        })
        .collect()
}

impl Field {
    /// F_c over the whole grid.
    pub fn value(&self, h: &[f64], cols: usize, rows: usize) -> f64 {
        self.window_value(h, Rect { c0: 0, c1: cols - 1, r0: 0, r1: rows - 1 }, cols)
    }

    /// The part of F_c that depends on the cells in `rect`: their own penalties, and each
    /// pair with a member in it (once).
    pub fn window_value(&self, h: &[f64], rect: Rect, cols: usize) -> f64 {
        if let (Some(q), None, None) = (&self.quadratic, &self.one_sided, &self.pairs) {
            // Only the quadratic part: the same sums in the same order, over row slices.
            return (rect.r0..=rect.r1).fold(0.0, |sum, r| {
                let (i0, i1) = (r * cols + rect.c0, r * cols + rect.c1);
                let row = h[i0..=i1].iter().zip(&q.w[i0..=i1]).zip(&q.t[i0..=i1]).zip(&q.c[i0..=i1]);
                sum + row.fold(0.0, |s, (((&h, &w), &t), &c)| s + (w * (h - t) * (h - t) + c))
            });
        }
        let mut sum = 0.0;
        for r in rect.r0..=rect.r1 {
            let mut row_sum = 0.0;
            for c in rect.c0..=rect.c1 {
                let i = r * cols + c;
                if let Some(q) = &self.quadratic {
                    row_sum += q.at(i, h[i]);
                }
                if let Some(m) = &self.one_sided {
                    row_sum += m.at(i, h[i]);
                }
                if let Some(p) = &self.pairs {
                    for j in p.partners(i) {
                        if j == NO_PARTNER {
                            continue;
                        }
                        let j = j as usize;
                        let inside = rect.contains(j % cols, j / cols);
                        if !inside || i < j {
                            let d = h[i] - h[j];
                            row_sum += p.scale * d * d;
                        }
                    }
                }
            }
            sum += row_sum;
        }
        if let Some(p) = &self.pairs {
            // Each slope term with a member in the window, once.
            for m in p.kinks_in(rect, cols, h.len() / cols) {
                let l = Pairs::kink(m, h);
                sum += p.kink_scale * l * l;
            }
        }
        sum
    }

    /// The constraint's own figures on the final heights, with its fitness.
    pub fn figures(&self, h: &[f64], grid: &Grid) -> Value {
        let mut out = Map::new();
        out.insert("kind".into(), json!(self.name));
        out.insert("weight".into(), json!(self.weight));
        out.insert("fitness".into(), json!(self.value(h, grid.cols, grid.rows)));
        let extra = match &self.detail {
            Detail::MatchHeightmap => match_heightmap::figures(self, h, grid),
            Detail::ShapeMask { water_level, margin, .. } => shape_mask::figures(self, h, *water_level, *margin),
            Detail::Road(d) => road::figures(d, h, grid),
            Detail::EdgeMatch(d) => edge_match::figures(d, h, grid),
            Detail::Tileable { x, z } => tileable::figures(*x, *z, h, grid),
            Detail::Points(p) => points::figures(p, h, grid),
            Detail::Preserve => preserve::figures(h, grid),
            Detail::Terraces(d) => terraces::figures(d, h, grid),
        };
        if let Value::Object(extra) = extra {
            out.extend(extra);
        }
        Value::Object(out)
    }
}

/// All constraints summed by weight, in the form the search evaluates.
pub struct Fitness {
    pub cols: usize,
    pub rows: usize,
    /// Combined quadratic weight and target per cell.
    q: Vec<f64>,
    m: Vec<f64>,
    one_sided: Option<OneSided>,
    pairs: Option<Pairs>,
}

/// The closed-form displacement is over-relaxed, as in successive over-relaxation: the
/// search's steps are coordinate steps on overlapping kernels, and stepping past each one's
/// own optimum (any factor below 2 still lowers F) reaches a given fitness in fewer
/// operations — about a fifth fewer on the S-road.
pub const OVER_RELAXATION: f64 = 1.5;

/// The most displacements one evaluation tries (sampled ones plus the closed-form optimum).
pub const MAX_DELTAS: usize = 128;

impl Fitness {
    pub fn new(fields: &[Field], cols: usize, rows: usize) -> Self {
        let n = cols * rows;
        let mut q = vec![0.0; n];
        let mut qt = vec![0.0; n];
        let mut one_sided = None;
        let mut pairs = None;
        for f in fields {
            if let Some(quad) = &f.quadratic {
                for i in 0..n {
                    let w = f.weight * quad.w[i];
                    q[i] += w;
                    qt[i] += w * quad.t[i];
                }
            }
            if let Some(o) = &f.one_sided {
                one_sided = Some(OneSided { scale: o.scale * f.weight, ..o.clone() });
            }
            if let Some(p) = &f.pairs {
                pairs = Some(Pairs { scale: p.scale * f.weight, kink_scale: p.kink_scale * f.weight, ..p.clone() });
            }
        }
        let m = (0..n).map(|i| if q[i] > 0.0 { qt[i] / q[i] } else { 0.0 }).collect();
        Self { cols, rows, q, m, one_sided, pairs }
    }

    /// Add a quadratic term the search weighs but no constraint reports (the request's
    /// `keep_weight`).
    pub fn with(mut self, extra: &Quadratic) -> Self {
        for i in 0..self.q.len() {
            let w = extra.w[i];
            if w > 0.0 {
                let q = self.q[i] + w;
                self.m[i] = (self.q[i] * self.m[i] + w * extra.t[i]) / q;
                self.q[i] = q;
            }
        }
        self
    }

    /// The weighted residual `q (h − m)` of every cell: the quadratic part's slope, which
    /// [`Fitness::best_change`] correlates with the kernel.
    pub fn residual(&self, h: &[f64]) -> Vec<f64> {
        h.iter().zip(&self.q).zip(&self.m).map(|((&h, &q), &m)| q * (h - m)).collect()
    }

    /// Bring `residual` up to date with `h` over `rect` (after a deformation there); with
    /// `change`, append the residual's change over `rect` to it, row by row, in the same pass.
    pub fn refresh_residual(&self, residual: &mut [f64], h: &[f64], rect: Rect, mut change: Option<&mut Vec<f64>>) {
        for r in rect.r0..=rect.r1 {
            let (i0, i1) = (r * self.cols + rect.c0, r * self.cols + rect.c1);
            for (((o, &h), &q), &m) in
                residual[i0..=i1].iter_mut().zip(&h[i0..=i1]).zip(&self.q[i0..=i1]).zip(&self.m[i0..=i1])
            {
                let now = q * (h - m);
                if let Some(change) = change.as_deref_mut() {
                    change.push(now - *o);
                }
                *o = now;
            }
        }
    }

    /// Whether every term is the quadratic part's (no one-sided mask, no tileable pairs): then
    /// a candidate's change depends on the heights only through its sum b = Σ K·residual, which
    /// can be brought up to date from the residual's changes ([`Fitness::lattice_sum`]) and
    /// turned into the best change by [`Fitness::change_from_sums`].
    pub fn residual_only(&self) -> bool {
        self.one_sided.is_none() && self.pairs.is_none()
    }

    /// The lattice step [`Fitness::best_change`] sums a window on: `stride`, or every cell of a
    /// window the border clips (a lattice through the centre could miss the edge line).
    pub fn lattice_step(&self, col: usize, row: usize, radius: usize, stride: usize) -> usize {
        let rect = Rect::around(col, row, radius, self.cols, self.rows);
        let clipped = rect.c1 - rect.c0 != 2 * radius || rect.r1 - rect.r0 != 2 * radius;
        if clipped {
            1
        } else {
            stride
        }
    }

    /// Σ K·v over the lattice of the window at (col, row) that falls inside `rect`, scaled as
    /// [`Fitness::best_change`] scales its sums; `values` covers `rect` row by row. With the
    /// residual's change over a deformed window, this is the change of a candidate's b there.
    pub fn lattice_sum(
        &self,
        values: &[f64],
        rect: Rect,
        col: usize,
        row: usize,
        kernel: &Kernel,
        stride: usize,
    ) -> f64 {
        let s = self.lattice_step(col, row, kernel.radius, stride);
        let window = Rect::around(col, row, kernel.radius, self.cols, self.rows);
        let (r0, r1) = (rect.r0.max(window.r0), rect.r1.min(window.r1));
        let (c0, c1) = (rect.c0.max(window.c0), rect.c1.min(window.c1));
        if r0 > r1 || c0 > c1 {
            return 0.0;
        }
        // The first lattice line at or after `lo`: lattice lines pass through the centre.
        let first = |lo: usize, centre: usize| lo + (centre as i64 - lo as i64).rem_euclid(s as i64) as usize;
        let (rad, side, width) = (kernel.radius, kernel.side(), rect.c1 - rect.c0 + 1);
        let c_first = first(c0, col);
        if c_first > c1 {
            return 0.0;
        }
        let c_last = c1 - (c1 - c_first) % s;
        let mut sum = 0.0;
        let mut r = first(r0, row);
        while r <= r1 {
            // Kernel weights and values along the row's lattice, as two slices walked at the
            // stride: no bounds checks inside, four partial sums.
            let (k0, v0) = ((r + rad - row) * side + rad, (r - rect.r0) * width);
            let kernel_row = &kernel.weights[k0 + c_first - col..=k0 + c_last - col];
            let values_row = &values[v0 + c_first - rect.c0..=v0 + c_last - rect.c0];
            sum += dot(kernel_row, values_row, s);
            r += s;
        }
        sum * (s * s) as f64
    }

    /// The best change over `deltas` within `range` (and the closed-form optimum clamped into
    /// it) from the quadratic part's sums alone, as [`Fitness::best_change`] finds it when
    /// [`Fitness::residual_only`]. [`ANY`] is no range.
    pub fn change_from_sums(
        &self,
        a: f64,
        b: f64,
        deltas: &[f64],
        d_max: f64,
        with_optimum: bool,
        range: (f64, f64),
    ) -> Best {
        debug_assert!(self.residual_only());
        let sampled = within(&deltas[..deltas.len().min(MAX_DELTAS - 1)], range);
        quadratic_best(a, b, sampled, closed_form(a, b, d_max, with_optimum).and_then(|d| clamp_into(d, range)))
    }

    /// The best change in F over the `deltas` (sorted ascending) within `range` (and the
    /// closed-form optimum of the quadratic part, times [`OVER_RELAXATION`], clamped to
    /// ±`d_max` and into `range`) of a deformation at (col, row) with `kernel`. [`ANY`] is no
    /// range; the search's limits ([`super::bounds`]) give one. With `stride` > 1 only every
    /// stride-th cell (through the centre) is summed, scaled by stride², as an
    /// estimate. `residual` is [`Fitness::residual`] of `h`. The curvature `a` of the quadratic
    /// part (Σ q K², plus the pairs') depends on the weights and the kernel only, never on the
    /// heights: pass the one an earlier call at the same place and stride returned, and it is
    /// not summed again. Sums run in a fixed order; nothing is allocated.
    #[allow(clippy::too_many_arguments)]
    pub fn best_change(
        &self,
        h: &[f64],
        residual: &[f64],
        col: usize,
        row: usize,
        kernel: &Kernel,
        stride: usize,
        deltas: &[f64],
        d_max: f64,
        with_optimum: bool,
        curvature: Option<f64>,
        range: (f64, f64),
    ) -> Best {
        let cols = self.cols;
        let rad = kernel.radius as i64;
        let rect = Rect::around(col, row, kernel.radius, cols, self.rows);
        let stride = self.lattice_step(col, row, kernel.radius, stride);
        let s = stride as i64;
        // Whole steps from the centre towards each border (no division on the full lattice).
        let steps = |room: i64| if s == 1 { room } else { room / s * s };
        let lo = |v: usize| -steps((v as i64).min(rad));
        let hi = |v: usize, n: usize| steps((n as i64 - 1 - v as i64).min(rad));
        let (dz0, dz1, dx0, dx1) = (lo(row), hi(row, self.rows), lo(col), hi(col, cols));
        let scale = (stride * stride) as f64;

        let side_len = kernel.side();
        // Row by row over slices on the stride lattice: no bounds checks or branches inside.
        let row_slices = |dz: i64| {
            let r = (row as i64 + dz) as usize;
            let k0 = ((dz + rad) as usize) * side_len;
            let krow = &kernel.weights[k0 + (dx0 + rad) as usize..=k0 + (dx1 + rad) as usize];
            let (c0, c1) = ((col as i64 + dx0) as usize, (col as i64 + dx1) as usize);
            (krow, r * cols + c0, r * cols + c1)
        };
        // b = Σ K·q(h − m), and a = Σ q K² when it is not known yet.
        let (mut a, mut b) = (0.0, 0.0);
        let mut dz = dz0;
        while dz <= dz1 {
            let (krow, i0, i1) = row_slices(dz);
            b += dot(krow, &residual[i0..=i1], stride);
            if curvature.is_none() {
                a += dot3(krow, krow, &self.q[i0..=i1], stride);
            }
            dz += s;
        }
        a *= scale;
        b *= scale;
        // Pairs live on the grid's border lines only; they are summed exactly.
        if let Some(p) = &self.pairs {
            let mut pair = |i: usize, j: u32| {
                if j == NO_PARTNER {
                    return;
                }
                let j = j as usize;
                let (jc, jr) = (j % cols, j / cols);
                let inside = rect.contains(jc, jr);
                if inside && j < i {
                    return;
                }
                let k = kernel.at((i % cols) as i64 - col as i64, (i / cols) as i64 - row as i64);
                let kj = if inside { kernel.at(jc as i64 - col as i64, jr as i64 - row as i64) } else { 0.0 };
                let e = k - kj;
                a += p.scale * e * e;
                b += p.scale * e * (h[i] - h[j]);
            };
            for c in [0, cols - 1] {
                if (rect.c0..=rect.c1).contains(&c) {
                    for r in rect.r0..=rect.r1 {
                        pair(r * cols + c, p.partner_x[r * cols + c]);
                    }
                }
            }
            for r in [0, self.rows - 1] {
                if (rect.r0..=rect.r1).contains(&r) {
                    for c in rect.c0..=rect.c1 {
                        pair(r * cols + c, p.partner_z[r * cols + c]);
                    }
                }
            }
            for m in p.kinks_in(rect, cols, self.rows) {
                let mut e = 0.0;
                for (&i, sign) in m.iter().zip(KINK_SIGNS) {
                    let (ic, ir) = (i % cols, i / cols);
                    if rect.contains(ic, ir) {
                        e += sign * kernel.at(ic as i64 - col as i64, ir as i64 - row as i64);
                    }
                }
                a += p.kink_scale * e * e;
                b += p.kink_scale * e * Pairs::kink(m, h);
            }
        }

        let a = curvature.unwrap_or(a);
        let sampled = within(&deltas[..deltas.len().min(MAX_DELTAS - 1)], range);
        let n = sampled.len();
        debug_assert!(sampled.windows(2).all(|w| w[0] <= w[1]), "displacements are sampled in order");
        let optimum = closed_form(a, b, d_max, with_optimum).and_then(|d| clamp_into(d, range));
        let Some(m) = &self.one_sided else {
            return quadratic_best(a, b, sampled, optimum);
        };
        let mut hinges = Hinges::new(sampled, optimum);
        let mut dz = dz0;
        while dz <= dz1 {
            let (krow, i0, i1) = row_slices(dz);
            for (t, &k) in krow.iter().enumerate().step_by(stride) {
                let i = i0 + t;
                debug_assert!(i <= i1);
                // Land wants h ≥ lo: max(0, (lo − h) − k·d)²; sea h ≤ hi: max(0, (h − hi) + k·d)².
                match m.side[i] {
                    1 if k > 0.0 => hinges.add(m.scale, m.lo - h[i], -k),
                    -1 if k > 0.0 => hinges.add(m.scale, h[i] - m.hi, k),
                    _ => {}
                }
            }
            dz += s;
        }
        let quadratic = |d: f64| a * d * d + 2.0 * b * d;
        let mut best = Best { change: f64::INFINITY, delta: 0.0, curvature: a, b };
        let mut consider = |d: f64, change: f64| {
            if change < best.change {
                (best.change, best.delta) = (change, d);
            }
        };
        let mut changes = [0.0f64; MAX_DELTAS];
        let at_optimum = hinges.changes(scale, &mut changes);
        for (&d, &p) in sampled.iter().zip(&changes[..n]) {
            consider(d, quadratic(d) + p);
        }
        if let (Some(d), Some(p)) = (optimum, at_optimum) {
            consider(d, quadratic(d) + p);
        }
        best
    }
}

/// What [`Fitness::best_change`] found: the change in F, the displacement that makes it, and
/// the curvature to pass back next time.
#[derive(Clone, Copy, Debug)]
pub struct Best {
    pub change: f64,
    pub delta: f64,
    pub curvature: f64,
    /// The quadratic part's sum b = Σ K·q(h − m) (scaled on the lattice, with the pairs').
    pub b: f64,
}

/// Every displacement.
pub const ANY: (f64, f64) = (f64::NEG_INFINITY, f64::INFINITY);

/// The displacements of `sorted` within `range` (none when it is empty).
fn within(sorted: &[f64], (lo, hi): (f64, f64)) -> &[f64] {
    if lo.is_nan() || hi.is_nan() || lo > hi {
        return &sorted[..0];
    }
    let start = sorted.partition_point(|&d| d < lo);
    let end = sorted.partition_point(|&d| d <= hi).max(start);
    &sorted[start..end]
}

/// `d` clamped into `range`, unless that leaves nothing to move.
fn clamp_into(d: f64, (lo, hi): (f64, f64)) -> Option<f64> {
    if lo.is_nan() || hi.is_nan() || lo > hi {
        return None;
    }
    let d = d.max(lo).min(hi);
    (d != 0.0).then_some(d)
}

/// The over-relaxed closed-form optimum of the quadratic part a·d² + 2b·d, clamped to ±d_max.
fn closed_form(a: f64, b: f64, d_max: f64, with_optimum: bool) -> Option<f64> {
    if !(with_optimum && a > 0.0) {
        return None;
    }
    let opt = (-b / a * OVER_RELAXATION).clamp(-d_max, d_max);
    (opt != 0.0 && opt.is_finite()).then_some(opt)
}

/// The best of the quadratic part over the sampled displacements (sorted) and the optimum, the
/// first of equals kept. With a > 0 the parabola's samples fall away towards its vertex −b/a,
/// so only the two samples around it can be the best.
fn quadratic_best(a: f64, b: f64, sampled: &[f64], optimum: Option<f64>) -> Best {
    let mut best = Best { change: f64::INFINITY, delta: 0.0, curvature: a, b };
    let near = if a > 0.0 {
        let above = first_at_or_above(sampled, -b / a);
        &sampled[above.saturating_sub(1)..(above + 1).min(sampled.len())]
    } else {
        sampled
    };
    for &d in near.iter().chain(&optimum) {
        let change = a * d * d + 2.0 * b * d;
        if change < best.change {
            (best.change, best.delta) = (change, d);
        }
    }
    best
}

/// The first index of `sorted` whose value is not below `v` (its length if none): what
/// `partition_point(|&d| d < v)` finds, found here by interpolating between the ends and
/// stepping to the exact place — one or two steps when the values are evenly spread, as the
/// sampled displacements are, where a bisection is a chain of five dependent loads.
fn first_at_or_above(sorted: &[f64], v: f64) -> usize {
    let n = sorted.len();
    if n == 0 || v.is_nan() || v <= sorted[0] {
        return 0;
    }
    if v > sorted[n - 1] {
        return n;
    }
    let guess = ((v - sorted[0]) / (sorted[n - 1] - sorted[0]) * (n - 1) as f64) as usize;
    let mut at = guess.clamp(1, n - 1);
    while at < n && sorted[at] < v {
        at += 1;
    }
    while sorted[at - 1] >= v {
        at -= 1;
    }
    at
}

/// Σ x·y over every `stride`-th element, in four interleaved partial sums (a fixed order the
/// compiler can keep in registers, whatever the thread).
#[inline]
fn dot(x: &[f64], y: &[f64], stride: usize) -> f64 {
    let n = x.len().min(y.len());
    let (x, y) = (&x[..n], &y[..n]);
    let mut acc = [0.0f64; 4];
    if stride == 1 {
        // The same sums in the same order, over chunks the compiler needs no bounds checks in.
        let (xs, ys) = (x.chunks_exact(4), y.chunks_exact(4));
        let (xr, yr) = (xs.remainder(), ys.remainder());
        for (xc, yc) in xs.zip(ys) {
            for l in 0..4 {
                acc[l] += xc[l] * yc[l];
            }
        }
        for (a, b) in xr.iter().zip(yr) {
            acc[0] += a * b;
        }
        return (acc[0] + acc[1]) + (acc[2] + acc[3]);
    }
    let mut i = 0;
    while i + 3 * stride < n {
        for (l, a) in acc.iter_mut().enumerate() {
            *a += x[i + l * stride] * y[i + l * stride];
        }
        i += 4 * stride;
    }
    while i < n {
        acc[0] += x[i] * y[i];
        i += stride;
    }
    (acc[0] + acc[1]) + (acc[2] + acc[3])
}

/// Σ x·y·z over every `stride`-th element, as [`dot`].
#[inline]
fn dot3(x: &[f64], y: &[f64], z: &[f64], stride: usize) -> f64 {
    let n = x.len().min(y.len()).min(z.len());
    let mut sum = 0.0;
    let mut i = 0;
    while i < n {
        sum += x[i] * y[i] * z[i];
        i += stride;
    }
    sum
}

/// The sea level the pictures show: the first shape mask's water level, if there is a mask.
pub fn water_level(fields: &[Field]) -> Option<f64> {
    fields.iter().find_map(|f| match f.detail {
        Detail::ShapeMask { water_level, .. } => Some(water_level),
        _ => None,
    })
}

/// The splat map's material (`splatmap.png`'s alpha): 255 on the cells of every road, when
/// there is a road.
pub fn road_material(fields: &[Field], cells: usize) -> Option<Vec<u8>> {
    let mut out: Option<Vec<u8>> = None;
    for f in fields {
        if let Detail::Road(d) = &f.detail {
            road::mark(d, out.get_or_insert_with(|| vec![0; cells]));
        }
    }
    out
}

/// The samples the result must hold when the limits are on ([`super::projection`]), by
/// priority, lowest first ([`Priority`]): a mask's land above its water level plus the margin
/// and its sea below it less the margin (less of it within a cell of the coast); each point's sample; each terrace region's samples;
/// each road's cells; each seam's shared edge samples and the samples one step in (continuing
/// the neighbour) on their targets. Each held sample names its constraint.
pub fn held(fields: &[Field]) -> [Vec<Held>; PRIORITIES] {
    let mut tiers: [Vec<Held>; PRIORITIES] = Default::default();
    for (k, f) in fields.iter().enumerate() {
        let targets = |list: &[(usize, f64)]| list.iter().map(|&(i, t)| Held::at(i, t).of(k)).collect::<Vec<_>>();
        match &f.detail {
            Detail::Road(d) => tiers[Priority::Road as usize].extend(targets(road::cells(d))),
            Detail::Points(p) => tiers[Priority::Point as usize].extend(targets(p)),
            Detail::Terraces(d) => tiers[Priority::Terrace as usize].extend(targets(terraces::targets(d))),
            Detail::EdgeMatch(d) => {
                tiers[Priority::Seam as usize].extend(edge_match::seam(d).map(|(i, t)| Held::at(i, t).of(k)))
            }
            _ => {}
        }
        if let (Some(m), Detail::ShapeMask { water_level, shore, .. }) = (&f.one_sided, &f.detail) {
            // The margin, less within a cell of the coast ([`shape_mask`]'s `shore`).
            let lo = |i: usize| water_level + (m.lo - water_level) * shore[i];
            let hi = |i: usize| water_level - (water_level - m.hi) * shore[i];
            tiers[Priority::Mask as usize].extend(m.side.iter().enumerate().filter_map(|(i, &s)| match s {
                1 => Some(Held::between(i, lo(i), f64::INFINITY).of(k)),
                -1 => Some(Held::between(i, f64::NEG_INFINITY, hi(i)).of(k)),
                _ => None,
            }));
        }
    }
    tiers
}

/// Which held target wins where two cannot both be met, lowest first: a mask's coast gives way
/// to a point, a point to a terrace, a terrace to a road, and a road to a tile's seam (which
/// must meet its neighbour exactly). Within a tier, targets whose faces cross meet halfway
/// unless the tier is pinned ([`Priority::pinned`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Priority {
    Mask,
    Point,
    Terrace,
    Road,
    Seam,
}

pub const PRIORITIES: usize = 5;

impl Priority {
    /// Whether the tier's faces are earthworks (at the cut and fill slopes) rather than a coast
    /// or a seam's transition (at the slope limit). A terrace's are both: at the slope limit
    /// between its regions, then an apron at the earthworks' slopes around them.
    pub fn earthwork(self) -> bool {
        matches!(self, Priority::Point | Priority::Road)
    }

    /// Whether its samples take their targets even where its own faces cross (a road's legs
    /// at a hairpin, a seam's two rows on a slope steeper than the limit): the target is the
    /// shape asked for, not a wish to meet halfway. Abutting terraces far apart in level meet
    /// halfway at the slope limit instead (a one-cell riser's corners stood as spikes).
    pub fn pinned(self) -> bool {
        matches!(self, Priority::Road | Priority::Seam)
    }

    pub const ALL: [Priority; PRIORITIES] =
        [Priority::Mask, Priority::Point, Priority::Terrace, Priority::Road, Priority::Seam];
}

/// `road.json`: every road constraint (its index among the constraints) as a game places it,
/// when there is a road.
pub fn roads_json(fields: &[Field], h: &[f64], grid: &Grid) -> Option<Value> {
    let roads: Vec<Value> = fields
        .iter()
        .enumerate()
        .filter_map(|(i, f)| match &f.detail {
            Detail::Road(d) => {
                let mut road = road::centreline(d, h, grid);
                road["constraint"] = json!(i);
                Some(road)
            }
            _ => None,
        })
        .collect();
    (!roads.is_empty()).then(|| json!({ "roads": roads }))
}

/// The cells to refine candidates around: the union of every constraint's interest.
pub fn interest(fields: &[Field], cells: usize) -> Vec<bool> {
    union_of_interest(fields, cells)
}

/// The cells near which a wide kernel keeps every vertex rather than a coarser lattice: those
/// of narrow features (roads, seams, points) and of a mask's coastline, which the kernels'
/// places must follow closely.
pub fn placed_closely(fields: &[Field], cells: usize) -> Vec<bool> {
    union_of_interest(fields.iter().filter(|f| matches!(f.anchors, Anchors::Interest) || f.one_sided.is_some()), cells)
}

fn union_of_interest<'a>(fields: impl IntoIterator<Item = &'a Field>, cells: usize) -> Vec<bool> {
    let mut out = vec![false; cells];
    for f in fields {
        for (o, &i) in out.iter_mut().zip(&f.interest) {
            *o |= i;
        }
    }
    out
}

/// The cells of interest that are candidate vertices themselves, as (col, row, inside): a cell
/// inside an area (off its edges) takes the smallest few radii, the others every small one.
pub fn anchors(fields: &[Field], cols: usize) -> Vec<(usize, usize, bool)> {
    let mut out = Vec::new();
    for f in fields {
        let inside = |i: usize| matches!(&f.anchors, Anchors::Edges(edges) if !edges[i]);
        if !matches!(f.anchors, Anchors::None) {
            out.extend(f.interest.iter().enumerate().filter(|(_, &x)| x).map(|(i, _)| (i % cols, i / cols, inside(i))));
        }
    }
    out
}

/// Root-mean-square of `values`, 0 for none.
pub fn rms(values: impl IntoIterator<Item = f64>) -> f64 {
    let (mut sum, mut n) = (0.0, 0usize);
    for v in values {
        sum += v * v;
        n += 1;
    }
    if n == 0 {
        0.0
    } else {
        (sum / n as f64).sqrt()
    }
}

#[cfg(test)]
mod tests;
