//! Landform measures written for the tests, apart from the erode kind's own (`metrics.rs`): a
//! Priority-Flood of our own, steepest-descent drainage, a slope–area fit, drainage density,
//! slopes and aspects from Horn's gradient, and erosion statistics. Shared by
//! `tests/erode_landform.rs` and `examples/erode_measures.rs`.
#![allow(dead_code)]

use std::cmp::Ordering;
use std::collections::BinaryHeap;

use landform::terrain::Heightfield;

/// A grid of f64 heights with its cell size.
#[derive(Clone)]
pub struct Surface {
    pub cols: usize,
    pub rows: usize,
    pub cell: f64,
    pub h: Vec<f64>,
}

const N8: [(isize, isize); 8] = [(-1, -1), (0, -1), (1, -1), (-1, 0), (1, 0), (-1, 1), (0, 1), (1, 1)];

impl Surface {
    pub fn of(hf: &Heightfield) -> Self {
        Self {
            cols: hf.cols,
            rows: hf.rows,
            cell: f64::from(hf.cell_size_m),
            h: hf.heights_m.iter().map(|&x| f64::from(x)).collect(),
        }
    }

    fn nb(&self, i: usize, k: usize) -> Option<usize> {
        let (c, r) = ((i % self.cols) as isize, (i / self.cols) as isize);
        let (nc, nr) = (c + N8[k].0, r + N8[k].1);
        (nc >= 0 && nr >= 0 && (nc as usize) < self.cols && (nr as usize) < self.rows)
            .then(|| nr as usize * self.cols + nc as usize)
    }

    fn len(&self, k: usize) -> f64 {
        if N8[k].0 != 0 && N8[k].1 != 0 {
            self.cell * std::f64::consts::SQRT_2
        } else {
            self.cell
        }
    }

    fn border(&self, i: usize) -> bool {
        let (c, r) = (i % self.cols, i / self.cols);
        c == 0 || r == 0 || c + 1 == self.cols || r + 1 == self.rows
    }

    /// Land: above `sea` and off the border.
    pub fn land(&self, sea: f64) -> Vec<bool> {
        (0..self.h.len()).map(|i| !self.border(i) && self.h[i] > sea).collect()
    }

    /// Horn's (1981) gradient (∂z/∂x, ∂z/∂y) at an inner cell.
    pub fn horn(&self, i: usize) -> (f64, f64) {
        let z = |dc: isize, dr: isize| self.h[(i as isize + dr * self.cols as isize + dc) as usize];
        let gx = ((z(1, -1) + 2.0 * z(1, 0) + z(1, 1)) - (z(-1, -1) + 2.0 * z(-1, 0) + z(-1, 1))) / (8.0 * self.cell);
        let gy = ((z(-1, 1) + 2.0 * z(0, 1) + z(1, 1)) - (z(-1, -1) + 2.0 * z(0, -1) + z(1, -1))) / (8.0 * self.cell);
        (gx, gy)
    }

    /// The share of `mask` cells whose Horn slope is steeper than `deg`.
    pub fn steeper_share(&self, mask: &[bool], deg: f64) -> f64 {
        let t = deg.to_radians().tan();
        let (mut n, mut steep) = (0usize, 0usize);
        for i in (0..self.h.len()).filter(|&i| mask[i] && !self.border(i)) {
            n += 1;
            let (gx, gy) = self.horn(i);
            steep += usize::from(gx.hypot(gy) > t);
        }
        steep as f64 / n.max(1) as f64
    }

    /// The slope-weighted four-fold aspect harmonic over `mask`: |Σ s·e^{4iφ}| / Σ s, φ the
    /// aspect. 0 for slopes facing every way alike; 1 when all face the grid's four axes (or all
    /// its diagonals).
    pub fn aspect_harmonic(&self, mask: &[bool]) -> f64 {
        let (mut re, mut im, mut w) = (0.0, 0.0, 0.0);
        for i in (0..self.h.len()).filter(|&i| mask[i] && !self.border(i)) {
            let (gx, gy) = self.horn(i);
            let s = gx.hypot(gy);
            if s < 1e-6 {
                continue;
            }
            let phi = gy.atan2(gx);
            re += s * (4.0 * phi).cos();
            im += s * (4.0 * phi).sin();
            w += s;
        }
        re.hypot(im) / w
    }

