//! Criterion benchmarks of the marker detector on seeded synthetic scenes.
//!
//! `fiducial/detect_*`: full detection (quads + decoding) of 8-marker scenes (20-120 px,
//! blur 1, noise 3) at three frame sizes; `_tag36h11` the 640x480 scene with tag36h11
//! markers and a tag36h11 detector; `_clean` (noise 0) against `_noisy` (noise 10) at
//! 640x480; `_no_side_check` the 640x480 scene without the occlusion checks, `_no_pattern`
//! without the corner refinement against the decoded pattern; clutter
//! without markers; `detect_1920x1080_rayon` the 1920x1080 scene through
//! `Detector::detect_with` and `Search::in_parallel` (binarization on rayon's threads with
//! `--features parallel`). `fiducial/find_quads_640x480` is the quad phase alone
//! (`stages_for_tools::find_quads`)
//! (`binarize_640x480` and `label_640x480` its first two stages apart;
//! `binarize_clutter_640x480` binarization of the clutter frame, where every tile has
//! contrast) and
//! `fiducial/baseline_sum_640x480` a plain pass summing the frame's bytes, measured in
//! the same run so that ratios survive a loaded machine.

use criterion::{Criterion, criterion_group, criterion_main};
use fiducial::stages_for_tools::find_quads;
use fiducial::{Detector, DetectorConfig, Dictionary, GrayView, Search};
use marker_testkit::{SceneConfig, clutter_frame, marker_scene};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::hint::black_box;
#[path = "../tests/common/mod.rs"]
mod common;

fn scene(width: usize, height: usize, noise: f64) -> Vec<u8> {
    scene_of(Dictionary::paper(), width, height, noise)
}

fn scene_of(dict: &Dictionary, width: usize, height: usize, noise: f64) -> Vec<u8> {
    let cfg = SceneConfig {
        width,
        height,
        noise,
        ..SceneConfig::default()
    };
    marker_scene(
        &cfg,
        &common::entries(dict),
        &mut ChaCha8Rng::seed_from_u64(42),
    )
    .expect("the benchmark scene fits its frame")
    .pixels
}

fn bench_detect(c: &mut Criterion, id: &str, pixels: &[u8], width: usize, height: usize) {
    bench_with(
        c,
        id,
        Detector::new(DetectorConfig::default()),
        pixels,
        width,
        height,
    );
}

fn bench_with(
    c: &mut Criterion,
    id: &str,
    mut det: Detector,
    pixels: &[u8],
    width: usize,
    height: usize,
) {
    let img = GrayView::new(pixels, width, height).expect("valid frame");
    let mut out = Vec::new();
    c.bench_function(id, |b| {
        b.iter(|| {
            det.detect(black_box(&img), &mut out);
            black_box(out.len())
        })
    });
}

fn benches(c: &mut Criterion) {
    let vga = scene(640, 480, 3.0);
    bench_detect(c, "fiducial/detect_640x480", &vga, 640, 480);
    // The same without the occlusion checks (`DetectorConfig::side_check`): what they cost.
    bench_with(
        c,
        "fiducial/detect_640x480_no_side_check",
        Detector::new(DetectorConfig {
            side_check: None,
            ..DetectorConfig::default()
        }),
        &vga,
        640,
        480,
    );
    // The same without the corner refinement against the decoded pattern
    // (`RefineConfig::with_pattern`, #13): what it costs.
    let mut no_pattern = DetectorConfig::default();
    no_pattern.refine.with_pattern = false;
    bench_with(
        c,
        "fiducial/detect_640x480_no_pattern",
        Detector::new(no_pattern),
        &vga,
        640,
        480,
    );
    // The same scene (seed, sizes, blur, noise) with eight tag36h11 markers, read by a
    // tag36h11 detector (587 codes, sorted-table lookup): compare with detect_640x480.
    let tag = fiducial::dictionary_by_name("tag36h11").expect("tag36h11 exists");
    bench_with(
        c,
        "fiducial/detect_640x480_tag36h11",
        Detector::with_dictionary(DetectorConfig::default(), tag.clone()),
        &scene_of(tag, 640, 480, 3.0),
        640,
        480,
    );
    bench_detect(
        c,
        "fiducial/detect_1280x720",
        &scene(1280, 720, 3.0),
        1280,
        720,
    );
    bench_detect(
        c,
        "fiducial/detect_1920x1080",
        &scene(1920, 1080, 3.0),
        1920,
        1080,
    );
    // The same 1920x1080 frame with binarization on the threads of rayon's pool (two on the
    // reference machine; build with `--features parallel`, else the bands run one after the
    // other): compare with detect_1920x1080 (do not pin this one to one core).
    let hd = scene(1920, 1080, 3.0);
    let img = GrayView::new(&hd, 1920, 1080).expect("valid frame");
    let mut det = Detector::new(DetectorConfig::default());
    let mut out = Vec::new();
    c.bench_function("fiducial/detect_1920x1080_rayon", |b| {
        b.iter(|| {
            det.detect_with(
                black_box(&img),
                &Search::whole_frame().in_parallel(),
                &mut out,
            );
            black_box(out.len())
        })
    });
    bench_detect(
        c,
        "fiducial/detect_640x480_clean",
        &scene(640, 480, 0.0),
        640,
        480,
    );
    bench_detect(
        c,
        "fiducial/detect_640x480_noisy",
        &scene(640, 480, 10.0),
        640,
        480,
    );
    let clutter = clutter_frame(
        640,
        480,
        1.0,
        3.0,
        common::not_markers(),
        &mut ChaCha8Rng::seed_from_u64(43),
    )
    .expect("valid clutter size");
    bench_detect(c, "fiducial/detect_clutter_640x480", &clutter, 640, 480);
    // Binarization of the clutter frame: textures everywhere, so (unlike the marker scenes,
    // mostly plain background) nearly every tile has contrast and needs its levels computed.
    let clutter_img = GrayView::new(&clutter, 640, 480).expect("valid frame");
    let mut binarizer = fiducial::stages_for_tools::Binarizer::new();
    let mut bin = Vec::new();
    c.bench_function("fiducial/binarize_clutter_640x480", |b| {
        b.iter(|| {
            binarizer.binarize(
                black_box(&clutter_img),
                fiducial::Threshold::default(),
                &mut bin,
            );
            black_box(bin.len())
        })
    });

    let img = GrayView::new(&vga, 640, 480).expect("valid frame");
    let mut det = Detector::new(DetectorConfig::default());
    c.bench_function("fiducial/find_quads_640x480", |b| {
        b.iter(|| black_box(find_quads(&mut det, black_box(&img)).len()))
    });
    // The stages of the quad phase apart: binarization (3x3 box and tile threshold), then
    // run-length labelling of the binary image; the rest of find_quads is contour tracing,
    // quad fitting and sub-pixel refinement of the surviving components.
    let mut binarizer = fiducial::stages_for_tools::Binarizer::new();
    let mut bin = Vec::new();
    c.bench_function("fiducial/binarize_640x480", |b| {
        b.iter(|| {
            binarizer.binarize(black_box(&img), fiducial::Threshold::default(), &mut bin);
            black_box(bin.len())
        })
    });
    let mut labeller = fiducial::stages_for_tools::Labeller::new();
    c.bench_function("fiducial/label_640x480", |b| {
        b.iter(|| black_box(labeller.label(black_box(&bin), 640).len()))
    });
    c.bench_function("fiducial/baseline_sum_640x480", |b| {
        b.iter(|| black_box(&vga).iter().map(|&v| u32::from(v)).sum::<u32>())
    });
}

criterion_group!(detect, benches);
criterion_main!(detect);
