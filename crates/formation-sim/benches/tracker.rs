//! Criterion benchmarks: the tracker's per-frame update with one leader, measurement given
//! (no image work: one chosen pose, and a single face's two planar candidates), and the
//! whole per-frame pipeline (detect + pose + track) on a pre-rendered 640x480 frame.

use criterion::{Criterion, criterion_group, criterion_main};
use formation_tracker::mount::CameraMount;
use formation_tracker::tracker::{
    FrameInput, Observation, PoseMeasurement, Tracker, TrackerConfig,
};
use nalgebra::{Matrix6, Vector6};
use unicycle::Inputs;

const DT: f64 = 1.0 / 30.0;

/// A leader 1.5 m ahead and 0.25 m to the left, facing the same way, seen by the reference
/// mount; covariance of a typical single-face solve.
fn estimate(yaw: f64) -> pose::Estimate {
    let (r, t) = CameraMount::default().leader_to_camera(1.5, 0.25, yaw);
    let sig = Vector6::new(0.01, 0.01, 0.01, 0.003, 0.003, 0.01);
    pose::Estimate {
        pose: pose::Pose::from_matrix(r.matrix(), t),
        rms: 0.3,
        covariance: Matrix6::from_diagonal(&sig.component_mul(&sig)),
        iterations: 4,
        converged: true,
    }
}

fn bench_step(c: &mut Criterion, id: &str, pose: PoseMeasurement) {
    let mut tracker = Tracker::new(TrackerConfig::reference(0.5, DT)).expect("reference config");
    let mut frame = FrameInput {
        t: 0.0,
        follower: Inputs::new(0.0, 0.0),
        mount: CameraMount::default(),
        observations: vec![Observation {
            robot: 1,
            points: 4,
            pose,
        }],
    };
    // Warm up past initialisation and the velocity transient.
    for _ in 0..60 {
        tracker.update(&frame).expect("update");
        frame.t += DT;
    }
    c.bench_function(id, |b| {
        b.iter(|| {
            frame.t += DT;
            std::hint::black_box(
                tracker
                    .update(std::hint::black_box(&frame))
                    .expect("update"),
            )
        })
    });
}

fn tracker_step(c: &mut Criterion) {
    bench_step(
        c,
        "formation-tracker/tracker_step",
        PoseMeasurement::Chosen(estimate(0.0)),
    );
    bench_step(
        c,
        "formation-tracker/tracker_step_candidates",
        PoseMeasurement::Candidates([estimate(0.0), estimate(0.6)]),
    );
}

/// Detect + pose + track on one pre-rendered 640x480 frame of the reference scene (leader
/// 1.5 m ahead, noise and blur on); rendering is outside the measurement.
fn frame_pipeline(c: &mut Criterion) {
    use fiducial::{Detector, DetectorConfig, Dictionary};
    use formation_sim::scene::{RobotSpec, SceneSpec, render_scene};
    use formation_tracker::pipeline::Pipeline;
    use formation_tracker::rig::RigModel;
    use formation_tracker::robots::RobotConfig;
    use unicycle::PlanarPose;

    let spec = SceneSpec {
        name: String::new(),
        camera_robot: PlanarPose::default(),
        mount: CameraMount::default(),
        camera: Default::default(),
        render: Default::default(),
        robots: vec![RobotSpec {
            robot: 1,
            x: 1.5,
            y: 0.25,
            theta: 0.0,
        }],
    };
    let rig = RigModel::reference();
    let image = render_scene(&spec, &rig, Dictionary::paper())
        .expect("render")
        .image;
    let k = pose::Intrinsics::from_hfov(60f64.to_radians(), 640, 480).expect("intrinsics");
    let mut pipeline = Pipeline::new(
        Detector::with_dictionary(DetectorConfig::default(), Dictionary::paper().clone()),
        pose::PoseSolver::new(k),
        (640, 480),
        rig,
        RobotConfig::default(),
        Tracker::new(TrackerConfig::reference(0.5, DT)).expect("reference config"),
    );
    let mut t = 0.0;
    let mut frame = || {
        t += DT;
        pipeline
            .process(
                image.as_raw(),
                640,
                480,
                t,
                Inputs::new(0.0, 0.0),
                CameraMount::default(),
            )
            .expect("frame")
    };
    let first = frame();
    assert_eq!(first.report.leaders.len(), 1, "the leader must be found");
    c.bench_function("formation-tracker/frame_pipeline_640x480", |b| {
        b.iter(|| std::hint::black_box(frame()))
    });
}

criterion_group!(benches, tracker_step, frame_pipeline);
criterion_main!(benches);