    /// Plain Priority-Flood (Barnes et al. 2014, Alg. 1) from the border and cells at or below
    /// `sea`: every cell raised to its spill height.
    pub fn filled(&self, sea: f64) -> Vec<f64> {
        #[derive(PartialEq)]
        struct Cell(f64, usize);
        impl Eq for Cell {}
        impl PartialOrd for Cell {
            fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
                Some(self.cmp(o))
            }
        }
        impl Ord for Cell {
            fn cmp(&self, o: &Self) -> Ordering {
                o.0.total_cmp(&self.0).then(o.1.cmp(&self.1))
            }
        }
        let mut w = self.h.clone();
        let mut done = vec![false; w.len()];
        let mut heap = BinaryHeap::new();
        for i in 0..w.len() {
            if self.border(i) || w[i] <= sea {
                done[i] = true;
                heap.push(Cell(w[i], i));
            }
        }
        while let Some(Cell(hc, c)) = heap.pop() {
            for k in 0..8 {
                if let Some(n) = self.nb(c, k) {
                    if !done[n] {
                        done[n] = true;
                        w[n] = w[n].max(hc);
                        heap.push(Cell(w[n], n));
                    }
                }
            }
        }
        w
    }

    /// The share of land cells a fill raises by more than 1 mm.
    pub fn pit_share(&self, sea: f64) -> f64 {
        let f = self.filled(sea);
        let land = self.land(sea);
        let n = land.iter().filter(|&&l| l).count();
        let pits = (0..f.len()).filter(|&i| land[i] && f[i] - self.h[i] > 1e-3).count();
        pits as f64 / n.max(1) as f64
    }
}

/// Steepest-descent drainage of land cells: receiver, slope to it, area (m²), longest path (m).
pub struct Drainage {
    pub receiver: Vec<Option<usize>>,
    pub slope: Vec<f64>,
    pub area: Vec<f64>,
    pub length: Vec<f64>,
    pub land: Vec<bool>,
}

impl Drainage {
    pub fn new(s: &Surface, sea: f64) -> Self {
        let n = s.h.len();
        let land = s.land(sea);
        let mut receiver = vec![None; n];
        let mut slope = vec![0.0; n];
        for i in (0..n).filter(|&i| land[i]) {
            for k in 0..8 {
                let j = s.nb(i, k).unwrap();
                let d = (s.h[i] - s.h[j]) / s.len(k);
                if d > slope[i] {
                    slope[i] = d;
                    receiver[i] = Some(j);
                }
            }
        }
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by(|&a, &b| s.h[b].total_cmp(&s.h[a]).then(a.cmp(&b)));
        let a0 = s.cell * s.cell;
        let mut area = vec![a0; n];
        let mut length = vec![0.0f64; n];
        for &i in &order {
            if let Some(j) = receiver[i] {
                area[j] += area[i];
                let step = if (i % s.cols) != (j % s.cols) && (i / s.cols) != (j / s.cols) {
                    s.cell * std::f64::consts::SQRT_2
                } else {
                    s.cell
                };
                length[j] = length[j].max(length[i] + step);
            }
        }
        Self { receiver, slope, area, length, land }
    }

