//! Stochastic local search over deformations (paper §3.3–3.5).
//!
//! The table holds, for every (candidate vertex, radius), its best change in fitness over the
//! sampled displacements (and the closed-form best of the quadratic penalties). Each iteration
//! chooses one entry — the best with probability p, otherwise one drawn uniformly from the top
//! fraction — then, up to `batch` in all, further improving entries best first whose windows
//! no change taken so far this iteration reaches (penalties are per vertex, so their changes
//! stay exact and add); it applies them in that order, each recorded as its own operation, and
//! recomputes only the entries whose window meets the changed cells (or their coupled partners
//! across a tileable terrain). Every entry's change depends only on its
//! window, so cached entries stay exact. Recomputation runs in parallel and is collected in
//! order; the only draws are the selection's, from one seeded stream, so the result does not
//! depend on the thread count.
//!
//! Wide windows are estimated on a sparser lattice. An estimate only ranks: when the choice
//! reaches an estimated entry it is checked on its full window — its best displacement there,
//! not the estimate's — and if it is then no longer ahead of the entry after it, it goes back
//! to its place in the order (lazy greedy), so what is applied is chosen on exact changes.
//! (Checking only the estimate's displacement, over-relaxed, failed 97–99 % of the checks on
//! the examples and left those entries to be estimated, reached and refused again.) An
//! entry's estimates are ranked scaled by what its last check found of them (the exact change
//! over the estimate), a scale that goes back towards 1 at each recomputation: a wide window
//! whose lattice overstates it does not crowd the head iteration after iteration, and is still
//! looked at again later. With
//! only quadratic penalties an entry's change depends on the heights through one sum b, which
//! is brought up to date from the residual's change over each deformed window rather than
//! summed again.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::Serialize;

use super::constraints::{Best, Field, Fitness};
use super::kernel::{self, Kernel, Rect};
use super::prediction;
use super::sequence::Deformation;

/// The search's settings, resolved against the grid.
pub struct Settings {
    pub max_iterations: u32,
    pub epsilon: f64,
    /// Stop when F fell by less than `stall_gain` of itself over this many iterations (0: never).
    pub stall_iterations: u32,
    pub stall_gain: f64,
    pub p: f64,
    pub top_fraction: f64,
    pub prediction: bool,
    pub prediction_constant: f64,
    /// Most deformations applied per iteration (1: the paper's one).
    pub batch: usize,
    pub kernels: Vec<Kernel>,
    /// Per radius: the sampled displacements (metres) and the largest allowed, ±d_max.
    pub deltas: Vec<Vec<f64>>,
    pub d_max: Vec<f64>,
    pub cell_m: f64,
    pub tile_x: bool,
    pub tile_z: bool,
}

/// Radii in cells: `count` geometric steps from `min` to `max`, rounded, without repeats.
pub fn radii(min: usize, max: usize, count: usize) -> Vec<usize> {
    let (min, max) = (min.max(1), max.max(min.max(1)));
    let mut out: Vec<usize> = (0..count)
        .map(|k| {
            let t = if count > 1 { k as f64 / (count - 1) as f64 } else { 1.0 };
            ((min as f64) * (max as f64 / min as f64).powf(t)).round() as usize
        })
        .collect();
    out.dedup();
    out
}

/// `count` displacements as shares of the largest, spread evenly over [−1, 1], zero excluded.
pub fn unit_displacements(count: usize) -> Vec<f64> {
    if count <= 1 {
        return vec![1.0];
    }
    (0..count).map(|k| -1.0 + 2.0 * k as f64 / (count - 1) as f64).filter(|u| u.abs() > 1e-12).collect()
}

/// How far down the improving entries are sorted up front, per deformation in a batch: the
/// batch passes over entries whose windows meet those already taken.
const HEAD_PER_BATCH: usize = 32;

