//! Measures of a deformed terrain against its input, reckoned here from the heights alone
//! (not with the code under test): earthwork slopes beside what a designer laid down, closed
//! pits in a sea. Shared by `tests/deform_earthworks.rs` and `examples/deform_measures.rs`.

#![allow(dead_code)]

/// A heightfield as the measures read it.
pub struct Grid<'a> {
    pub h: &'a [f64],
    pub cols: usize,
    pub rows: usize,
    pub cell_m: f64,
}

impl Grid<'_> {
    /// The slope at sample (c, r), degrees, from central differences (one-sided at the edges).
    pub fn slope_deg(&self, c: usize, r: usize) -> f64 {
        let at = |c: usize, r: usize| self.h[r * self.cols + c];
        let d = |a: f64, b: f64, cells: usize| (b - a) / (cells as f64 * self.cell_m);
        let (c0, c1) = (c.saturating_sub(1), (c + 1).min(self.cols - 1));
        let (r0, r1) = (r.saturating_sub(1), (r + 1).min(self.rows - 1));
        let gx = d(at(c0, r), at(c1, r), c1 - c0);
        let gz = d(at(c, r0), at(c, r1), r1 - r0);
        gx.hypot(gz).atan().to_degrees()
    }
}

/// Distance from (x, z) to a polyline, metres.
pub fn to_path(path: &[(f64, f64)], x: f64, z: f64) -> f64 {
    if path.len() == 1 {
        return (x - path[0].0).hypot(z - path[0].1);
    }
    path.windows(2)
        .map(|w| {
            let ((x0, z0), (x1, z1)) = (w[0], w[1]);
            let (dx, dz) = (x1 - x0, z1 - z0);
            let t = (((x - x0) * dx + (z - z0) * dz) / (dx * dx + dz * dz)).clamp(0.0, 1.0);
            (x - x0 - t * dx).hypot(z - z0 - t * dz)
        })
        .fold(f64::INFINITY, f64::min)
}

/// Even-odd point in polygon.
pub fn inside(poly: &[(f64, f64)], x: f64, z: f64) -> bool {
    let mut inside = false;
    for k in 0..poly.len() {
        let (a, b) = (poly[k], poly[(k + 1) % poly.len()]);
        if (a.1 > z) != (b.1 > z) && x < a.0 + (z - a.1) / (b.1 - a.1) * (b.0 - a.0) {
            inside = !inside;
        }
    }
    inside
}

/// Distance from (x, z) to a polygon's outline (0 inside), metres.
pub fn to_polygon(poly: &[(f64, f64)], x: f64, z: f64) -> f64 {
    if inside(poly, x, z) {
        return 0.0;
    }
    let mut closed = poly.to_vec();
    closed.push(poly[0]);
    to_path(&closed, x, z)
}

/// What the earthworks measure counts beside the designed features.
#[derive(Debug, Default, Clone, Copy)]
pub struct Earthworks {
    /// Samples within reach of a feature (not on it) moved more than the threshold.
    pub moved: usize,
    /// Of those, lowered (cut) and raised (fill) samples steeper than their slope + margin.
    pub steep_cut: usize,
    pub steep_fill: usize,
    /// The steepest moved sample, degrees.
    pub steepest_deg: f64,
}

impl Earthworks {
    pub fn steep_share(&self) -> f64 {
        if self.moved == 0 {
            0.0
        } else {
            (self.steep_cut + self.steep_fill) as f64 / self.moved as f64
        }
    }
}

/// Samples whose distance to a feature (`distance(x, z)`, metres; 0 on it) is in (0, reach]
/// and which moved more than `moved_m` from the input: how many, and how many are steeper than
/// the cut slope (lowered) or the fill slope (raised) plus `margin_deg`.
#[allow(clippy::too_many_arguments)]
pub fn earthworks(
    input: &Grid,
    out: &Grid,
    distance: impl Fn(f64, f64) -> f64,
    reach_m: f64,
    moved_m: f64,
    cut_deg: f64,
    fill_deg: f64,
    margin_deg: f64,
) -> Earthworks {
    let mut e = Earthworks::default();
    for r in 0..out.rows {
        for c in 0..out.cols {
            let (x, z) = (c as f64 * out.cell_m, r as f64 * out.cell_m);
            let d = distance(x, z);
            if d <= 0.0 || d > reach_m {
                continue;
            }
            let i = r * out.cols + c;
            let change = out.h[i] - input.h[i];
            if change.abs() <= moved_m {
                continue;
            }
            e.moved += 1;
            let s = out.slope_deg(c, r);
            e.steepest_deg = e.steepest_deg.max(s);
            if change < 0.0 && s > cut_deg + margin_deg {
                e.steep_cut += 1;
            } else if change > 0.0 && s > fill_deg + margin_deg {
                e.steep_fill += 1;
            }
        }
    }
    e
}

