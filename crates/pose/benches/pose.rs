//! Criterion benchmarks of the pose solvers on seeded random views of the reference camera
//! (640x480, 60 degree HFOV) with 0.3 px Gaussian corner noise.

use criterion::{Criterion, criterion_group, criterion_main};
use nalgebra::{Point2, Point3, Rotation3, Vector3};
use pose::{Intrinsics, Pose, PoseSolver};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use std::hint::black_box;

const CASES: usize = 64;

fn camera() -> Intrinsics {
    Intrinsics::from_hfov(60f64.to_radians(), 640, 480).expect("valid camera")
}

fn face() -> Vec<Point3<f64>> {
    let (w, h) = (0.07, 0.06);
    vec![
        Point3::new(-w, -h, 0.0),
        Point3::new(w, -h, 0.0),
        Point3::new(w, h, 0.0),
        Point3::new(-w, h, 0.0),
    ]
}

/// Markers (140 x 120 mm) on faces 2, 3, 4 of the reference octagon (0.18 m faces).
fn three_faces() -> Vec<Point3<f64>> {
    let apothem = 0.09 / (std::f64::consts::PI / 8.0).tan();
    let mut pts = Vec::new();
    for yaw in [135f64, 180.0, -135.0] {
        let n = Vector3::new(yaw.to_radians().cos(), yaw.to_radians().sin(), 0.0);
        let tangent = Vector3::z().cross(&n);
        let c = n * apothem + Vector3::new(0.0, 0.0, 0.3);
        for (a, b) in [(-1.0, 1.0), (1.0, 1.0), (1.0, -1.0), (-1.0, -1.0)] {
            pts.push(Point3::from(
                c + tangent * (0.07 * a) + Vector3::z() * (0.06 * b),
            ));
        }
    }
    pts
}

fn noisy(
    k: &Intrinsics,
    pose: &Pose,
    model: &[Point3<f64>],
    rng: &mut ChaCha8Rng,
) -> Vec<Point2<f64>> {
    let noise = Normal::new(0.0, 0.3).expect("valid sigma");
    model
        .iter()
        .map(|p| {
            let m = k
                .project(&pose.transform_point(p))
                .expect("in front of the camera");
            Point2::new(m.x + noise.sample(rng), m.y + noise.sample(rng))
        })
        .collect()
}

fn bench(c: &mut Criterion) {
    let k = camera();
    let solver = PoseSolver::new(k);
    let mut rng = ChaCha8Rng::seed_from_u64(42);

    // One face: 0.5 to 2.5 m, tilted 0 to 60 degrees.
    let model = face();
    let views: Vec<Vec<Point2<f64>>> = (0..CASES)
        .map(|_| {
            let z = rng.random_range(0.5..2.5);
            let tilt = rng.random_range(0.0..60f64.to_radians());
            let phi = rng.random_range(-3.1..3.1f64);
            let r = Rotation3::from_axis_angle(&Vector3::z_axis(), rng.random_range(-3.1..3.1))
                * Rotation3::from_scaled_axis(Vector3::new(phi.cos(), phi.sin(), 0.0) * tilt);
            let pose = Pose::from_matrix(
                r.matrix(),
                Vector3::new(
                    0.2 * z * rng.random_range(-1.0..1.0),
                    0.15 * z * rng.random_range(-1.0..1.0),
                    z,
                ),
            );
            noisy(&k, &pose, &model, &mut rng)
        })
        .collect();
    let mut i = 0;
    c.bench_function("pose/one_face_4pts", |b| {
        b.iter(|| {
            i = (i + 1) % CASES;
            black_box(solver.solve(black_box(&model), black_box(&views[i])).ok())
        })
    });

    // Three faces of the rig seen from behind, leader yaw +-50 degrees, 0.8 to 3 m.
    let rig = three_faces();
    let base = Rotation3::from_matrix_unchecked(nalgebra::Matrix3::new(
        0.0, -1.0, 0.0, 0.0, 0.0, -1.0, 1.0, 0.0, 0.0,
    ));
    let rig_views: Vec<(Pose, Vec<Point2<f64>>)> = (0..CASES)
        .map(|_| {
            let r = base
                * Rotation3::from_euler_angles(
                    0.0,
                    0.0,
                    rng.random_range(-50f64..50.0).to_radians(),
                );
            let z = rng.random_range(0.8..3.0);
            let pose = Pose::from_matrix(
                r.matrix(),
                Vector3::new(0.2 * z * rng.random_range(-1.0..1.0), 0.1 * z, z),
            );
            let image = noisy(&k, &pose, &rig, &mut rng);
            (pose, image)
        })
        .collect();
    let mut j = 0;
    c.bench_function("pose/three_faces_12pts_lm", |b| {
        b.iter(|| {
            j = (j + 1) % CASES;
            black_box(
                solver
                    .solve(black_box(&rig), black_box(&rig_views[j].1))
                    .ok(),
            )
        })
    });

    // A tracker's refinement from a prediction 0.05 rad / 5 cm off.
    let mut l = 0;
    c.bench_function("pose/three_faces_12pts_refine", |b| {
        b.iter(|| {
            l = (l + 1) % CASES;
            let (truth, image) = &rig_views[l];
            let start = Pose::new(
                truth.rotation + Vector3::new(0.03, -0.04, 0.0),
                truth.translation + Vector3::new(0.05, 0.0, -0.03),
            );
            black_box(
                solver
                    .refine(black_box(&rig), black_box(image), &start)
                    .ok(),
            )
        })
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