/// Windows larger than this many cells a side are estimated on a sparser lattice, at most
/// this many samples a side; an estimate only ranks, and is checked exactly before it is
/// applied. 13 (was 25) halved the table's recomputation on the examples at no loss of
/// fitness (`benches/deform_against.sh`); 12, with the estimates' scale relaxing at 0.05 (see
/// [`TRUST_RELAXATION`]), reached a lower fitness on the roads (S-road 2.09e-5 against 2.21e-5 at
/// 13 and 0.1; star island with roads 2.186e-3 against 2.190e-3) for 2–3 % more
/// evaluations on the terraces. Differences of this size are within the spread between seeds.
const EXACT_SIDE: usize = 12;

fn stride(radius: usize) -> usize {
    (2 * radius + 1).div_ceil(EXACT_SIDE).max(1)
}

/// The per-iteration record for `fitness.json`.
#[derive(Clone, Debug, Serialize)]
pub struct Record {
    pub iteration: u64,
    pub total: f64,
    pub constraints: Vec<f64>,
}

/// Tracks each constraint's fitness as deformations apply, updating over the changed window
/// only. The run and the replay both apply through it, so their heights and records match.
pub struct Tracker<'a> {
    pub fields: &'a [Field],
    pub values: Vec<f64>,
    pub history: Vec<Record>,
    pub cols: usize,
    pub rows: usize,
}

impl<'a> Tracker<'a> {
    pub fn new(fields: &'a [Field], h: &[f64], cols: usize, rows: usize) -> Self {
        let values: Vec<f64> = fields.par_iter().map(|f| f.value(h, cols, rows)).collect();
        let mut t = Self { fields, values, history: Vec::new(), cols, rows };
        t.record(0);
        t
    }

    pub fn total(&self) -> f64 {
        self.fields.iter().zip(&self.values).map(|(f, v)| f.weight * v).sum()
    }

    fn record(&mut self, iteration: u64) {
        self.history.push(Record { iteration, total: self.total(), constraints: self.values.clone() });
    }

    /// Apply one deformation and record the fitness after it; returns the changed cells' rect.
    pub fn apply(&mut self, h: &mut [f64], op: &Deformation, kernel: &Kernel) -> Rect {
        let (col, row) = (op.col as usize, op.row as usize);
        let rect = Rect::around(col, row, kernel.radius, self.cols, self.rows);
        let before: Vec<f64> = self.fields.iter().map(|f| f.window_value(h, rect, self.cols)).collect();
        kernel::apply(h, self.cols, self.rows, col, row, op.amplitude as f64, kernel);
        for ((f, v), b) in self.fields.iter().zip(self.values.iter_mut()).zip(before) {
            *v += f.window_value(h, rect, self.cols) - b;
        }
        let next = self.history.len() as u64;
        self.record(next);
        rect
    }
}

/// One entry of the table.
#[derive(Clone, Copy, Debug)]
struct Entry {
    col: u32,
    row: u32,
    radius: u8,
    delta: f64,
    /// The quadratic part's curvature at this place and stride (NaN until first evaluated):
    /// it never changes, so it is summed once.
    curvature: f64,
    /// The same on the full lattice, for the exact check of an estimate (NaN until needed).
    exact_curvature: f64,
    /// The quadratic part's sum b as of its last recomputation (current unless `missed`).
    b: f64,
    /// Whether the entry's key (its change) and `delta` are the exact ones on the full window,
    /// as of now.
    checked: bool,
    /// What the last exact check found of this entry's estimate: the exact best change over the
    /// estimated one. Estimates are ranked scaled by it (1 until checked).
    trust: f64,
}

/// One row of one radius's entries, in column order.
#[derive(Clone, Default)]
struct Row {
    cols: Vec<u32>,
    entries: Vec<u32>,
}

/// Why the search stopped.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Stop {
    Epsilon,
    MaxIterations,
    NoImprovement,
    Stalled,
}

/// What the search did.
pub struct Searched {
    pub operations: Vec<Deformation>,
    /// Iterations run; each applied 1 to `batch` of the operations.
    pub iterations: u64,
    pub evaluations: u64,
    pub stop: Stop,
}

/// Who follows the search between iterations.
pub trait Watch {
    type Stop;
    fn check(&self) -> Result<(), Self::Stop>;
    fn progress(&self, iteration: u64, total: u64, fitness: f64, h: &[f64]);
}