/// 1V:xH as degrees.
pub fn degrees_of(h_per_v: f64) -> f64 {
    (1.0 / h_per_v).atan().to_degrees()
}

/// Per sample, how deep water poured on it would stand when it can drain only off the grid's
/// border: the priority-flood fill (Barnes et al. 2014) less the heights.
pub fn pit_depths(g: &Grid) -> Vec<f64> {
    use std::cmp::Reverse;
    use std::collections::BinaryHeap;
    let (cols, rows) = (g.cols, g.rows);
    // f64's total order as an integer (negative heights' bits flipped), for the heap.
    let key = |v: f64| {
        let b = v.to_bits() as i64;
        b ^ (((b >> 63) as u64) >> 1) as i64
    };
    let mut filled = vec![f64::NAN; cols * rows];
    let mut heap = BinaryHeap::new();
    for r in 0..rows {
        for c in 0..cols {
            if r == 0 || c == 0 || r == rows - 1 || c == cols - 1 {
                let i = r * cols + c;
                filled[i] = g.h[i];
                heap.push(Reverse((key(g.h[i]), i)));
            }
        }
    }
    while let Some(Reverse((_, i))) = heap.pop() {
        let (c, r) = (i % cols, i / cols);
        let level = filled[i];
        let mut visit = |j: usize| {
            if filled[j].is_nan() {
                filled[j] = g.h[j].max(level);
                heap.push(Reverse((key(filled[j]), j)));
            }
        };
        if c > 0 {
            visit(i - 1);
        }
        if c + 1 < cols {
            visit(i + 1);
        }
        if r > 0 {
            visit(i - cols);
        }
        if r + 1 < rows {
            visit(i + cols);
        }
    }
    filled.iter().zip(g.h).map(|(f, h)| f - h).collect()
}

/// The share of the samples below `level` (the sea) that lie in closed pits deeper than
/// `depth_m`.
pub fn sea_pit_share(g: &Grid, level: f64, depth_m: f64) -> f64 {
    let depths = pit_depths(g);
    let (mut sea, mut pits) = (0usize, 0usize);
    for (h, d) in g.h.iter().zip(&depths) {
        if *h < level {
            sea += 1;
            pits += usize::from(*d > depth_m);
        }
    }
    if sea == 0 {
        0.0
    } else {
        pits as f64 / sea as f64
    }
}

