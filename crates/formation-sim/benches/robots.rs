//! Criterion benchmarks of the robot stage on the paper's Fig. 10 scene (two leaders, six
//! faces read): `formation-tracker/measure_robots_fig10` (grouping, joint poses, ground-plane
//! refinement, formation variables and covariance from the detected markers) and
//! `formation-tracker/detect_and_measure_fig10` (the detector on the rendered 640 x 480 frame,
//! then the robot stage), so the robot stage's share of a frame is visible.

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use fiducial::{Dictionary, GrayView};
use formation_sim::evaluate::{default_detector, truth_k};
use formation_sim::paper::paper_scene;
use formation_sim::scene::render_scene;
use formation_tracker::rig::RigModel;
use formation_tracker::robots::{MarkerObservation, RobotConfig, measure_robots};

fn bench(c: &mut Criterion) {
    let dict = Dictionary::paper();
    let rig = RigModel::reference();
    let spec = paper_scene(10).expect("Fig. 10 exists");
    let rendered = render_scene(&spec, &rig, dict).expect("Fig. 10 renders");
    let (w, h) = (rendered.truth.width, rendered.truth.height);
    let view = GrayView::new(rendered.image.as_raw(), w, h).expect("frame matches its size");
    let mut detector = default_detector(dict);
    let mut found = Vec::new();
    detector.detect(&view, &mut found);
    let observations: Vec<MarkerObservation> = found
        .iter()
        .map(|d| MarkerObservation {
            index: d.index,
            corners: d.corners,
        })
        .collect();
    let intrinsics =
        pose::Intrinsics::from_matrix(&truth_k(&rendered.truth)).expect("valid camera matrix");
    let solver = pose::PoseSolver::new(intrinsics);
    let config = RobotConfig::default();
    c.bench_function("formation-tracker/measure_robots_fig10", |b| {
        b.iter(|| {
            measure_robots(
                black_box(&observations),
                &rig,
                &solver,
                &spec.mount,
                &config,
            )
        })
    });
    c.bench_function("formation-tracker/detect_and_measure_fig10", |b| {
        let mut out = Vec::new();
        b.iter(|| {
            detector.detect(black_box(&view), &mut out);
            let obs: Vec<MarkerObservation> = out
                .iter()
                .map(|d| MarkerObservation {
                    index: d.index,
                    corners: d.corners,
                })
                .collect();
            measure_robots(&obs, &rig, &solver, &spec.mount, &config)
        })
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
