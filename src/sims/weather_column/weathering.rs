//! The weathering loop (paper sections 4–5): every active voxel that touches air has its
//! decimation level fall by its rate each step (the others wait, at level 1, until a removal
//! exposes them); voxels that reach zero are removed and their neighbours' air counts grow by
//! the bubble's lookup table.
//!
//! The synchronized two-step update finds all removals of a step from the levels at its start,
//! then applies them; it runs in parallel and gives the same result on any number of threads.
//! The event-based update removes each voxel at the moment its level reaches zero, in
//! continuous time (one step = one unit of time), and changes its neighbours' rates at once.

use std::cmp::{Ordering, Reverse};
use std::collections::{BinaryHeap, HashMap};

use rayon::prelude::*;

use super::grid::{NEIGHBOURS_26, ROCK};
use super::rock::{Active, Rock};
use crate::jobs::SimError;
use crate::stop::Stop;

/// What each step did, for the sequence and the job's result.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct History {
    /// Active voxels at the start of each step.
    pub active_per_step: Vec<u32>,
    /// Voxels removed by each step.
    pub removed_per_step: Vec<u32>,
}

impl History {
    pub fn steps(&self) -> u32 {
        self.removed_per_step.len() as u32
    }
}

/// When to stop and how fast rock weathers.
#[derive(Clone, Copy, Debug)]
pub struct Schedule<'a> {
    /// Looked at between steps and within long ones.
    pub stop: Stop<'a>,
    /// Decimation per step at air-to-rock ratio 1 and resistance 1.
    pub rate: f32,
    pub steps: u32,
    /// Stop once at most this many rock voxels remain.
    pub stop_at_voxels: u64,
}

/// Called after each step with (step, rock, active voxels now): reports progress and returns
/// `Err` to stop (cancellation).
pub type OnStep<'a> = dyn FnMut(u32, &Rock, usize) -> Result<(), SimError> + 'a;

pub fn weather_synchronized(rock: &mut Rock, schedule: Schedule, on_step: &mut OnStep) -> Result<History, SimError> {
    let mut active = rock.initialise(schedule.stop)?;
    let mut history = History::default();
    for step in 1..=schedule.steps {
        if active.is_empty() || rock.rock_voxels <= schedule.stop_at_voxels {
            break;
        }
        history.active_per_step.push(active.len() as u32);
        let removed = synchronized_step(rock, &mut active, schedule.rate, step as u16);
        history.removed_per_step.push(removed as u32);
        on_step(step, rock, active.len())?;
    }
    Ok(history)
}

/// One step of the two-step update: decimate every active voxel by the rate its air count
/// gives, then remove those at zero and update their neighbours. Returns the removals.
pub fn synchronized_step(rock: &mut Rock, active: &mut Active, rate: f32, step: u16) -> usize {
    let plane = rock.grid.plane();
    {
        let rock = &*rock;
        active.level.par_iter_mut().zip(active.index.par_iter()).zip(active.resistance.par_iter()).for_each(
            |((level, &i), &resistance)| {
                if let Some(exposure) = rock.grid.exposure(&rock.state, i as usize) {
                    let bubble = rock.bubble_of_plane(i as usize / plane);
                    *level -= bubble.decimation(rock.air[i as usize], exposure, rate, resistance);
                }
            },
        );
    }
    let removed: Vec<u32> =
        active.index.par_iter().zip(active.level.par_iter()).filter(|(_, &l)| l <= 0.0).map(|(&i, _)| i).collect();
    let activated = rock.remove(&removed, step);
    *active = merge_active(rock, std::mem::take(active), activated);
    if rock.gravity.is_some() {
        fall(rock, active, &removed, step);
    }
    removed.len()
}

