//! The erode kind measured as issue 49 asks, in release, on islands of our own:
//! `cargo run --release --example erode_measures -- [what] [size] [seed]`. `what` is one of
//! `timestep`, `resolution`, `rotation`, `talus`, `mass`, `all`. Figures for people; the same
//! checks, smaller, are `tests/erode_landform.rs`.

use std::time::Instant;

use serde_json::{json, Value};

use landform::sims::erode::{ErodeParams, Erosion};
use landform::terrain::{resolve, Heightfield, TerrainLookup};
use landform::validate::Limits;

#[path = "../tests/erode_support/measures.rs"]
mod measures;
use measures::*;

struct NoStore;
impl TerrainLookup for NoStore {
    fn job_heightfield(&self, id: &str) -> Result<Heightfield, String> {
        Err(id.into())
    }
    fn input(&self, sha: &str) -> Result<Vec<u8>, String> {
        Err(sha.into())
    }
}

fn island(size: u32, cell: f32, relief: f32, seed: u64) -> Heightfield {
    let src = serde_json::from_value(
        json!({"fractal": {"size": size, "cell_size": cell, "relief": relief, "island": true, "seed": seed}}),
    )
    .unwrap();
    resolve(&src, &NoStore, &Limits::default()).unwrap()
}

fn run(hf: &Heightfield, extra: Value) -> (Heightfield, f64) {
    let mut body = json!({"terrain": {"fractal": {}}});
    for (k, v) in extra.as_object().unwrap() {
        body[k] = v.clone();
    }
    let p: ErodeParams = serde_json::from_value(body).unwrap();
    let t = Instant::now();
    let mut e = Erosion::new(hf, &p);
    for _ in 0..p.iterations {
        e.step();
    }
    e.flush();
    if std::env::var("TOTALS").is_ok() {
        println!(
            "    totals: settled in sea {:.0} m³, exported {:.0} m³",
            e.totals.settled_in_sea_m3, e.totals.exported_m3
        );
    }
    (e.heightfield(), t.elapsed().as_secs_f64())
}