/// Run the search from `h`, applying through `tracker`; each vertex (col, row, radii) is tried
/// with the radii whose bits are set.
pub fn search<W: Watch>(
    h: &mut [f64],
    fitness: &Fitness,
    tracker: &mut Tracker,
    vertices: &[(usize, usize, u32)],
    s: &Settings,
    seed: u64,
    watch: &W,
) -> Result<Searched, W::Stop> {
    let (cols, rows) = (fitness.cols, fitness.rows);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut table: Vec<Entry> = vertices
        .iter()
        .flat_map(|&(c, r, radii)| {
            (0..s.kernels.len()).filter(move |k| radii & (1 << k) != 0).map(move |k| Entry {
                col: c as u32,
                row: r as u32,
                radius: k as u8,
                delta: 0.0,
                curvature: f64::NAN,
                exact_curvature: f64::NAN,
                b: f64::NAN,
                checked: false,
                trust: 1.0,
            })
        })
        .collect();
    let mut residual = fitness.residual(h);
    let eval = |h: &[f64], residual: &[f64], e: &Entry| {
        let k = e.radius as usize;
        let kernel = &s.kernels[k];
        fitness.best_change(
            h,
            residual,
            e.col as usize,
            e.row as usize,
            kernel,
            stride(kernel.radius),
            &s.deltas[k],
            s.d_max[k],
            true,
            (!e.curvature.is_nan()).then_some(e.curvature),
            super::constraints::ANY,
        )
    };
    // Per radius and row, the entries in column order: what a change can reach is found
    // without scanning the table.
    let reach: Vec<usize> = s.kernels.iter().map(|k| k.radius).collect();
    // Each row keeps its entries' columns beside their indices, so the search for the first
    // column in reach runs over contiguous memory rather than through the table.
    let mut by_radius: Vec<Vec<Row>> = vec![vec![Row::default(); rows]; reach.len()];
    let mut order: Vec<usize> = (0..table.len()).collect();
    order.sort_by_key(|&i| (table[i].row, table[i].col));
    for i in order {
        let t = &table[i];
        let row = &mut by_radius[t.radius as usize][t.row as usize];
        row.cols.push(t.col);
        row.entries.push(i as u32);
    }
    // Each entry's change while it is current, +∞ once a change reaches it: what the choice
    // scans and sorts by, apart from the table, so the scans and the sort's comparisons run
    // over 8 bytes an entry instead of through the table's cache lines.
    let mut keys = vec![f64::INFINITY; table.len()];
    let all: Vec<usize> = (0..table.len()).collect();
    let mut evaluations = recompute_watched(&mut table, &mut keys, &all, &|e| eval(h, &residual, e), watch)?;
    let mut operations = Vec::new();
    let mut stop = Stop::MaxIterations;
    let mut improving: Vec<usize> = Vec::with_capacity(table.len());
    let mut iterations = 0;
    // With only quadratic terms, the residual's change over each deformed window this
    // iteration, to update the sums of the entries it reaches.
    let incremental = fitness.residual_only();
    let mut changes: Vec<(Rect, Vec<f64>)> = Vec::new();
    let mut updates = 0u64;
    let mut checks = 0u64;
    let window =
        |e: &Entry| Rect::around(e.col as usize, e.row as usize, s.kernels[e.radius as usize].radius, cols, rows);
    // The exact best change of an estimated entry, on its full window (None: exact already),
    // kept as its key and in the entry (the full window's curvature too, as the estimate's is).
    let unchecked = |e: &Entry| stride(s.kernels[e.radius as usize].radius) > 1 && !e.checked;
    let check = |h: &[f64], residual: &[f64], e: &Entry| {
        let k = e.radius as usize;
        fitness.best_change(
            h,
            residual,
            e.col as usize,
            e.row as usize,
            &s.kernels[k],
            1,
            &s.deltas[k],
            s.d_max[k],
            true,
            (!e.exact_curvature.is_nan()).then_some(e.exact_curvature),
            super::constraints::ANY,
        )
    };
    let exact = |h: &[f64], residual: &[f64], e: &mut Entry, key: &mut f64| {
        unchecked(e).then(|| take_check(e, key, check(h, residual, e)))
    };
    // What a check costs, in cell visits: its window, once per sampled displacement when the
    // fitness has terms other than the quadratic (the one-sided mask's, the pairs').
    let per_cell = if fitness.residual_only() { 1 } else { s.deltas.iter().map(Vec::len).max().unwrap_or(1) + 1 };
    let check_cost = |e: &Entry| (2 * s.kernels[e.radius as usize].radius + 1).pow(2) * per_cell;
    // Checks made ahead for entries the batch is about to reach, to be taken when it does.
    let mut ahead: Vec<(usize, Best)> = Vec::new();
    // Entries invalidated this iteration, and those prediction lets wait by when they fall due,
    // so the table is not scanned for them every iteration.
    let mut invalidated: Vec<usize> = Vec::new();
    // Apart from the table, as the keys are, since every invalidated entry is looked at: each
    // entry's confidence (§3.5), and whether its sum b missed changes while it waited.
    let mut confidence = vec![1.0f64; table.len()];
    let mut missed = vec![false; table.len()];
    let mut waiting = prediction::Waiting::new(s.prediction_constant, s.max_iterations as u64);
    let mut totals: std::collections::VecDeque<f64> = std::collections::VecDeque::new();

    for iteration in 1..=s.max_iterations as u64 {
        watch.check()?;
        if tracker.total() <= s.epsilon {
            stop = Stop::Epsilon;
            break;
        }
        // F at the start of each of the last `stall_iterations` iterations, oldest first.
        if s.stall_iterations > 0 {
            let window = s.stall_iterations as usize;
            if totals.len() == window {
                let then = totals.pop_front().unwrap_or(f64::INFINITY);
                if then - tracker.total() < s.stall_gain * then {
                    stop = Stop::Stalled;
                    break;
                }
            }
            totals.push_back(tracker.total());
        }
        // Choose (§3.3), re-checking estimated entries exactly before applying.
        let top = ((s.top_fraction * table.len() as f64).ceil() as usize).max(1);
        let head = HEAD_PER_BATCH * s.batch;
        let mut below = gather(&mut improving, &keys, top.max(head));
        if improving.is_empty() {
            let stale: Vec<usize> = (0..keys.len()).filter(|&i| keys[i] == f64::INFINITY).collect();
            evaluations += recompute_watched(&mut table, &mut keys, &stale, &|e| eval(h, &residual, e), watch)?;
            for &i in &stale {
                missed[i] = false;
            }
            waiting.clear();
            below = gather(&mut improving, &keys, top.max(head));
        }
        // Best first. The draw needs the top fraction as a set, and the greedy choice and the
        // batch only the head of it in order, so the set is selected, the head sorted, and
        // the rest only when the batch reaches it (the order is total: the same as sorting
        // everything).
        let drawn = select(&mut improving, top, &keys);
        let mut sorted = sort_more(&mut improving[..drawn], 0, head, &keys);
        // An estimated entry is checked exactly when it is reached (its best displacement on
        // the full window); if it is then no longer ahead of the next, it goes back to its
        // place in the order, so the choice is made on exact changes (lazy greedy).
        let chosen = loop {
            if improving.is_empty() {
                break None;
            }
            let pick = if rng.random::<f64>() < s.p { 0 } else { rng.random_range(0..drawn.min(improving.len())) };
            let i = improving[pick];
            if let Some(change) = exact(h, &residual, &mut table[i], &mut keys[i]) {
                evaluations += 1;
                checks += 1;
                if change >= 0.0 {
                    drop_drawn(&mut improving, pick, &mut sorted, drawn, &keys);
                    if sorted == 0 {
                        let n = drawn.min(improving.len());
                        sorted = sort_more(&mut improving[..n], 0, head, &keys);
                    }
                } else if !(pick == 0 && reinsert(&mut improving, 0, &mut sorted, &keys)) {
                    break Some((i, table[i]));
                }
                continue;
            }
            break Some((i, table[i]));
        };
        let Some((first, e)) = chosen else {
            stop = Stop::NoImprovement;
            break;
        };
        iterations = iteration;
        // The batch: the choice, then further improving entries best first whose windows the
        // changes so far leave untouched, so each entry's change is still exact and they add.
        let mut batch = vec![(first, e)];
        ahead.clear();
        let mut dirty = dirty_rects(window(&e), cols, rows, s.tile_x, s.tile_z);
        if s.batch > 1 {
            let mut k = 0;
            while batch.len() < s.batch {
                if k == improving.len() {
                    // Past what was gathered: the rest of the improving entries, in order.
                    if below == 0.0 {
                        break;
                    }
                    improving.extend((0..keys.len()).filter(|&i| (below..0.0).contains(&keys[i])));
                    below = 0.0;
                    continue;
                }
                if k == sorted {
                    sorted = sort_more(&mut improving, sorted, sorted, &keys);
                }
                let j = improving[k];
                let w = window(&table[j]);
                if j == first || keys[j] >= 0.0 || dirty.iter().any(|d| d.intersects(&w)) {
                    k += 1;
                    continue;
                }
                if unchecked(&table[j]) {
                    let best = match ahead.iter().position(|a| a.0 == j) {
                        Some(at) => ahead.swap_remove(at).1,
                        None => {
                            // This check and those of the next few entries the batch will reach
                            // (as far as the changes taken so far tell), at once: the heights
                            // do not change before the batch is applied, so each is what it
                            // would be when reached, and is taken then (or never).
                            let mut block = vec![j];
                            for &x in &improving[k + 1..sorted] {
                                if block.len() == CHECKS_AT_ONCE {
                                    break;
                                }
                                let reached = x != first && keys[x] < 0.0 && unchecked(&table[x]);
                                if reached
                                    && !ahead.iter().any(|a| a.0 == x)
                                    && !dirty.iter().any(|d| d.intersects(&window(&table[x])))
                                {
                                    block.push(x);
                                }
                            }
                            evaluations += block.len() as u64;
                            checks += block.len() as u64;
                            let cost: usize = block.iter().map(|&x| check_cost(&table[x])).sum();
                            let mut results: Vec<Best> = if cost >= PARALLEL_CHECK_CELLS {
                                block.par_iter().map(|&x| check(h, &residual, &table[x])).collect()
                            } else {
                                block.iter().map(|&x| check(h, &residual, &table[x])).collect()
                            };
                            ahead.extend(block[1..].iter().copied().zip(results.drain(1..)));
                            results[0]
                        }
                    };
                    let change = take_check(&mut table[j], &mut keys[j], best);
                    if change >= 0.0 {
                        k += 1;
                        continue;
                    }
                    if reinsert(&mut improving, k, &mut sorted, &keys) {
                        continue;
                    }
                }
                dirty.extend(dirty_rects(w, cols, rows, s.tile_x, s.tile_z));
                batch.push((j, table[j]));
                k += 1;
            }
        }
        changes.clear();
        // What the applied deformations changed.
        let mut changed: Vec<Rect> = Vec::with_capacity(dirty.len());
        for &(_, e) in &batch {
            let kernel = &s.kernels[e.radius as usize];
            let (col, row) = (e.col as usize, e.row as usize);
            let delta = e.delta;
            let amplitude = (h[row * cols + col] + delta) as f32;
            let op = Deformation {
                x: col as f64 * s.cell_m,
                z: row as f64 * s.cell_m,
                col: e.col,
                row: e.row,
                amplitude,
                radius_cells: kernel.radius as u32,
                radius_m: kernel.radius as f64 * s.cell_m,
            };
            let rect = tracker.apply(h, &op, kernel);
            changed.extend(dirty_rects(rect, cols, rows, s.tile_x, s.tile_z));
            let mut change = Vec::new();
            fitness.refresh_residual(&mut residual, h, rect, incremental.then_some(&mut change));
            if incremental {
                changes.push((rect, change));
            }
            operations.push(op);
        }

        // Invalidate what the change can reach; recompute (with prediction, only the likely).
        // Only entries within their radius of a changed cell can reach it: per radius, the
        // rows within that radius, and in each row the columns within it.
        for d in &changed {
            for (k, rows_of) in by_radius.iter().enumerate() {
                let r = reach[k];
                let (lo, hi) = (d.r0.saturating_sub(r), (d.r1 + r).min(rows - 1));
                let (c0, c1) = (d.c0.saturating_sub(r) as u32, (d.c1 + r) as u32);
                for row in &rows_of[lo..=hi] {
                    // The first column in reach by bisection; the rest in reach follow it.
                    let from = row.cols.partition_point(|&c| c < c0);
                    let to = from + row.cols[from..].iter().take_while(|&&c| c <= c1).count();
                    for &i in &row.entries[from..to] {
                        let key = &mut keys[i as usize];
                        if *key != f64::INFINITY {
                            *key = f64::INFINITY;
                            invalidated.push(i as usize);
                        }
                    }
                }
            }
        }
        // An entry whose sum b is current up to this iteration is updated from the residual's
        // changes — a few products where a window meets a small deformation — instead of summed
        // again; the rest (those prediction let wait, whose sums missed changes) are recomputed.
        let (mut todo, mut update) = (Vec::new(), Vec::new());
        for i in invalidated.drain(..) {
            if s.prediction && confidence[i] < prediction::THRESHOLD {
                missed[i] = true;
                waiting.wait(i, confidence[i], iteration);
            } else if incremental && !missed[i] {
                update.push(i);
            } else {
                todo.push(i);
            }
        }
        waiting.take_due(iteration, &mut todo);
        updates += update.len() as u64;
        let summed = todo.len();
        todo.extend(update);
        let sum = |e: &Entry| eval(h, &residual, e);
        let update = |e: &Entry| updated(fitness, &changes, e, s);
        evaluations += refresh(&mut table, &mut keys, &todo, summed, &sum, &update);
        for &i in &todo[..summed] {
            missed[i] = false;
        }
        if s.prediction {
            // The worst is taken as "no change" (0): a candidate that cannot improve the terrain
            // is no nearer the top for harming it less than another, and with the table's true
            // worst — some far-off entry whose every displacement hurts — every improvement
            // ranked near full confidence, so on roads nothing was ever skipped.
            let best = best_key(&keys);
            let worst = 0.0;
            for &i in &todo {
                confidence[i] = prediction::confidence(keys[i], best, worst, s.prediction_constant);
            }
        }
        watch.progress(iteration, s.max_iterations as u64, tracker.total(), h);
    }
    tracing::debug!(evaluations, updates, checks, "deform-terrain search: entries summed, updated and checked exactly");
    Ok(Searched { operations, iterations, evaluations, stop })
}