/// Let what the step's removals cut loose fall; when anything fell, count the air afresh and
/// keep every active voxel's decimation level (a fallen one's too).
fn fall(rock: &mut Rock, active: &mut Active, removed: &[u32], step: u16) {
    let mut gravity = rock.gravity.take().expect("gravity");
    gravity.removed(removed, step);
    let moved = super::gravity::settle(&rock.grid, &mut rock.state, &mut gravity, removed, step);
    rock.gravity = Some(gravity);
    if moved.is_empty() {
        return;
    }
    let plane = rock.grid.plane() as u32;
    let mut to: HashMap<u32, u32> = HashMap::new();
    for (fall, piece) in &moved {
        for &c in piece {
            to.insert(c as u32, c as u32 - fall.dy * plane);
        }
    }
    let levels: HashMap<u32, f32> =
        active.index.iter().zip(&active.level).map(|(&i, &l)| (to.get(&i).copied().unwrap_or(i), l)).collect();
    rock.air.fill(0);
    let mut fresh = rock.initialise(Stop::NEVER).expect("never stopped");
    for (k, i) in fresh.index.iter().enumerate() {
        if let Some(&l) = levels.get(i) {
            fresh.level[k] = l;
        }
    }
    *active = fresh;
}

/// Survivors of `active` (level above 0) and the newly `activated` voxels (level 1), sorted.
fn merge_active(rock: &Rock, active: Active, activated: Vec<u32>) -> Active {
    let fresh: Vec<f32> = activated.par_iter().map(|&i| rock.resistance_of(i as usize)).collect();
    let capacity = active.len() + activated.len();
    let mut out = Active {
        index: Vec::with_capacity(capacity),
        level: Vec::with_capacity(capacity),
        resistance: Vec::with_capacity(capacity),
    };
    let mut n = 0;
    let push_fresh_below = |out: &mut Active, bound: u32, n: &mut usize| {
        while *n < activated.len() && activated[*n] < bound {
            out.index.push(activated[*n]);
            out.level.push(1.0);
            out.resistance.push(fresh[*n]);
            *n += 1;
        }
    };
    for k in 0..active.len() {
        if active.level[k] <= 0.0 {
            continue;
        }
        push_fresh_below(&mut out, active.index[k], &mut n);
        out.index.push(active.index[k]);
        out.level.push(active.level[k]);
        out.resistance.push(active.resistance[k]);
    }
    push_fresh_below(&mut out, u32::MAX, &mut n);
    // u32::MAX itself is never a voxel index (grids are capped well below it).
    debug_assert_eq!(n, activated.len());
    out
}

/// An active voxel in the event-based update: its level at time `since`, falling at `rate`.
struct EventVoxel {
    level: f64,
    since: f64,
    rate: f64,
    resistance: f32,
    version: u32,
}

/// A scheduled removal; stale when the voxel's version moved on.
#[derive(PartialEq)]
struct Event {
    time: f64,
    index: u32,
    version: u32,
}

impl Eq for Event {}

