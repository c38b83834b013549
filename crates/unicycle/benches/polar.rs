//! Speed of one RK4 step of the polar leader-follower model.

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use nalgebra::Vector2;
use unicycle::{PlanarPose, PolarModel};

fn polar_rk4_step(c: &mut Criterion) {
    let model = PolarModel::new(0.5).expect("valid offset");
    let x = model
        .state_from_poses(
            &PlanarPose::new(1.5, 0.25, 0.1),
            &PlanarPose::new(0.0, 0.0, 0.0),
        )
        .expect("valid poses");
    let u = Vector2::new(0.7, 0.05);
    let w = Vector2::new(0.8, 0.1);
    c.bench_function("unicycle/polar_rk4_step", |b| {
        b.iter(|| model.f(black_box(&x), black_box(&u), black_box(&w), 1.0 / 30.0))
    });
}

criterion_group!(benches, polar_rk4_step);
criterion_main!(benches);