    /// Channel cells: land draining at least `min_area_m2`.
    fn channels(&self, min_area_m2: f64) -> impl Iterator<Item = usize> + '_ {
        (0..self.area.len()).filter(move |&i| self.land[i] && self.area[i] >= min_area_m2 && self.slope[i] > 1e-4)
    }

    /// Channel concavity θ: S ∝ A^−θ, a least-squares line through the medians of log S in
    /// bins of a tenth of a decade of A (at least 10 cells a bin), on channel cells.
    pub fn concavity(&self, min_area_m2: f64) -> Option<f64> {
        concavity_of(&self.slope_area(min_area_m2))
    }

    /// (log₁₀ A, log₁₀ S) of every channel cell, to pool over several terrains.
    pub fn slope_area(&self, min_area_m2: f64) -> Vec<(f64, f64)> {
        self.channels(min_area_m2).map(|i| (self.area[i].log10(), self.slope[i].log10())).collect()
    }

    /// Channel length (m) and land area (m²), to pool drainage density over several terrains.
    pub fn channel_length_and_land(&self, s: &Surface, min_area_m2: f64) -> (f64, f64) {
        let mut length = 0.0;
        for i in self.channels(min_area_m2) {
            let j = self.receiver[i].unwrap();
            let diag = (i % s.cols) != (j % s.cols) && (i / s.cols) != (j / s.cols);
            length += if diag { s.cell * std::f64::consts::SQRT_2 } else { s.cell };
        }
        (length, self.land.iter().filter(|&&l| l).count() as f64 * s.cell * s.cell)
    }

    /// Hack's exponent: L ∝ A^h on channel cells, binned the same way.
    pub fn hack(&self, min_area_m2: f64) -> Option<f64> {
        let pts: Vec<(f64, f64)> = self
            .channels(min_area_m2)
            .filter(|&i| self.length[i] > 0.0)
            .map(|i| (self.area[i].log10(), self.length[i].log10()))
            .collect();
        binned_fit(&pts)
    }

    /// Drainage density: channel length (each channel cell's link to its receiver) per land
    /// area, 1/m.
    pub fn density(&self, s: &Surface, min_area_m2: f64) -> f64 {
        let (length, land) = self.channel_length_and_land(s, min_area_m2);
        length / land
    }
}

/// θ of (log₁₀ A, log₁₀ S) points, fitted as [`Drainage::concavity`] fits one terrain's.
pub fn concavity_of(pts: &[(f64, f64)]) -> Option<f64> {
    binned_fit(pts).map(|b| -b)
}

/// Slope of the least-squares line through the bins' medians.
fn binned_fit(pts: &[(f64, f64)]) -> Option<f64> {
    use std::collections::BTreeMap;
    let mut bins: BTreeMap<i64, Vec<(f64, f64)>> = BTreeMap::new();
    for &(x, y) in pts {
        bins.entry((x * 10.0).floor() as i64).or_default().push((x, y));
    }
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let meds: Vec<(f64, f64)> = bins
        .into_values()
        .filter(|b| b.len() >= 10)
        .map(|b| (median(b.iter().map(|p| p.0).collect()), median(b.iter().map(|p| p.1).collect())))
        .collect();
    if meds.len() < 3 {
        return None;
    }
    let n = meds.len() as f64;
    let (mx, my) = (meds.iter().map(|p| p.0).sum::<f64>() / n, meds.iter().map(|p| p.1).sum::<f64>() / n);
    let sxy: f64 = meds.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let sxx: f64 = meds.iter().map(|p| (p.0 - mx).powi(2)).sum();
    Some(sxy / sxx)
}

/// Erosion statistics of `after` against `before` over `mask`: mean lowering (m; deposition
/// counts as negative lowering), and each cell's lowering.
pub fn lowering(before: &Surface, after: &Surface, mask: &[bool]) -> (f64, Vec<f64>) {
    let d: Vec<f64> = before.h.iter().zip(&after.h).map(|(a, b)| a - b).collect();
    let (sum, n) = d.iter().zip(mask).filter(|(_, &m)| m).fold((0.0, 0usize), |(s, n), (&x, _)| (s + x, n + 1));
    (sum / n.max(1) as f64, d)
}

/// RMS over `mask` of the difference of two lowering maps, over the first map's mean |lowering|.
pub fn rms_share(a: &[f64], b: &[f64], mask: &[bool]) -> f64 {
    let (mut sq, mut abs, mut n) = (0.0, 0.0, 0usize);
    for i in (0..a.len()).filter(|&i| mask[i]) {
        sq += (a[i] - b[i]).powi(2);
        abs += a[i].abs();
        n += 1;
    }
    (sq / n as f64).sqrt() / (abs / n as f64)
}

