//! `sequence.bin`: the deformation sequence as the compressed terrain (paper §4.5) — the
//! starting terrain's source and what replay needs of each operation, nothing more.
//!
//! Layout, version 2 (integers little-endian; "varint" is unsigned LEB128, "zigzag" maps a
//! signed n to 2n or −2n − 1 before it):
//!
//! | bytes | field |
//! |---|---|
//! | 4 | magic `LFDS` |
//! | 1 | version, 2 |
//! | 1 | amplitudes: 0 = exact (f32), 1 = quantised |
//! | 2 | reserved, 0 |
//! | 4 | u32 L, then L bytes: the starting terrain's source, compact JSON (as in `sequence.json`) |
//! | 4 + 4 | u32 cols, u32 rows of the grid |
//! | 4 | f32 q, metres: the amplitude quantum (0 when exact) |
//! | 4 | f32 the tolerance, metres, the encoder held the replay to (when exact, the one asked, 0 if none) |
//! | 4 | f32 the largest difference, metres, the encoder measured between this replay and the run |
//! | 1 | u8 R, then R × u16: the radii used, cells |
//! | 4 | u32 N, the operations |
//! | 4 | u32 P, then P bytes: a raw DEFLATE stream (RFC 1951) of three columns, N entries each: |
//! | | zigzag varint v − previous v, v = row · cols + col the operation's vertex (the first from 0) |
//! | | u8 index into the radii |
//! | | exact: f32 amplitude, metres; quantised: zigzag varint d, the amplitude being h + d·q with h the height the replay has at that vertex before the operation (f64 sum, rounded to f32) |
//!
//! Replay applies the operations in order with the kernel of `kernel.rs`. Exact amplitudes
//! are the run's own, in the run's order: they replay bit for bit what `sequence.json` does.
//! Quantised ones use that every operation adds (a − h(v))·K to the heights: additions
//! commute, so all of a vertex's operations of one radius sum to one, and the sums are stored
//! in raster order (small steps between vertices, which DEFLATE packs tightly). Each sum is
//! rounded to a multiple of q after taking off the rounding error the sums before it left at
//! its vertex (error feedback); a sum of no step is left out, and q is halved until the whole
//! replay stays within the tolerance of the run, cell by cell.

use std::io::{Read, Write};

use super::kernel::{self, Kernel};
use super::sequence::{DeformSequence, Deformation};
use crate::terrain::TerrainSource;

const MAGIC: &[u8; 4] = b"LFDS";
const VERSION: u8 = 2;
/// The first quantum tried, in tolerances, and the halvings tried after it before the
/// amplitudes are stored exactly (q from 4 × the tolerance down to a 128th of it).
const FIRST_QUANTUM: f64 = 4.0;
const HALVINGS: u32 = 9;
/// The finest tolerance held, in f32 steps (machine epsilons) of the highest height.
const F32_STEPS: f64 = 4.0;
/// The most operations a file may declare (a job records at most 1 000 000).
const MAX_OPERATIONS: u64 = super::params::MAX_OPERATIONS_PER_JOB;

/// An encoded sequence and what the encoder measured.
#[derive(Clone, Debug)]
pub struct Packed {
    pub bytes: Vec<u8>,
    /// Operations kept (after merging and pruning).
    pub operations: usize,
    pub quantum_m: f64,
    pub tolerance_m: f64,
    /// The largest |replay of these bytes − the run| over every cell.
    pub max_error_m: f64,
}

/// Why bytes are not a sequence.
#[derive(Debug, thiserror::Error)]
#[error("sequence.bin: {0}")]
pub struct PackError(String);

fn bad<T>(what: impl Into<String>) -> Result<T, PackError> {
    Err(PackError(what.into()))
}

/// The grid a sequence runs on: the starting heights and their shape.
pub struct Start<'a> {
    pub original: &'a [f64],
    pub cols: usize,
    pub rows: usize,
}

