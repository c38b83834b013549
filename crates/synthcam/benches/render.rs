//! Rendering speed: a 640 x 480 frame of two leader robots with octagon rigs of cell-grid
//! markers, on a soft-checker ground, with shading, at 4 (2 x 2) and 16 (4 x 4) samples per
//! pixel. The target is at most 50 ms per 4-sample frame on 2 cores.

use std::hint::black_box;
use std::sync::Arc;

use criterion::{Criterion, criterion_group, criterion_main};
#[path = "../tests/common/mod.rs"]
mod common;

use synthcam::{Body, CellGrid, Face, Ground, RenderSettings, Robot, Scene, SoftChecker, render};
use unicycle::PlanarPose;

fn marker(seed: u64) -> CellGrid {
    // 8 x 9 cells: quiet zone, border, pseudo-random data cells (a fixed LCG).
    let mut x = seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
    let mut black = vec![false; 72];
    for r in 1..7 {
        for c in 1..8 {
            x = x
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            black[r * 9 + c] = r == 1 || r == 6 || c == 1 || c == 7 || (x >> 63) == 1;
        }
    }
    CellGrid::from_bits(8, 9, &black).expect("8 x 9 grid")
}

fn scene() -> Scene {
    let mut s = Scene::new(0.85);
    s.ground = Some(Ground {
        texture: Arc::new(SoftChecker::new(0.42, 0.58).expect("valid")),
        tile: 1.0,
    });
    for (k, pose) in [
        PlanarPose::new(1.6, 0.45, 0.5),
        PlanarPose::new(2.2, -0.5, -0.4),
    ]
    .into_iter()
    .enumerate()
    {
        let mut r = Robot::new(
            pose,
            Body::Cylinder {
                radius: 0.2,
                height: 0.2,
                albedo: 0.35,
            },
        );
        for (i, p) in common::octagon_faces(0.16)
            .expect("valid")
            .into_iter()
            .enumerate()
        {
            r = r.with_face(Face::new(
                i as u32 + 1,
                p,
                Arc::new(marker((k * 5 + i) as u64)),
            ));
        }
        s.robots.push(r);
    }
    s
}

fn bench(c: &mut Criterion) {
    let s = scene();
    let mount = common::mount(0.1, 0.3, 0.0, 0.0);
    let cam = common::camera(640, 480, 60.0, &mount, PlanarPose::default()).expect("valid camera");
    for (name, n) in [
        ("synthcam/render_640x480_ss4", 2),
        ("synthcam/render_640x480_ss16", 4),
    ] {
        let settings = RenderSettings {
            supersampling: n,
            noise_sigma: 2.0,
            seed: 1,
            ..RenderSettings::default()
        };
        c.bench_function(name, |b| {
            b.iter(|| render(black_box(&s), black_box(&cam), black_box(&settings)).expect("render"))
        });
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