impl PartialOrd for Event {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for Event {
    /// By time, ties by voxel index: the order never depends on the heap's history.
    fn cmp(&self, other: &Self) -> Ordering {
        self.time.total_cmp(&other.time).then(self.index.cmp(&other.index)).then(self.version.cmp(&other.version))
    }
}

/// Events handled between looks at the stop request: a step may hold any number of them.
const EVENTS_PER_STOP_CHECK: u32 = 1 << 16;
/// Stale events the heap may hold per live one before it is compacted.
pub const STALE_EVENTS_PER_LIVE: usize = 4;

pub fn weather_event_based(rock: &mut Rock, schedule: Schedule, on_step: &mut OnStep) -> Result<History, SimError> {
    let initial = rock.initialise(schedule.stop)?;
    let plane = rock.grid.plane();
    // Unexposed voxels do not decay: rate 0, and no event until a removal exposes them.
    let rate_of = |rock: &Rock, i: u32, resistance: f32| -> f64 {
        let Some(exposure) = rock.grid.exposure(&rock.state, i as usize) else { return 0.0 };
        rock.bubble_of_plane(i as usize / plane).decimation(rock.air[i as usize], exposure, schedule.rate, resistance)
            as f64
    };
    let scheduled = |t: f64, level: f64, rate: f64, index: u32, version: u32| {
        (rate > 0.0).then(|| Reverse(Event { time: t + level.max(0.0) / rate, index, version }))
    };
    let mut voxels: HashMap<u32, EventVoxel> = HashMap::with_capacity(initial.len());
    let mut queue = BinaryHeap::with_capacity(initial.len());
    for (&i, &resistance) in initial.index.iter().zip(&initial.resistance) {
        let rate = rate_of(rock, i, resistance);
        voxels.insert(i, EventVoxel { level: 1.0, since: 0.0, rate, resistance, version: 0 });
        queue.extend(scheduled(0.0, 1.0, rate, i, 0));
    }
    drop(initial);
    let mut history = History::default();
    let mut step = 1u32;
    let mut removed_this_step = 0u32;
    let mut active_at_start = voxels.len() as u32;
    let mut targets: Vec<(usize, usize, usize)> = Vec::new();
    let mut events = 0u32;
    loop {
        if rock.rock_voxels <= schedule.stop_at_voxels {
            break;
        }
        events = events.wrapping_add(1);
        if events % EVENTS_PER_STOP_CHECK == 0 {
            schedule.stop.check()?;
        }
        // Every change of a voxel's rate leaves its earlier event behind; keep only the live
        // ones once the stale outnumber them, so the heap stays within a few times the active
        // set. Events order totally by (time, voxel, version), so the pops are the same.
        if queue.len() > STALE_EVENTS_PER_LIVE * voxels.len() + 1024 {
            queue.retain(|Reverse(e)| voxels.get(&e.index).is_some_and(|v| v.version == e.version));
        }
        let Some(Reverse(event)) = queue.pop() else { break };
        let Some(v) = voxels.get(&event.index) else { continue };
        if v.version != event.version {
            continue;
        }
        // Close the steps that ended before this removal.
        while event.time > step as f64 {
            history.active_per_step.push(active_at_start);
            history.removed_per_step.push(removed_this_step);
            on_step(step, rock, voxels.len())?;
            if step == schedule.steps {
                return Ok(history);
            }
            step += 1;
            removed_this_step = 0;
            active_at_start = voxels.len() as u32;
        }
        let t = event.time;
        voxels.remove(&event.index);
        rock.state[event.index as usize] = step as u16;
        rock.rock_voxels -= 1;
        removed_this_step += 1;
        targets.clear();
        rock.for_each_target_run(event.index as usize, 0..rock.grid.ny, |row, lo, hi| targets.push((row, lo, hi)));
        for &(row, lo, hi) in &targets {
            for i in row + lo..=row + hi {
                rock.air[i] += 1;
                if rock.state[i] != ROCK {
                    continue;
                }
                let i = i as u32;
                match voxels.get_mut(&i) {
                    Some(v) => {
                        v.level -= v.rate * (t - v.since);
                        v.since = t;
                        v.rate = rate_of(rock, i, v.resistance);
                        v.version += 1;
                        queue.extend(scheduled(t, v.level, v.rate, i, v.version));
                    }
                    None => {
                        let resistance = rock.resistance_of(i as usize);
                        let rate = rate_of(rock, i, resistance);
                        voxels.insert(i, EventVoxel { level: 1.0, since: t, rate, resistance, version: 0 });
                        queue.extend(scheduled(t, 1.0, rate, i, 0));
                    }
                }
            }
        }
        // The removal opened faces of, or exposed, the voxels around it: their rates change
        // even where their bubble does not reach it (a small or a gumdrop bubble). Re-rating
        // one already updated above changes nothing (no time has passed).
        let (x, y, z) = rock.grid.coords(event.index as usize);
        for (dx, dy, dz) in NEIGHBOURS_26 {
            let (nx, ny, nz) = (x as i64 + dx, y as i64 + dy, z as i64 + dz);
            if ny < 0 || !rock.grid.solid(&rock.state, nx, ny, nz) {
                continue;
            }
            let i = rock.grid.index(nx as usize, ny as usize, nz as usize) as u32;
            let Some(resistance) = voxels.get(&i).map(|v| v.resistance) else { continue };
            let rate = rate_of(rock, i, resistance);
            let v = voxels.get_mut(&i).expect("looked up above");
            v.level -= v.rate * (t - v.since);
            v.since = t;
            v.rate = rate;
            v.version += 1;
            queue.extend(scheduled(t, v.level, rate, i, v.version));
        }
    }
    // Stopped within `step`: it counts when it removed anything.
    if removed_this_step > 0 {
        history.active_per_step.push(active_at_start);
        history.removed_per_step.push(removed_this_step);
        on_step(step, rock, voxels.len())?;
    }
    Ok(history)
}