/// Encode `sequence` whose run ended at `run_final`, holding every cell of the replay within
/// `tolerance_m` of it (0: exact amplitudes, every operation kept). A tolerance is never held
/// finer than [`F32_STEPS`] f32 steps of the highest height: replay stores each amplitude as
/// an f32 height, as `heightfield.npy` stores the heights, so nothing finer could be held (at
/// 3 000 m one step is 0.24 mm, more than half a 16-bit step of a 12 m relief).
pub fn encode(sequence: &DeformSequence, start: &Start, run_final: &[f64], tolerance_m: f64) -> Packed {
    let ops = &sequence.operations;
    if tolerance_m > 0.0 {
        let highest = run_final.iter().chain(start.original).fold(0.0f64, |m, v| m.max(v.abs()));
        let tolerance_m = tolerance_m.max(F32_STEPS * f32::EPSILON as f64 * highest);
        let sums = summed(ops, start);
        let mut q = tolerance_m * FIRST_QUANTUM;
        for _ in 0..=HALVINGS {
            let (codes, h) = quantise(&sums, start, q as f32);
            let error = max_difference(&h, run_final);
            if error <= tolerance_m {
                return write(&sequence.terrain, start, &codes, q as f32, tolerance_m, error);
            }
            q /= 2.0;
        }
    }
    let exact: Vec<(Deformation, Amplitude)> = ops.iter().map(|op| (*op, Amplitude::Exact(op.amplitude))).collect();
    let mut h = start.original.to_vec();
    replay(&mut h, start, ops);
    // The tolerance asked, when it could not be held quantised.
    write(&sequence.terrain, start, &exact, 0.0, tolerance_m, max_difference(&h, run_final))
}

/// How an amplitude is stored.
#[derive(Clone, Copy, Debug)]
enum Amplitude {
    Exact(f32),
    Steps(i64),
}

/// One vertex's operations of one radius, summed: the change (a − h(v)) each made there.
#[derive(Clone, Copy, Debug)]
struct Sum {
    op: Deformation,
    change: f64,
}

/// Replay the run's operations and sum each vertex's changes per radius, in raster order
/// (vertex, then radius).
fn summed(ops: &[Deformation], start: &Start) -> Vec<Sum> {
    let mut h = start.original.to_vec();
    let mut kernels = KernelCache::default();
    let mut sums: std::collections::BTreeMap<(u32, u32, u32), Sum> = std::collections::BTreeMap::new();
    for op in ops {
        let v = op.row as usize * start.cols + op.col as usize;
        let change = op.amplitude as f64 - h[v];
        sums.entry((op.row, op.col, op.radius_cells)).or_insert(Sum { op: *op, change: 0.0 }).change += change;
        kernel::apply(
            &mut h,
            start.cols,
            start.rows,
            op.col as usize,
            op.row as usize,
            op.amplitude as f64,
            kernels.get(*op),
        );
    }
    sums.into_values().collect()
}

/// Round the sums to steps of `q` from the height the replay has at each vertex, each after
/// taking off the error the sums before it left at its vertex, dropping those of no step;
/// returns the stored operations and the heights they give.
fn quantise(sums: &[Sum], start: &Start, q: f32) -> (Vec<(Deformation, Amplitude)>, Vec<f64>) {
    let (cols, rows) = (start.cols, start.rows);
    let mut h = start.original.to_vec();
    // Σ (stored change − summed change)·K over the sums so far.
    let mut error = vec![0.0; h.len()];
    let mut kernels = KernelCache::default();
    let mut out = Vec::with_capacity(sums.len());
    for sum in sums {
        let (col, row) = (sum.op.col as usize, sum.op.row as usize);
        let v = row * cols + col;
        let kernel = kernels.get(sum.op);
        let steps = ((sum.change - error[v]) / q as f64).round() as i64;
        let stored = if steps == 0 {
            0.0
        } else {
            let amplitude = stepped(h[v], steps, q);
            let stored = amplitude as f64 - h[v];
            kernel::apply(&mut h, cols, rows, col, row, amplitude as f64, kernel);
            out.push((Deformation { amplitude, ..sum.op }, Amplitude::Steps(steps)));
            stored
        };
        // error + (stored − change)·K, through the same kernel loop.
        let pinned = error[v] + stored - sum.change;
        kernel::apply(&mut error, cols, rows, col, row, pinned, kernel);
    }
    (out, h)
}

/// h + steps·q, as the decoder computes it.
fn stepped(h: f64, steps: i64, q: f32) -> f32 {
    (h + steps as f64 * q as f64) as f32
}

fn replay(h: &mut [f64], start: &Start, ops: &[Deformation]) {
    let mut kernels = KernelCache::default();
    for op in ops {
        kernel::apply(
            h,
            start.cols,
            start.rows,
            op.col as usize,
            op.row as usize,
            op.amplitude as f64,
            kernels.get(*op),
        );
    }
}