/// The contour of `g` at `level` (marching squares; above: h ≥ level) as polylines of points
/// in cells, each a chain of crossings on the grid's edges.
pub fn contours(g: &Grid, level: f64) -> Vec<Vec<(f64, f64)>> {
    use std::collections::HashMap;
    let (cols, rows) = (g.cols, g.rows);
    let above = |c: usize, r: usize| g.h[r * cols + c] >= level;
    // An edge's id: 2 × its first sample, + 1 for the edge down a column.
    let point = |id: usize| {
        let (i, down) = (id / 2, id % 2 == 1);
        let (c, r) = (i % cols, i / cols);
        let (j, dc, dr) = if down { (i + cols, 0.0, 1.0) } else { (i + 1, 1.0, 0.0) };
        let t = (level - g.h[i]) / (g.h[j] - g.h[i]);
        (c as f64 + t * dc, r as f64 + t * dr)
    };
    let mut links: HashMap<usize, Vec<usize>> = HashMap::new();
    let mut link = |a: usize, b: usize| {
        links.entry(a).or_default().push(b);
        links.entry(b).or_default().push(a);
    };
    for r in 0..rows - 1 {
        for c in 0..cols - 1 {
            let i = r * cols + c;
            // The cell's edges in order round it: top, right, bottom, left.
            let edges = [2 * i, 2 * (i + 1) + 1, 2 * (i + cols), 2 * i + 1];
            let corners = [above(c, r), above(c + 1, r), above(c + 1, r + 1), above(c, r + 1)];
            let crossed: Vec<usize> =
                (0..4).filter(|&k| corners[k] != corners[(k + 1) % 4]).map(|k| edges[k]).collect();
            match crossed.len() {
                2 => link(crossed[0], crossed[1]),
                4 => {
                    // A saddle: the centre's mean decides which corners join.
                    let centre = (g.h[i] + g.h[i + 1] + g.h[i + cols] + g.h[i + cols + 1]) / 4.0;
                    if (centre >= level) == corners[0] {
                        link(crossed[0], crossed[1]);
                        link(crossed[2], crossed[3]);
                    } else {
                        link(crossed[3], crossed[0]);
                        link(crossed[1], crossed[2]);
                    }
                }
                _ => {}
            }
        }
    }
    let mut seen = std::collections::HashSet::new();
    let mut starts: Vec<usize> = links.iter().filter(|(_, l)| l.len() == 1).map(|(&k, _)| k).collect();
    starts.sort_unstable();
    let mut rest: Vec<usize> = links.keys().copied().collect();
    rest.sort_unstable();
    starts.extend(rest);
    let mut out = Vec::new();
    for s in starts {
        if !seen.insert(s) {
            continue;
        }
        let mut chain = vec![point(s)];
        let mut at = s;
        while let Some(&next) = links[&at].iter().find(|n| !seen.contains(n)) {
            seen.insert(next);
            chain.push(point(next));
            at = next;
        }
        if links[&at].contains(&s) && chain.len() > 2 {
            chain.push(chain[0]);
        }
        out.push(chain);
    }
    out
}

/// A coastline's high-pass roughness: each contour at `level` resampled every half cell, and
/// the root mean square distance of its points from their running mean over `window_cells`
/// of arc on each side (points that far from an open contour's ends only), in cells. Contours
/// shorter than four windows are left out.
pub fn coast_roughness(g: &Grid, level: f64, window_cells: f64) -> (f64, usize) {
    let step = 0.5;
    let half = (window_cells / step).round() as usize;
    let (mut sum, mut count) = (0.0, 0usize);
    for chain in contours(g, level) {
        let mut pts = vec![chain[0]];
        let mut carry = 0.0;
        for w in chain.windows(2) {
            let ((x0, z0), (x1, z1)) = (w[0], w[1]);
            let len = (x1 - x0).hypot(z1 - z0);
            let mut t = step - carry;
            while t <= len {
                pts.push((x0 + (x1 - x0) * t / len, z0 + (z1 - z0) * t / len));
                t += step;
            }
            carry = len - (t - step);
        }
        if pts.len() < 8 * half {
            continue;
        }
        let closed = chain.first() == chain.last();
        let n = pts.len();
        let range: Box<dyn Iterator<Item = usize>> = if closed { Box::new(0..n) } else { Box::new(half..n - half) };
        for k in range {
            let (mut mx, mut mz) = (0.0, 0.0);
            for d in 0..=2 * half {
                let j = if closed { (k + n + d - half) % n } else { k + d - half };
                mx += pts[j].0;
                mz += pts[j].1;
            }
            let m = (2 * half + 1) as f64;
            let (dx, dz) = (pts[k].0 - mx / m, pts[k].1 - mz / m);
            sum += dx * dx + dz * dz;
            count += 1;
        }
    }
    (if count == 0 { 0.0 } else { (sum / count as f64).sqrt() }, count)
}

/// Samples more than `off_m` from the median of their 5 × 5 neighbourhood (clipped at the
/// border): spikes and beads.
pub fn spikes(g: &Grid, off_m: f64) -> usize {
    let mut count = 0;
    let mut window = Vec::with_capacity(25);
    for r in 0..g.rows {
        for c in 0..g.cols {
            window.clear();
            for rr in r.saturating_sub(2)..(r + 3).min(g.rows) {
                for cc in c.saturating_sub(2)..(c + 3).min(g.cols) {
                    window.push(g.h[rr * g.cols + cc]);
                }
            }
            window.sort_by(f64::total_cmp);
            let median = window[window.len() / 2];
            count += usize::from((g.h[r * g.cols + c] - median).abs() > off_m);
        }
    }
    count
}