/// `hf` turned by `deg` about its centre, sampled bilinearly on the same grid; outside the
/// turned square, `outside`.
pub fn rotated(hf: &Heightfield, deg: f64, outside: f32) -> Heightfield {
    let (sin, cos) = deg.to_radians().sin_cos();
    let (cx, cy) = ((hf.cols - 1) as f64 / 2.0, (hf.rows - 1) as f64 / 2.0);
    let mut out = hf.clone();
    for r in 0..hf.rows {
        for c in 0..hf.cols {
            let (x, y) = (c as f64 - cx, r as f64 - cy);
            // Where this sample came from in the input.
            let (sx, sy) = (cos * x + sin * y + cx, -sin * x + cos * y + cy);
            let v = if sx < 0.0 || sy < 0.0 || sx > (hf.cols - 1) as f64 || sy > (hf.rows - 1) as f64 {
                outside
            } else {
                let (c0, r0) = ((sx.floor() as usize).min(hf.cols - 2), (sy.floor() as usize).min(hf.rows - 2));
                let (fx, fy) = (sx - c0 as f64, sy - r0 as f64);
                let z = |c: usize, r: usize| f64::from(hf.heights_m[r * hf.cols + c]);
                let top = z(c0, r0) * (1.0 - fx) + z(c0 + 1, r0) * fx;
                let bottom = z(c0, r0 + 1) * (1.0 - fx) + z(c0 + 1, r0 + 1) * fx;
                (top * (1.0 - fy) + bottom * fy) as f32
            };
            out.heights_m[r * hf.cols + c] = v;
        }
    }
    out
}

/// An island that can be turned exactly: a cone falling from `relief` m at the centre to the sea
/// floor (−0.2 × `relief`) at 0.46 of the grid's width (land to 0.38), roughened by 96 plane waves of random
/// direction and phase with wavelengths from 8 cells to half the grid (amplitude ∝ wavelength^1.5,
/// a fractal's spectrum), evaluated at each sample turned by `deg` about the centre. Sampled,
/// never resampled: the 30° island is the same function as the 0° one, not a smoothed copy.
/// The island stays inside the inscribed circle, so no corner of the turned grid is land.
pub fn wavy_island(size: usize, cell: f64, relief: f64, seed: u64, deg: f64) -> Heightfield {
    let mut s = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    let mut next = || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 11) as f64 / (1u64 << 53) as f64
    };
    let width = (size - 1) as f64 * cell;
    let waves: Vec<(f64, f64, f64, f64)> = (0..96)
        .map(|_| {
            let lambda = 8.0 * cell * (width / 2.0 / (8.0 * cell)).powf(next());
            let dir = next() * std::f64::consts::TAU;
            let amp = lambda.powf(1.5);
            (
                dir.cos() * std::f64::consts::TAU / lambda,
                dir.sin() * std::f64::consts::TAU / lambda,
                amp,
                next() * std::f64::consts::TAU,
            )
        })
        .collect();
    let norm = (waves.iter().map(|w| w.2 * w.2 / 2.0).sum::<f64>()).sqrt();
    let (sin, cos) = deg.to_radians().sin_cos();
    let centre = width / 2.0;
    let radius = 0.38 * width;
    let mut hf = Heightfield::flat(size, size, cell as f32, 0.0);
    for r in 0..size {
        for c in 0..size {
            let (x, y) = (c as f64 * cell - centre, r as f64 * cell - centre);
            // Where this sample lies on the unturned island.
            let (u, v) = (cos * x + sin * y, -sin * x + cos * y);
            let rough: f64 = waves.iter().map(|&(kx, ky, a, p)| a * (kx * u + ky * v + p).cos()).sum::<f64>() / norm;
            let d = (u * u + v * v).sqrt() / radius;
            let cone = 1.0 - d;
            let taper = (1.0 - d * d).max(0.0);
            let h = relief * (cone + 0.25 * rough * taper).max(-0.2);
            hf.heights_m[r * size + c] = h as f32;
        }
    }
    hf
}