/// Sort `more` entries of `improving` after its sorted head `[..sorted]` (the best of the
/// rest, selected first); returns the new head's length.
fn sort_more(improving: &mut [usize], sorted: usize, more: usize, keys: &[f64]) -> usize {
    let rest = &mut improving[sorted..];
    let more = more.max(1).min(rest.len());
    if more < rest.len() {
        rest.select_nth_unstable_by(more, best_first(keys));
    }
    rest[..more].sort_unstable_by(best_first(keys));
    sorted + more
}

/// Move `improving[at]`, whose change was just made exact, back to its place in the sorted
/// head if it is no longer ahead of the entry after it (or out of the head, into the unsorted
/// rest, if it falls past it). Returns whether it moved.
fn reinsert(improving: &mut [usize], at: usize, sorted: &mut usize, keys: &[f64]) -> bool {
    let order = best_first(keys);
    let i = improving[at];
    if at + 1 >= *sorted || order(&i, &improving[at + 1]) != std::cmp::Ordering::Greater {
        return false;
    }
    // Only the head between its old and new place moves (the rest can be long).
    let place = at + 1 + improving[at + 1..*sorted].partition_point(|x| order(x, &i) == std::cmp::Ordering::Less);
    improving[at..place].rotate_left(1);
    if place == *sorted {
        // It falls past the head: the first of the unsorted rest.
        *sorted -= 1;
    }
    true
}