/// A search uses a handful of radii: each kernel built once.
#[derive(Default)]
struct KernelCache(Vec<Kernel>);

impl KernelCache {
    fn get(&mut self, op: Deformation) -> &Kernel {
        let r = op.radius_cells as usize;
        match self.0.iter().position(|k| k.radius == r) {
            Some(i) => &self.0[i],
            None => {
                self.0.push(Kernel::new(r));
                self.0.last().expect("just pushed")
            }
        }
    }
}

fn max_difference(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max)
}

fn write(
    terrain: &TerrainSource,
    start: &Start,
    ops: &[(Deformation, Amplitude)],
    q: f32,
    tolerance_m: f64,
    error: f64,
) -> Packed {
    let mut radii: Vec<u32> = ops.iter().map(|(op, _)| op.radius_cells).collect();
    radii.sort_unstable();
    radii.dedup();
    let exact = ops.iter().all(|(_, a)| matches!(a, Amplitude::Exact(_)));
    let mut columns: [Vec<u8>; 3] = Default::default();
    let mut previous = 0i64;
    for (op, amplitude) in ops {
        let v = op.row as i64 * start.cols as i64 + op.col as i64;
        varint(&mut columns[0], zigzag(v - previous));
        previous = v;
        columns[1].push(radii.binary_search(&op.radius_cells).expect("listed") as u8);
        match amplitude {
            Amplitude::Exact(a) => columns[2].extend_from_slice(&a.to_le_bytes()),
            Amplitude::Steps(d) => varint(&mut columns[2], zigzag(*d)),
        }
    }
    let mut deflate = flate2::write::DeflateEncoder::new(Vec::new(), flate2::Compression::best());
    for c in &columns {
        deflate.write_all(c).expect("writing to memory");
    }
    let payload = deflate.finish().expect("writing to memory");
    let source = serde_json::to_vec(terrain).expect("a terrain source serialises");
    let mut out = Vec::with_capacity(64 + source.len() + payload.len());
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&[VERSION, if exact { 0 } else { 1 }, 0, 0]);
    out.extend_from_slice(&(source.len() as u32).to_le_bytes());
    out.extend_from_slice(&source);
    out.extend_from_slice(&(start.cols as u32).to_le_bytes());
    out.extend_from_slice(&(start.rows as u32).to_le_bytes());
    out.extend_from_slice(&q.to_le_bytes());
    out.extend_from_slice(&(tolerance_m as f32).to_le_bytes());
    out.extend_from_slice(&(error as f32).to_le_bytes());
    out.push(radii.len() as u8);
    for r in &radii {
        out.extend_from_slice(&(*r as u16).to_le_bytes());
    }
    out.extend_from_slice(&(ops.len() as u32).to_le_bytes());
    out.extend_from_slice(&(payload.len() as u32).to_le_bytes());
    out.extend_from_slice(&payload);
    Packed { bytes: out, operations: ops.len(), quantum_m: q as f64, tolerance_m, max_error_m: error }
}

/// The header of a `sequence.bin`: what can be read without the starting heights.
#[derive(Debug)]
pub struct Header {
    pub terrain: TerrainSource,
    pub cols: usize,
    pub rows: usize,
    pub quantum_m: f32,
    pub tolerance_m: f32,
    pub max_error_m: f32,
    pub operations: usize,
}

/// Read a `sequence.bin`'s header.
pub fn header(bytes: &[u8]) -> Result<Header, PackError> {
    Ok(parse(bytes)?.0)
}

