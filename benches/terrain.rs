//! The shared terrain and output layers: fBm terrain generation, and the four heightfield
//! artifacts (16-bit PNG, preview, glb, npy) every heightfield kind writes.
//! Run with `cargo bench --bench terrain`.

use criterion::{criterion_group, criterion_main, Criterion};

use landform::export::heightfield_artifacts;
use landform::terrain::{generate_fractal, FractalParams};

fn fractal(size: u32) -> FractalParams {
    FractalParams { size, octaves: 8, seed: 7, ..FractalParams::default() }
}

fn bench(c: &mut Criterion) {
    let mut g = c.benchmark_group("terrain");
    g.sample_size(10);
    for size in [1025u32, 4097] {
        g.bench_function(format!("fractal_{size}x{size}_8_octaves"), |b| b.iter(|| generate_fractal(&fractal(size))));
    }
    for size in [1025u32, 4097] {
        let hf = generate_fractal(&fractal(size));
        g.bench_function(format!("artifacts_{size}x{size}"), |b| {
            b.iter(|| heightfield_artifacts(&hf, &Default::default()).unwrap())
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