/// Entries sampled to estimate where the best few lie.
const SAMPLE_STRIDE: usize = 16;

/// Gather into `improving` at least the `want` best improving entries: those below a key
/// estimated from every [`SAMPLE_STRIDE`]-th entry with a margin of two, or, when that falls
/// short, every improving entry. Returns the bound: every entry not gathered has a key at or
/// above it (0: every improving entry is gathered).
fn gather(improving: &mut Vec<usize>, keys: &[f64], want: usize) -> f64 {
    improving.clear();
    let mut sample: Vec<f64> = keys.iter().step_by(SAMPLE_STRIDE).copied().filter(|&k| k < 0.0).collect();
    let rank = (2 * want).div_ceil(SAMPLE_STRIDE);
    if rank < sample.len() {
        let below = *sample.select_nth_unstable_by(rank, f64::total_cmp).1;
        below_into(improving, keys, below);
        if improving.len() >= want {
            return below;
        }
        improving.clear();
    }
    below_into(improving, keys, 0.0);
    0.0
}

/// Append the entries whose keys are below `bound`, in index order: written unconditionally
/// and kept by moving the end, with no branch to mispredict (most keys fall on one side).
fn below_into(out: &mut Vec<usize>, keys: &[f64], bound: f64) {
    let start = out.len();
    out.resize(start + keys.len(), 0);
    let mut n = start;
    for (i, &k) in keys.iter().enumerate() {
        out[n] = i;
        n += usize::from(k < bound);
    }
    out.truncate(n);
}

