//! Criterion benchmarks of a 12-megapixel camera frame (4000x3000 grey), as a phone or a
//! machine-vision camera delivers it.
//!
//! `formation-tracker-cli/detect_12mp_grey`: full detection (quads and decoding) of a frame
//! with 24 markers of 10 to 44 px a cell on a noisy background (seeded), with one reused
//! `Detector`. `formation-tracker-cli/load_12mp_grey_png`: the command-line loader
//! (`frames::read_grey`) on the same frame saved as an 8-bit grey PNG.

use criterion::{Criterion, criterion_group, criterion_main};
use fiducial::{Detector, DetectorConfig, Dictionary, GrayView, RenderOptions, render_marker};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::hint::black_box;

const W: usize = 4000;
const H: usize = 3000;

/// The 12 MP frame: grey 170 with +-12 uniform noise, and 24 markers in a 6x4 grid.
fn frame() -> Vec<u8> {
    let mut rng = ChaCha8Rng::seed_from_u64(12);
    let mut px: Vec<u8> = (0..W * H)
        .map(|_| (170 + rng.random_range(-12i32..=12)) as u8)
        .collect();
    let dict = Dictionary::paper();
    for k in 0..24usize {
        let opts = RenderOptions {
            px_per_cell: 10 + (k as u32 * 3) % 35,
            quiet_cells: 1,
        };
        let code = dict.code(k * 7 % dict.len()).expect("index in range");
        let m = render_marker(dict.family(), code, &opts).expect("valid marker");
        let (x0, y0) = (100 + (k % 6) * 640, 120 + (k / 6) * 720);
        for y in 0..m.height() {
            let row = &m.pixels()[y * m.width()..(y + 1) * m.width()];
            let at = (y0 + y) * W + x0;
            for (o, &v) in px[at..at + m.width()].iter_mut().zip(row) {
                // Markers printed on matte paper: not quite black and white.
                *o = 30 + (u16::from(v) * 190 / 255) as u8;
            }
        }
    }
    px
}

fn benches(c: &mut Criterion) {
    let px = frame();
    let view = GrayView::new(&px, W, H).expect("valid frame");
    let mut det = Detector::new(DetectorConfig::default());
    let mut out = Vec::new();
    det.detect(&view, &mut out);
    assert_eq!(out.len(), 24, "every marker of the benchmark frame is read");
    let mut group = c.benchmark_group("formation-tracker-cli");
    group.sample_size(10);
    group.bench_function("detect_12mp_grey", |b| {
        b.iter(|| {
            det.detect(black_box(&view), &mut out);
            black_box(out.len())
        })
    });
    let path = std::env::temp_dir().join(format!("bench-12mp-{}.png", std::process::id()));
    image::GrayImage::from_raw(W as u32, H as u32, px.clone())
        .expect("buffer of the frame's size")
        .save(&path)
        .expect("temporary PNG written");
    group.bench_function("load_12mp_grey_png", |b| {
        b.iter(|| {
            let g =
                formation_io::frames::read_grey(black_box(&path)).expect("the PNG just written");
            black_box(g.data.len())
        })
    });
    group.finish();
    let _ = std::fs::remove_file(&path);
}

criterion_group!(large, benches);
criterion_main!(large);