/// Decode a `sequence.bin` onto its starting heights (those of `header(bytes).terrain`,
/// `cols` × `rows`, `cell_m` apart): the operations replay applies, amplitudes resolved.
pub fn decode(bytes: &[u8], original: &[f64], cell_m: f64) -> Result<DeformSequence, PackError> {
    let (head, radii, exact, payload) = parse(bytes)?;
    let (cols, rows, n) = (head.cols, head.rows, head.operations);
    if original.len() != cols * rows {
        return bad(format!("the starting terrain has {} samples, not {cols} × {rows}", original.len()));
    }
    // Each entry is at most 10 + 1 + 10 bytes; read no more than that could need.
    let limit = (n as u64) * 21;
    let mut body = Vec::new();
    flate2::read::DeflateDecoder::new(payload)
        .take(limit + 1)
        .read_to_end(&mut body)
        .or_else(|e| bad(format!("payload: {e}")))?;
    if body.len() as u64 > limit {
        return bad("payload longer than its operations");
    }
    let mut at = 0usize;
    let steps: Vec<i64> = (0..n).map(|_| read_varint(&body, &mut at).map(unzigzag)).collect::<Result<_, _>>()?;
    let mut radius_index = Vec::with_capacity(n);
    for _ in 0..n {
        radius_index.push(*body.get(at).ok_or_else(|| PackError("payload ends early".into()))?);
        at += 1;
    }
    let mut h = original.to_vec();
    let mut kernels = KernelCache::default();
    let mut operations = Vec::with_capacity(n);
    let mut v = 0i64;
    for (k, step) in steps.iter().enumerate() {
        v = v
            .checked_add(*step)
            .filter(|v| (0..(cols * rows) as i64).contains(v))
            .ok_or_else(|| PackError(format!("operation {k} is off the grid")))?;
        let (col, row) = (v % cols as i64, v / cols as i64);
        let radius = *radii.get(radius_index[k] as usize).ok_or_else(|| PackError(format!("operation {k}: radius")))?;
        let v = v as usize;
        let amplitude = if exact {
            let b = body.get(at..at + 4).ok_or_else(|| PackError("payload ends early".into()))?;
            at += 4;
            f32::from_le_bytes(b.try_into().expect("4 bytes"))
        } else {
            stepped(h[v], unzigzag(read_varint(&body, &mut at)?), head.quantum_m)
        };
        if !amplitude.is_finite() {
            return bad(format!("operation {k}: amplitude"));
        }
        let op = Deformation {
            x: col as f64 * cell_m,
            z: row as f64 * cell_m,
            col: col as u32,
            row: row as u32,
            amplitude,
            radius_cells: radius,
            radius_m: radius as f64 * cell_m,
        };
        if !exact {
            kernel::apply(&mut h, cols, rows, col as usize, row as usize, amplitude as f64, kernels.get(op));
        }
        operations.push(op);
    }
    if at != body.len() {
        return bad("payload longer than its operations");
    }
    Ok(DeformSequence { terrain: head.terrain, operations })
}

type Parsed<'a> = (Header, Vec<u32>, bool, &'a [u8]);

fn parse(bytes: &[u8]) -> Result<Parsed<'_>, PackError> {
    let mut r = Reader { bytes, at: 0 };
    if r.take(4)? != MAGIC {
        return bad("not a Landform sequence (magic)");
    }
    let head = r.take(4)?;
    if head[0] != VERSION {
        return bad(format!("version {} (this server reads {VERSION})", head[0]));
    }
    let exact = match head[1] {
        0 => true,
        1 => false,
        m => return bad(format!("amplitude mode {m}")),
    };
    let len = r.u32()? as usize;
    let terrain: TerrainSource =
        serde_json::from_slice(r.take(len)?).or_else(|e| bad(format!("terrain source: {e}")))?;
    let (cols, rows) = (r.u32()? as usize, r.u32()? as usize);
    let quantum_m = r.f32()?;
    let tolerance_m = r.f32()?;
    let max_error_m = r.f32()?;
    let usable = quantum_m.is_finite() && quantum_m > 0.0;
    if !exact && !usable {
        return bad("quantum");
    }
    let radii: Vec<u32> = (0..r.take(1)?[0]).map(|_| r.u16().map(u32::from)).collect::<Result<_, _>>()?;
    if radii.iter().any(|&x| !(1..=super::params::MAX_RADIUS_CELLS).contains(&x)) {
        return bad("a radius out of range");
    }
    let n = r.u32()? as u64;
    if n > MAX_OPERATIONS {
        return bad(format!("{n} operations is more than {MAX_OPERATIONS}"));
    }
    let p = r.u32()? as usize;
    let payload = r.take(p)?;
    if r.at != bytes.len() {
        return bad("bytes after the payload");
    }
    let header = Header { terrain, cols, rows, quantum_m, tolerance_m, max_error_m, operations: n as usize };
    Ok((header, radii, exact, payload))
}

struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize) -> Result<&'a [u8], PackError> {
        let end = self.at.checked_add(n).filter(|&e| e <= self.bytes.len());
        let end = end.ok_or_else(|| PackError("ends early".into()))?;
        let out = &self.bytes[self.at..end];
        self.at = end;
        Ok(out)
    }

    fn u16(&mut self) -> Result<u16, PackError> {
        Ok(u16::from_le_bytes(self.take(2)?.try_into().expect("2 bytes")))
    }

    fn u32(&mut self) -> Result<u32, PackError> {
        Ok(u32::from_le_bytes(self.take(4)?.try_into().expect("4 bytes")))
    }

    fn f32(&mut self) -> Result<f32, PackError> {
        Ok(f32::from_le_bytes(self.take(4)?.try_into().expect("4 bytes")))
    }
}