/// The smallest key, at most 0, in four running minima a compiler can keep in vector lanes.
fn best_key(keys: &[f64]) -> f64 {
    let mut lanes = [0.0f64; 4];
    let chunks = keys.chunks_exact(4);
    let rest = chunks.remainder();
    for c in chunks {
        for (l, &k) in lanes.iter_mut().zip(c) {
            *l = if k < *l { k } else { *l };
        }
    }
    rest.iter().chain(&lanes).fold(0.0f64, |b, &k| if k < b { k } else { b })
}

/// Put the `n` best of `improving` first, in no order; returns how many that is.
fn select(improving: &mut [usize], n: usize, keys: &[f64]) -> usize {
    let n = n.min(improving.len());
    if n < improving.len() {
        improving.select_nth_unstable_by(n, best_first(keys));
    }
    n
}

/// Drop `improving[at]`, one of the `drawn` best (sorted up to `sorted`), and put the best of
/// the rest in its place among them, so the draw keeps its reach.
fn drop_drawn(improving: &mut Vec<usize>, at: usize, sorted: &mut usize, drawn: usize, keys: &[f64]) {
    let mut at = at;
    if at < *sorted {
        improving[at..*sorted].rotate_left(1);
        *sorted -= 1;
        at = *sorted;
    }
    let order = best_first(keys);
    let next = (drawn..improving.len()).min_by(|&a, &b| order(&improving[a], &improving[b]));
    match next {
        Some(m) => {
            improving.swap(at, m);
            improving.swap_remove(m);
        }
        None => {
            improving.remove(at);
        }
    }
}

