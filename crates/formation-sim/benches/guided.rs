//! Criterion benchmarks of tracking-guided detection (#12) on the demo scene: robot 2's
//! camera looking at robot 1 at the demo's start (1.5 m ahead, 0.25 m to the left), rendered
//! once at 640x480 and at 3840x2160 (one sample per pixel, noise 3, blur 1).
//!
//! Per size: `formation-sim/detect_full_WxH` scans the whole frame at full resolution;
//! `detect_coarse2_WxH` scans it at half resolution (corners refined at full resolution,
//! the periodic scan of guided mode from 1920 px wide); `detect_guided_WxH` searches only
//! the leader's predicted region, as the pipeline computes it after three tracked frames
//! (the rig reprojected at the predicted pose, default margins, quads searched at the
//! scale the predicted marker size allows: 1 at 640x480, 4 at 3840x2160), plus the boxes of
//! faces too narrow for that scale at full resolution, as the pipeline does. The same `Detector` type
//! and defaults as `track`; one core. `formation-sim/baseline_sum_640x480` sums the 640x480
//! frame's bytes: a fixed-work reference in the same run, for ratios on a loaded machine.

use criterion::{Criterion, criterion_group, criterion_main};
use fiducial::{Detector, DetectorConfig, GrayView, Region, Search};
use formation_tracker::guided::GuidedConfig;
use std::hint::black_box;

#[path = "../tests/guided_support/mod.rs"]
mod guided_support;

/// The frame (robot 1 1.5 m ahead, 0.25 m to the left, as at the demo's start) and the
/// leader's predicted region(s) and their scale.
fn setup(width: usize, height: usize) -> (Vec<u8>, Vec<Region>, Vec<Region>, usize) {
    let (image, predicted) = guided_support::leader_frame(width, height, 1.5, 0.25, 0.0);
    let factor = predicted.factor(&GuidedConfig::default());
    let fine = predicted.fine_regions(factor).collect();
    (image, vec![predicted.region], fine, factor)
}

fn benches(c: &mut Criterion) {
    for (w, h) in [(640usize, 480usize), (3840, 2160)] {
        let (pixels, regions, fine, factor) = setup(w, h);
        let img = GrayView::new(&pixels, w, h).expect("valid frame");
        let mut det = Detector::new(DetectorConfig::default());
        let mut out = Vec::new();
        det.detect(&img, &mut out);
        let seen = out.len();
        assert!(seen >= 2, "{w}x{h}: only {seen} markers read");
        let guided = |det: &mut Detector, out: &mut Vec<_>| {
            det.detect_with(&img, &Search::in_regions(&regions).at_scale(factor), out);
            if !fine.is_empty() {
                det.detect_with(&img, &Search::in_regions(&fine).appending(), out);
            }
        };
        guided(&mut det, &mut out);
        assert_eq!(out.len(), seen, "{w}x{h}: the region holds every marker");
        let mut group = c.benchmark_group("formation-sim");
        if w > 1000 {
            group.sample_size(20);
        }
        group.bench_function(format!("detect_full_{w}x{h}"), |b| {
            b.iter(|| {
                det.detect(black_box(&img), &mut out);
                black_box(out.len())
            })
        });
        group.bench_function(format!("detect_coarse2_{w}x{h}"), |b| {
            b.iter(|| {
                det.detect_with(
                    black_box(&img),
                    &Search::whole_frame().at_scale(2),
                    &mut out,
                );
                black_box(out.len())
            })
        });
        group.bench_function(format!("detect_guided_{w}x{h}"), |b| {
            b.iter(|| {
                guided(&mut det, &mut out);
                black_box(out.len())
            })
        });
        group.finish();
    }
    // A fixed-work reference measured in the same run (as in the fiducial benches), so that
    // figures taken on a loaded machine can be compared as ratios.
    let (pixels, _, _, _) = setup(640, 480);
    c.bench_function("formation-sim/baseline_sum_640x480", |b| {
        b.iter(|| {
            black_box(&pixels)
                .iter()
                .map(|&v| u32::from(v))
                .sum::<u32>()
        })
    });
}

criterion_group!(guided, benches);
criterion_main!(guided);
