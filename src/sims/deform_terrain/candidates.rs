//! Candidate vertices (paper §3.3, Figure 2): a coarse uniform grid over the whole terrain,
//! plus quadtree subdivision wherever a quad holds a constrained cell of interest, down to a
//! smallest spacing, adding each quad's centre.

/// Vertices as (col, row), sorted by (row, col), without duplicates.
pub fn candidate_vertices(
    interest: &[bool],
    cols: usize,
    rows: usize,
    coarse: usize,
    min_spacing: usize,
) -> Vec<(usize, usize)> {
    let coarse = coarse.max(1);
    let min_spacing = min_spacing.max(1);
    // Summed-area table of interest: any-interest in a quad in O(1).
    let mut sat = vec![0u32; (cols + 1) * (rows + 1)];
    for r in 0..rows {
        let mut run = 0;
        for c in 0..cols {
            run += interest[r * cols + c] as u32;
            sat[(r + 1) * (cols + 1) + c + 1] = sat[r * (cols + 1) + c + 1] + run;
        }
    }
    let any = |c0: usize, r0: usize, c1: usize, r1: usize| {
        let (c1, r1) = (c1.min(cols - 1) + 1, r1.min(rows - 1) + 1);
        let w = cols + 1;
        sat[r1 * w + c1] + sat[r0 * w + c0] > sat[r0 * w + c1] + sat[r1 * w + c0]
    };
    let axis = |n: usize| {
        let mut v: Vec<usize> = (0..n).step_by(coarse).collect();
        if *v.last().unwrap() != n - 1 {
            v.push(n - 1);
        }
        v
    };
    let (xs, zs) = (axis(cols), axis(rows));
    let mut out: Vec<(usize, usize)> = Vec::new();
    for &r in &zs {
        for &c in &xs {
            out.push((c, r));
        }
    }
    let mut stack: Vec<(usize, usize, usize, usize)> = Vec::new();
    for zw in zs.windows(2) {
        for xw in xs.windows(2) {
            stack.push((xw[0], zw[0], xw[1], zw[1]));
        }
    }
    while let Some((c0, r0, c1, r1)) = stack.pop() {
        let size = (c1 - c0).max(r1 - r0);
        if size <= min_spacing || !any(c0, r0, c1, r1) {
            continue;
        }
        let (cm, rm) = ((c0 + c1) / 2, (r0 + r1) / 2);
        out.push((cm, rm));
        stack.extend([(c0, r0, cm, rm), (cm, r0, c1, rm), (c0, rm, cm, r1), (cm, rm, c1, r1)]);
    }
    out.sort_by_key(|&(c, r)| (r, c));
    out.dedup();
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vertices_concentrate_around_interest() {
        let (cols, rows) = (65, 65);
        let mut interest = vec![false; cols * rows];
        interest[40 * cols + 20] = true;
        let v = candidate_vertices(&interest, cols, rows, 16, 2);
        let near = v.iter().filter(|&&(c, r)| c.abs_diff(20) <= 8 && r.abs_diff(40) <= 8).count();
        assert_eq!(v.iter().filter(|&&(c, r)| c % 16 == 0 && r % 16 == 0).count(), 25);
        assert!(near >= 9, "{near}");
        assert!(v.contains(&(20, 40)) || v.contains(&(18, 38)) || v.contains(&(22, 42)), "{v:?}");
        let mut sorted = v.clone();
        sorted.sort_by_key(|&(c, r)| (r, c));
        sorted.dedup();
        assert_eq!(sorted, v);
    }
}