/// Entries by their change, best first; ties by index, so the order is total.
fn best_first(keys: &[f64]) -> impl Fn(&usize, &usize) -> std::cmp::Ordering + '_ {
    |a, b| keys[*a].total_cmp(&keys[*b]).then(a.cmp(b))
}

/// Entries recomputed between looks at the stop request: a whole table can take seconds.
const ENTRIES_PER_CHECK: usize = 1 << 16;

/// Checks the batch makes at once (one reached, the next few it is about to reach).
const CHECKS_AT_ONCE: usize = 4;
/// Below this many cell visits in all, checks made at once run on this thread: handing them
/// to the pool costs more.
const PARALLEL_CHECK_CELLS: usize = 8192;

/// Take an exact check's result into an estimated entry: its key, displacement and full
/// window's curvature, and the scale its estimates are ranked by from now on. Returns the
/// exact change.
fn take_check(e: &mut Entry, key: &mut f64, best: Best) -> f64 {
    e.exact_curvature = best.curvature;
    let estimate = *key / e.trust;
    if estimate < 0.0 {
        e.trust = (best.change / estimate).clamp(TRUST_RANGE.0, TRUST_RANGE.1);
    }
    *key = best.change;
    e.delta = best.delta;
    e.checked = true;
    best.change
}

/// Sum the listed entries again (`sum`), in chunks, looking at `watch` between them; returns
/// how many were evaluated.
fn recompute_watched<W: Watch>(
    table: &mut [Entry],
    keys: &mut [f64],
    which: &[usize],
    sum: &(impl Fn(&Entry) -> Best + Sync),
    watch: &W,
) -> Result<u64, W::Stop> {
    let mut n = 0;
    for chunk in which.chunks(ENTRIES_PER_CHECK) {
        watch.check()?;
        n += refresh(table, keys, chunk, chunk.len(), sum, sum);
    }
    Ok(n)
}