fn zigzag(v: i64) -> u64 {
    ((v << 1) ^ (v >> 63)) as u64
}

fn unzigzag(v: u64) -> i64 {
    ((v >> 1) as i64) ^ -((v & 1) as i64)
}

fn varint(out: &mut Vec<u8>, mut v: u64) {
    while v >= 0x80 {
        out.push((v as u8) | 0x80);
        v >>= 7;
    }
    out.push(v as u8);
}

fn read_varint(bytes: &[u8], at: &mut usize) -> Result<u64, PackError> {
    let mut v = 0u64;
    for shift in (0..64).step_by(7) {
        let b = *bytes.get(*at).ok_or_else(|| PackError("payload ends early".into()))?;
        *at += 1;
        v |= u64::from(b & 0x7f) << shift;
        if b & 0x80 == 0 {
            return Ok(v);
        }
    }
    bad("a varint longer than 64 bits")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn op(col: u32, row: u32, radius: u32, amplitude: f32) -> Deformation {
        let (x, z, radius_m) = (col as f64, row as f64, radius as f64);
        Deformation { x, z, col, row, amplitude, radius_cells: radius, radius_m }
    }

    fn terrain() -> TerrainSource {
        serde_json::from_value(serde_json::json!({"fractal": {"size": 40}})).unwrap()
    }

    const N: usize = 40;

    fn start(h: &[f64]) -> Start<'_> {
        Start { original: h, cols: N, rows: N }
    }

    fn ramp() -> Vec<f64> {
        (0..N * N).map(|i| (i % N) as f64 * 0.5 + (i / N) as f64 * 0.25).collect()
    }

    #[test]
    fn a_vertexs_operations_of_one_radius_sum_to_one_that_gives_the_same_heights() {
        let h = ramp();
        // A and C at (10, 10) with B between them reaching A's window; D at another radius.
        let ops = [op(10, 10, 3, 5.0), op(12, 10, 3, 2.0), op(10, 10, 3, 7.0), op(10, 10, 4, 1.0)];
        let sums = summed(&ops, &start(&h));
        let keys: Vec<(u32, u32, u32)> = sums.iter().map(|s| (s.op.col, s.op.row, s.op.radius_cells)).collect();
        assert_eq!(keys, vec![(10, 10, 3), (10, 10, 4), (12, 10, 3)], "raster order, then radius");
        // By hand: each operation adds (a − h(v))·K, with h(v) the height just before it.
        let (k3, k4) = (Kernel::new(3), Kernel::new(4));
        let at = |c: usize, r: usize| r * N + c;
        let a_change = 5.0 - h[at(10, 10)];
        let b_change = 2.0 - (h[at(12, 10)] + a_change * k3.at(2, 0));
        let c_change = 7.0 - (5.0 + b_change * k3.at(-2, 0));
        let d_change = 1.0 - 7.0;
        assert!((sums[0].change - (a_change + c_change)).abs() < 1e-12);
        assert!((sums[1].change - d_change).abs() < 1e-12);
        assert!((sums[2].change - b_change).abs() < 1e-12);
        let mut all = h.clone();
        replay(&mut all, &start(&h), &ops);
        for (i, &a) in all.iter().enumerate() {
            let (c, r) = ((i % N) as i64, (i / N) as i64);
            let want = h[i]
                + (a_change + c_change) * k3.at(c - 10, r - 10)
                + d_change * k4.at(c - 10, r - 10)
                + b_change * k3.at(c - 12, r - 10);
            assert!((a - want).abs() < 1e-9, "cell {i}: {a} vs {want}");
        }
    }

    #[test]
    fn exact_amplitudes_round_trip_bit_for_bit_and_quantised_ones_within_the_tolerance() {
        let h = ramp();
        let ops: Vec<Deformation> = (0..300u32)
            .map(|k| op((k * 7) % 40, (k * 13) % 40, 2 + k % 4, 3.0 + ((k as f32) * 0.37).sin() * 4.0))
            .collect();
        let mut run = h.clone();
        replay(&mut run, &start(&h), &ops);
        let seq = DeformSequence { terrain: terrain(), operations: ops.clone() };
        let exact = encode(&seq, &start(&h), &run, 0.0);
        let back = decode(&exact.bytes, &h, 1.0).unwrap();
        assert_eq!(back.operations, ops);
        assert_eq!(back.terrain, seq.terrain);
        assert_eq!(exact.max_error_m, 0.0);
        for tolerance in [0.05, 0.002, 1e-5] {
            let packed = encode(&seq, &start(&h), &run, tolerance);
            let header = header(&packed.bytes).unwrap();
            assert!(header.quantum_m > 0.0 && header.operations == packed.operations);
            let back = decode(&packed.bytes, &h, 1.0).unwrap();
            let mut replayed = h.clone();
            replay(&mut replayed, &start(&h), &back.operations);
            let worst = max_difference(&replayed, &run);
            assert!(worst <= tolerance, "{worst} > {tolerance}");
            assert!((worst - packed.max_error_m).abs() < 1e-12);
            assert!(packed.bytes.len() < exact.bytes.len(), "{} vs {}", packed.bytes.len(), exact.bytes.len());
        }
    }

    #[test]
    fn high_terrain_is_quantised_within_what_its_f32_heights_hold() {
        // 3 000 m up, one f32 step of a height is 0.24 mm: a tolerance of 0.1 mm cannot be
        // held by f32 amplitudes, so it is raised to four such steps (not given up to the
        // exact form, four times the size).
        let h: Vec<f64> = ramp().iter().map(|v| v + 3000.0).collect();
        let ops: Vec<Deformation> = (0..300u32)
            .map(|k| op((k * 7) % 40, (k * 13) % 40, 2 + k % 4, 3003.0 + ((k as f32) * 0.37).sin() * 4.0))
            .collect();
        let mut run = h.clone();
        replay(&mut run, &start(&h), &ops);
        let seq = DeformSequence { terrain: terrain(), operations: ops };
        let exact = encode(&seq, &start(&h), &run, 0.0);
        let packed = encode(&seq, &start(&h), &run, 1e-4);
        let header = header(&packed.bytes).unwrap();
        let step = f32::EPSILON as f64 * 3025.0;
        assert!(header.quantum_m > 0.0, "quantised");
        assert!((packed.tolerance_m - 4.0 * step).abs() < 0.01 * step, "{}", packed.tolerance_m);
        let mut replayed = h.clone();
        replay(&mut replayed, &start(&h), &decode(&packed.bytes, &h, 1.0).unwrap().operations);
        assert!(max_difference(&replayed, &run) <= packed.tolerance_m);
        assert!(packed.bytes.len() * 2 < exact.bytes.len(), "{} vs {}", packed.bytes.len(), exact.bytes.len());
    }

    #[test]
    fn damaged_bytes_are_refused_without_panicking() {
        let h = ramp();
        let ops: Vec<Deformation> = (0..50u32).map(|k| op((k * 7) % 40, (k * 3) % 40, 3, k as f32 * 0.1)).collect();
        let mut run = h.clone();
        replay(&mut run, &start(&h), &ops);
        let seq = DeformSequence { terrain: terrain(), operations: ops };
        let packed = encode(&seq, &start(&h), &run, 0.01).bytes;
        for cut in 0..packed.len() {
            assert!(decode(&packed[..cut], &h, 1.0).is_err(), "cut at {cut}");
        }
        // Every single-bit flip either fails cleanly or decodes to operations on the grid.
        for i in 0..packed.len() {
            for bit in 0..8 {
                let mut b = packed.clone();
                b[i] ^= 1 << bit;
                if let Ok(s) = decode(&b, &h, 1.0) {
                    assert!(s.operations.iter().all(|o| (o.col as usize) < N && (o.row as usize) < N));
                }
            }
        }
        assert!(decode(&packed, &h[..N * N - 1], 1.0).is_err(), "wrong terrain size");
    }

    #[test]
    fn varints_and_zigzag_round_trip_at_their_extremes() {
        for v in [0i64, 1, -1, 63, -64, 64, 1 << 40, i64::MAX, i64::MIN] {
            let mut out = Vec::new();
            varint(&mut out, zigzag(v));
            let mut at = 0;
            assert_eq!(unzigzag(read_varint(&out, &mut at).unwrap()), v);
            assert_eq!(at, out.len());
        }
    }
}
