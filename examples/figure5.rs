//! The paper's Figure 5 for our examples: the deformation sequence as the compressed terrain
//! against image formats of the same terrain. Give it the folders `landform run --out` wrote:
//!
//! ```text
//! for f in api/deform-terrain/*.json; do
//!   landform run --out /tmp/fig5/$(basename $f .json) $f; done
//! cargo run --example figure5 -- /tmp/fig5/*
//! ```
//!
//! For each: `sequence.bin` (and the largest difference its replay has from the result),
//! `sequence.json`, the 16-bit `heightmap.png`, and a baseline JPEG of the 8-bit heightmap
//! (the 16-bit one scaled to 0–255 over its range, grayscale, IJG quality 80 with 4:2:0 — the
//! image crate's baseline encoder; the paper used Photoshop's setting 9 of 12, "high", which has
//! no exact IJG equal) with its own largest and RMS error in metres, decoded again.

use image::codecs::jpeg::JpegEncoder;
use image::{ExtendedColorType, ImageEncoder};

const JPEG_QUALITY: u8 = 80;

fn main() {
    println!("| example | ops | sequence.bin | max error | sequence.json | heightmap.png (16-bit) | JPEG 8-bit q{JPEG_QUALITY} | JPEG max error | JPEG RMS error |");
    println!("|---|---:|---:|---:|---:|---:|---:|---:|---:|");
    for dir in std::env::args().skip(1) {
        let dir = std::path::Path::new(&dir);
        let read =
            |name: &str| std::fs::read(dir.join(name)).unwrap_or_else(|e| panic!("{}/{name}: {e}", dir.display()));
        let job: serde_json::Value = serde_json::from_slice(&read("job.json")).unwrap();
        let result = &job["result"];
        let (z_min, z_max) = (result["z_min"].as_f64().unwrap(), result["z_max"].as_f64().unwrap());
        let png = read("heightmap.png");
        let img = image::load_from_memory(&png).unwrap().to_luma16();
        let (w, h) = img.dimensions();
        let metres = |v: f64, top: f64| z_min + v / top * (z_max - z_min);
        let eight: Vec<u8> = img.pixels().map(|p| (p.0[0] as f64 / 65535.0 * 255.0).round() as u8).collect();
        let mut jpeg = Vec::new();
        JpegEncoder::new_with_quality(&mut jpeg, JPEG_QUALITY)
            .write_image(&eight, w, h, ExtendedColorType::L8)
            .unwrap();
        let back = image::load_from_memory(&jpeg).unwrap().to_luma8();
        let (mut worst, mut sum) = (0.0f64, 0.0f64);
        for (a, b) in img.pixels().zip(back.pixels()) {
            let d = metres(a.0[0] as f64, 65535.0) - metres(b.0[0] as f64, 255.0);
            worst = worst.max(d.abs());
            sum += d * d;
        }
        let rms = (sum / (w * h) as f64).sqrt();
        let bin = &result["sequence_bin"];
        println!(
            "| {} | {} | {} | {:.4} m | {} | {} | {} | {:.3} m | {:.3} m |",
            dir.file_name().unwrap().to_string_lossy(),
            bin["operations"],
            read("sequence.bin").len(),
            bin["max_error_m"].as_f64().unwrap(),
            read("sequence.json").len(),
            png.len(),
            jpeg.len(),
            worst,
            rms,
        );
    }
}