fn describe(label: &str, input: &Heightfield, out: &Heightfield, secs: f64, talus: f64) {
    let (a, b) = (Surface::of(input), Surface::of(out));
    let land = a.land(0.0);
    let (mean, _) = lowering(&a, &b, &land);
    let d = Drainage::new(&b, 0.0);
    let chan = 200.0 * b.cell * b.cell;
    let _ = chan;
    let min_area = 400.0f64;
    println!(
        "{label}: {secs:.2} s, mean lowering {mean:.3} m of {:.2}, θ {:?}, Hack {:?}, density {:.5}/m, steeper than talus+5° {:.3} (input {:.3}), aspect harmonic {:.3} (input {:.3}), pits {:.4}, max {:.1} → {:.1}",
        a.h.iter().zip(&land).filter(|(_, &l)| l).map(|(h, _)| h).sum::<f64>() / land.iter().filter(|&&l| l).count() as f64,
        d.concavity(min_area),
        d.hack(min_area),
        d.density(&b, min_area),
        b.steeper_share(&b.land(0.0), talus + 5.0),
        a.steeper_share(&land, talus + 5.0),
        b.aspect_harmonic(&land),
        a.aspect_harmonic(&land),
        b.pit_share(0.0),
        input.min_max().1,
        out.min_max().1,
    );
    hillshade(out, &format!("target/erode-measures/{}.png", label.replace([' ', '×', '°'], "_")));
    let m = landform::sims::erode::metrics::D8::new(out, 0.0);
    println!("    metrics.rs: θ {:?}, Hack {:?}", m.concavity(), m.hack());
    for a in [1000.0, 3000.0, 10000.0] {
        println!("    from {a} m²: θ {:?}, Hack {:?}, density {:.5}", d.concavity(a), d.hack(a), d.density(&b, a));
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let what = args.get(1).map_or("all", String::as_str);
    let size: u32 = args.get(2).map_or(257, |s| s.parse().unwrap());
    let seed: u64 = args.get(3).map_or(11, |s| s.parse().unwrap());
    let extra: Value = args.get(4).map_or(json!({}), |s| serde_json::from_str(s).unwrap());
    let with = |v: Value| {
        let mut v = v;
        for (k, x) in extra.as_object().unwrap() {
            v[k] = x.clone();
        }
        v
    };
    let talus = extra["thermal"]["talus_angle_deg"]
        .as_f64()
        .unwrap_or(landform::sims::erode::Thermal::default().talus_angle_deg);
    let relief: f32 = std::env::var("RELIEF").ok().map_or(120.0, |r| r.parse().unwrap());
    let hf = island(size, 2.0, relief, seed);
    if what == "defaults" || what == "all" {
        let (out, s) = run(&hf, with(json!({})));
        describe("defaults", &hf, &out, s, talus);
    }
    if what == "timestep" || what == "all" {
        let (a, sa) = run(&hf, with(json!({"iterations": 50, "time_step_years": 1000.0})));
        let (b, sb) = run(&hf, with(json!({"iterations": 200, "time_step_years": 250.0})));
        describe("50 × 1000 yr", &hf, &a, sa, talus);
        describe("200 × 250 yr", &hf, &b, sb, talus);
        let s = Surface::of(&hf);
        let land = s.land(0.0);
        let (_, la) = lowering(&s, &Surface::of(&a), &land);
        let (_, lb) = lowering(&s, &Surface::of(&b), &land);
        println!("time step: RMS difference {:.3} of the mean erosion", rms_share(&la, &lb, &land));
    }
    if what == "resolution" || what == "all" {
        let fine = island(2 * size - 1, 1.0, relief, seed);
        let coarse = fine.resampled(2.0);
        let (a, sa) = run(&fine, with(json!({})));
        let (b, sb) = run(&coarse, with(json!({})));
        describe("1 m", &fine, &a, sa, talus);
        describe("2 m", &coarse, &b, sb, talus);
    }
    if what == "wavy" {
        for deg in [0.0, 30.0] {
            let (mut pts, mut length, mut area, mut lowered, mut before, mut after) = (vec![], 0.0, 0.0, 0.0, 0.0, 0.0);
            for seed in seed..seed + 4 {
                let hf = wavy_island(size as usize, 2.0, f64::from(relief), seed, deg);
                let (out, secs) = run(&hf, with(json!({})));
                describe(&format!("wavy {seed} {deg}°"), &hf, &out, secs, talus);
                let (a, b) = (Surface::of(&hf), Surface::of(&out));
                let land = a.land(0.0);
                let d = Drainage::new(&b, 0.0);
                pts.extend(d.slope_area(400.0));
                let (l, s) = d.channel_length_and_land(&b, 400.0);
                length += l;
                area += s;
                lowered += lowering(&a, &b, &land).0;
                before += a.aspect_harmonic(&land);
                after += b.aspect_harmonic(&land);
            }
            println!(
                "pooled {deg}°: θ {:?}, density {:.5}, mean lowering {:.3}, aspect {:.3} → {:.3}",
                concavity_of(&pts),
                length / area,
                lowered / 4.0,
                before / 4.0,
                after / 4.0
            );
        }
    }
    if what == "fan" {
        fan(&extra);
    }
    if what == "rotation" || what == "all" {
        let turned = rotated(&hf, 30.0, hf.min_max().0);
        let (a, sa) = run(&hf, with(json!({})));
        let (b, sb) = run(&turned, with(json!({})));
        describe("0°", &hf, &a, sa, talus);
        describe("30°", &turned, &b, sb, talus);
        let commuted = rotated(&a, 30.0, a.min_max().0);
        describe("eroded, then turned 30°", &turned, &commuted, 0.0, talus);
        describe("input 0°", &hf, &hf, 0.0, talus);
        describe("input 30°", &turned, &turned, 0.0, talus);
        let twice = rotated(&rotated(&hf, 30.0, hf.min_max().0), -30.0, hf.min_max().0);
        let (c, sc) = run(&twice, with(json!({})));
        describe("turned 30° and back", &twice, &c, sc, talus);
        for deg in [15.0, 45.0, 60.0] {
            let t = rotated(&hf, deg, hf.min_max().0);
            let (d, sd) = run(&t, with(json!({})));
            describe(&format!("{deg}°"), &t, &d, sd, talus);
        }
    }
}

/// The unit test's mountain front (a rough block falling 6 m a row to row 48, then a plain
/// sloping 0.2 % south), eroded for 100 iterations; prints the channels crossing each row of the
/// plain by the test's own steepest-descent drainage and writes hillshades.
fn fan(extra: &Value) {
    const FRONT: usize = 48;
    let (cols, rows, cell) = (97usize, 129usize, 10.0f32);
    let mut s = 17u64;
    let mut hf = Heightfield::flat(cols, rows, cell, 0.0);
    for r in 0..rows {
        for c in 0..cols {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            let noise = (s >> 40) as f64 / (1u64 << 24) as f64 * 10.0;
            let plain = 0.002 * (rows - 1 - r) as f64 * f64::from(cell);
            hf.heights_m[r * cols + c] =
                if r <= FRONT { (plain + 40.0 + 6.0 * (FRONT - r) as f64 + 3.0 * noise) as f32 } else { plain as f32 };
        }
    }
    let mut body = json!({"sea_level": -1000.0, "iterations": 100, "thermal": null,
        "hydraulic": {"deposition_g": 1.0, "k": 2e-4}});
    for (k, v) in extra.as_object().unwrap() {
        body[k] = v.clone();
    }
    let (out, secs) = run(&hf, body);
    hillshade(&out, "target/erode-measures/fan.png");
    let (a, b) = (Surface::of(&hf), Surface::of(&out));
    // Channels across each row: runs of cells draining at least 20 cells (steepest descent).
    let d = Drainage::new(&b, -1000.0);
    let mut line = String::new();
    for r in (FRONT + 1..rows - 5).step_by(4) {
        let mut runs = 0;
        let mut inside = false;
        for c in 2..cols - 2 {
            let ch = d.area[r * cols + c] >= 20.0 * f64::from(cell * cell);
            if ch && !inside {
                runs += 1;
            }
            inside = ch;
        }
        let gain: f64 = (2..cols - 2).map(|c| b.h[r * cols + c] - a.h[r * cols + c]).sum::<f64>() / (cols - 4) as f64;
        line += &format!(" r{r}:{runs}/{gain:.1}m");
    }
    println!("fan: {secs:.2} s, channels/deposit by row:{line}");
    // Troughs: along each row, a cell lower than the cells two columns either side by 0.2 m.
    let trough = |r: usize, c: usize| {
        let h = |c: usize| b.h[r * cols + c];
        h(c) < h(c - 1) && h(c) <= h(c + 1) && h(c) + 0.2 < h(c - 2).min(h(c + 2))
    };
    let (mut splits, mut joins, mut count) = (0, 0, 0);
    for r in FRONT + 2..rows - 10 {
        for c in 3..cols - 3 {
            if !trough(r, c) || b.h[r * cols + c] - a.h[r * cols + c] < 0.5 {
                continue;
            }
            count += 1;
            let down = (c - 2..=c + 2).filter(|&k| trough(r + 1, k)).count();
            let up = (c - 2..=c + 2).filter(|&k| trough(r - 1, k)).count();
            splits += down.saturating_sub(1);
            joins += up.saturating_sub(1);
        }
    }
    println!("fan: trough cells {count}, splits downstream {splits}, joins {joins}");
}

/// A hillshade with the sun low in the north-west, as a greyscale PNG.
fn hillshade(hf: &Heightfield, path: &str) {
    std::fs::create_dir_all("target/erode-measures").unwrap();
    let s = Surface::of(hf);
    let mut px = vec![0u8; hf.cols * hf.rows];
    let (sx, sy, sz) = (-0.5f64, -0.5, std::f64::consts::FRAC_1_SQRT_2);
    for r in 1..hf.rows - 1 {
        for c in 1..hf.cols - 1 {
            let i = r * hf.cols + c;
            let (gx, gy) = s.horn(i);
            let n = (gx * gx + gy * gy + 1.0).sqrt();
            let l = ((-gx * sx - gy * sy + sz) / n).clamp(0.0, 1.0);
            px[i] = if s.h[i] <= 0.0 { (40.0 + 60.0 * l) as u8 } else { (255.0 * l) as u8 };
        }
    }
    // Three times larger, each sample a 3 × 3 block, so the facets can be seen.
    let z = 3;
    let big: Vec<u8> = (0..hf.rows * z)
        .flat_map(|r| (0..hf.cols * z).map(move |c| (r / z) * hf.cols + c / z))
        .map(|i| px[i])
        .collect();
    let file = std::fs::File::create(path).unwrap();
    let mut enc = png::Encoder::new(std::io::BufWriter::new(file), (hf.cols * z) as u32, (hf.rows * z) as u32);
    enc.set_color(png::ColorType::Grayscale);
    enc.write_header().unwrap().write_image_data(&big).unwrap();
}