/// Sum the first `summed` of the listed entries again (`sum`) and bring the rest's sums up to
/// date (`update`), in one parallel pass: one hand-over to the pool an iteration rather than
/// two. Returns how many entries were evaluated.
fn refresh(
    table: &mut [Entry],
    keys: &mut [f64],
    which: &[usize],
    summed: usize,
    sum: &(impl Fn(&Entry) -> Best + Sync),
    update: &(impl Fn(&Entry) -> Best + Sync),
) -> u64 {
    let snapshot: &[Entry] = table;
    let results: Vec<Best> = which
        .par_iter()
        .enumerate()
        .map(|(k, &i)| if k < summed { sum(&snapshot[i]) } else { update(&snapshot[i]) })
        .collect();
    store(table, keys, which, results)
}

/// An entry's best change from its sum b brought up to date with the residual's `changes`
/// (each a window and the change over it, row by row): exact, as a recomputation, when the
/// fitness is residual-only.
fn updated(fitness: &Fitness, changes: &[(Rect, Vec<f64>)], e: &Entry, s: &Settings) -> Best {
    let k = e.radius as usize;
    let kernel = &s.kernels[k];
    let (col, row) = (e.col as usize, e.row as usize);
    let window = Rect::around(col, row, kernel.radius, fitness.cols, fitness.rows);
    let b = changes
        .iter()
        .filter(|(rect, _)| rect.intersects(&window))
        .fold(e.b, |b, (rect, change)| b + fitness.lattice_sum(change, *rect, col, row, kernel, stride(kernel.radius)));
    fitness.change_from_sums(e.curvature, b, &s.deltas[k], s.d_max[k], true, super::constraints::ANY)
}

/// How much of the way back to 1 an estimate's scale goes at each recomputation, so an entry
/// whose estimate once misled is looked at again (0.1 before; 0.05 chosen with [`EXACT_SIDE`]).
const TRUST_RELAXATION: f64 = 0.05;
/// How far an estimate's scale may go.
const TRUST_RANGE: (f64, f64) = (0.02, 2.0);

fn store(table: &mut [Entry], keys: &mut [f64], which: &[usize], results: Vec<Best>) -> u64 {
    for (&i, best) in which.iter().zip(results) {
        let t = &mut table[i];
        // Only an estimate's check moves its scale away from 1; an entry summed on its full
        // window keeps 1, which the relaxation leaves as it is.
        keys[i] = best.change * t.trust;
        t.trust += (1.0 - t.trust) * TRUST_RELAXATION;
        t.delta = best.delta;
        t.curvature = best.curvature;
        t.b = best.b;
        t.checked = false;
    }
    which.len() as u64
}

/// The changed cells, plus the opposite edge strip their tileable partners lie in: the two
/// samples nearest each edge, which the pairs and the wrap's slope terms couple.
fn dirty_rects(rect: Rect, cols: usize, rows: usize, tile_x: bool, tile_z: bool) -> Vec<Rect> {
    let mut out = vec![rect];
    if tile_x && cols >= 2 {
        if rect.c0 <= 1 {
            out.push(Rect { c0: cols - 2, c1: cols - 1, ..rect });
        }
        if rect.c1 >= cols - 2 {
            out.push(Rect { c0: 0, c1: 1, ..rect });
        }
    }
    if tile_z && rows >= 2 {
        if rect.r0 <= 1 {
            out.push(Rect { r0: rows - 2, r1: rows - 1, ..rect });
        }
        if rect.r1 >= rows - 2 {
            out.push(Rect { r0: 0, r1: 1, ..rect });
        }
    }
    out
}
