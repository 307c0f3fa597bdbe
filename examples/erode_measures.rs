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
    if what == "rotation" || what == "all" {
        let turned = rotated(&hf, 30.0, hf.min_max().0);
        let (a, sa) = run(&hf, with(json!({})));
        let (b, sb) = run(&turned, with(json!({})));
        describe("0°", &hf, &a, sa, talus);
        describe("30°", &turned, &b, sb, talus);
    }
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
