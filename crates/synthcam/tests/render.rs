//! Rendering: determinism, noise, blur, lighting, formats and bad input.
#![allow(clippy::unwrap_used)] // Tests may unwrap (house rules); helpers here are test code too.

use std::sync::Arc;

use nalgebra::{Point3, Vector3};
mod common;

use synthcam::*;
use unicycle::PlanarPose;

fn scene() -> Scene {
    let grid = Arc::new(
        CellGrid::from_bits(
            3,
            3,
            &[true, false, true, false, true, false, true, true, false],
        )
        .unwrap(),
    );
    let mut r = Robot::new(
        PlanarPose::new(1.5, 0.1, 0.3),
        Body::Box {
            length: 0.3,
            width: 0.3,
            height: 0.2,
            albedo: 0.3,
        },
    );
    for (i, p) in common::octagon_faces(0.16).unwrap().into_iter().enumerate() {
        r = r.with_face(Face::new(i as u32 + 1, p, grid.clone()));
    }
    let mut s = Scene::new(0.8);
    s.robots.push(r);
    s.ground = Some(Ground {
        texture: Arc::new(SoftChecker::new(0.4, 0.6).unwrap()),
        tile: 0.5,
    });
    s
}

fn camera(w: usize, h: usize) -> PosedCamera {
    let mount = common::mount(0.1, 0.3, 0.05, 0.05);
    common::camera(w, h, 60.0, &mount, PlanarPose::default()).unwrap()
}

fn noisy(seed: u64) -> RenderSettings {
    RenderSettings {
        noise_sigma: 3.0,
        seed,
        ..RenderSettings::default()
    }
}

#[test]
fn same_seed_gives_identical_bytes_and_different_seeds_differ() {
    let (s, c) = (scene(), camera(160, 120));
    let a = render(&s, &c, &noisy(7)).unwrap();
    let b = render(&s, &c, &noisy(7)).unwrap();
    assert_eq!(a.frame, b.frame);
    assert_eq!(a.truth, b.truth);
    let d = render(&s, &c, &noisy(8)).unwrap();
    let differing = a
        .frame
        .data
        .iter()
        .zip(&d.frame.data)
        .filter(|(x, y)| x != y)
        .count();
    assert!(
        differing > a.frame.data.len() / 2,
        "only {differing} pixels differ"
    );
    // The ground truth does not depend on the noise.
    assert_eq!(a.truth, d.truth);
}

#[test]
fn output_does_not_depend_on_the_number_of_threads() {
    let (s, c) = (scene(), camera(120, 90));
    let settings = RenderSettings {
        blur_sigma: 0.8,
        ..noisy(3)
    };
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let three = rayon::ThreadPoolBuilder::new()
        .num_threads(3)
        .build()
        .unwrap();
    let a = one.install(|| render(&s, &c, &settings)).unwrap();
    let b = three.install(|| render(&s, &c, &settings)).unwrap();
    assert_eq!(a.frame, b.frame);
}

#[test]
fn noise_has_the_requested_standard_deviation() {
    let (s, c) = (scene(), camera(160, 120));
    let clean = render(&s, &c, &RenderSettings::default()).unwrap();
    let dirty = render(&s, &c, &noisy(1)).unwrap();
    let diffs: Vec<f64> = clean
        .frame
        .data
        .iter()
        .zip(&dirty.frame.data)
        .filter(|(x, _)| (10..245).contains(*x))
        .map(|(&x, &y)| f64::from(y) - f64::from(x))
        .collect();
    let n = diffs.len() as f64;
    let mean = diffs.iter().sum::<f64>() / n;
    let sd = (diffs.iter().map(|d| (d - mean) * (d - mean)).sum::<f64>() / n).sqrt();
    assert!(mean.abs() < 0.1, "mean {mean}");
    // Rounding adds variance 1/12 to both images' difference; expect sqrt(9 + ~0.17).
    assert!((sd - 3.0).abs() < 0.15, "sd {sd}");
}

#[test]
fn rgb_output_has_three_channels_with_the_same_content() {
    let (s, c) = (scene(), camera(80, 60));
    let grey = render(&s, &c, &RenderSettings::default()).unwrap().frame;
    let rgb = render(
        &s,
        &c,
        &RenderSettings {
            format: PixelFormat::Rgb,
            ..RenderSettings::default()
        },
    )
    .unwrap()
    .frame;
    assert_eq!(rgb.data.len(), 3 * grey.data.len());
    for (g, px) in grey.data.iter().zip(rgb.data.chunks(3)) {
        assert!(px.iter().all(|c| c == g));
    }
    let mut pnm = Vec::new();
    rgb.write_pnm(&mut pnm).unwrap();
    assert!(pnm.starts_with(b"P6\n80 60\n255\n"));
    assert_eq!(pnm.len(), b"P6\n80 60\n255\n".len() + rgb.data.len());
}

#[test]
fn blur_keeps_the_mean_and_softens_edges() {
    let (s, c) = (scene(), camera(160, 120));
    let sharp = render(&s, &c, &RenderSettings::default()).unwrap().frame;
    let soft = render(
        &s,
        &c,
        &RenderSettings {
            blur_sigma: 1.5,
            ..RenderSettings::default()
        },
    )
    .unwrap()
    .frame;
    let mean = |f: &Frame| f.data.iter().map(|&x| f64::from(x)).sum::<f64>() / f.data.len() as f64;
    assert!((mean(&sharp) - mean(&soft)).abs() < 0.5);
    let max_step = |f: &Frame| {
        (0..f.height)
            .flat_map(|v| (1..f.width).map(move |u| (u, v)))
            .map(|(u, v)| {
                (i32::from(f.grey(u, v).unwrap()) - i32::from(f.grey(u - 1, v).unwrap())).abs()
            })
            .max()
            .unwrap()
    };
    assert!(
        max_step(&soft) * 2 < max_step(&sharp),
        "{} vs {}",
        max_step(&soft),
        max_step(&sharp)
    );
}

#[test]
fn gradient_darkens_from_one_side_to_the_other() {
    // Nothing but background: the image is the light factor itself.
    let s = Scene::new(1.0);
    let c = camera(101, 11);
    let settings = RenderSettings {
        gradient: Some(Gradient {
            from: 1.0,
            to: 0.5,
            angle: 0.0,
        }),
        ..RenderSettings::default()
    };
    let f = render(&s, &c, &settings).unwrap().frame;
    let row: Vec<u8> = (0..101).map(|u| f.grey(u, 5).unwrap()).collect();
    assert!(row.windows(2).all(|w| w[0] >= w[1]));
    // Factor 1 at the left edge of the image (u = -0.5), 0.5 at the right edge: pixel centres
    // sit half a pixel inside.
    assert!((f64::from(row[0]) - 255.0 * (1.0 - 0.5 * 0.5 / 101.0)).abs() <= 1.0);
    assert!((f64::from(row[100]) - 255.0 * (0.5 + 0.5 * 0.5 / 101.0)).abs() <= 1.0);
    assert_eq!(row[50], 191); // 255 * 0.75, rounded
    // Vertical gradient: the columns are uniform, rows change.
    let settings = RenderSettings {
        gradient: Some(Gradient {
            from: 0.2,
            to: 1.0,
            angle: std::f64::consts::FRAC_PI_2,
        }),
        ..RenderSettings::default()
    };
    let f = render(&s, &c, &settings).unwrap().frame;
    assert_eq!(f.grey(0, 3), f.grey(100, 3));
    assert!(f.grey(0, 0).unwrap() < f.grey(0, 10).unwrap());
}

#[test]
fn marker_faces_stay_unshaded_by_default_but_bodies_are_shaded() {
    let s = scene();
    let c = camera(160, 120);
    let unshaded = RenderSettings {
        shading: None,
        ..RenderSettings::default()
    };
    let shaded = RenderSettings::default();
    let truth = ground_truth(&s, &c).unwrap();
    let f = truth.robots[0].faces.iter().find(|f| f.visible).unwrap();
    let centre = c.project(&f.centre_camera).unwrap();
    let (u, v) = (centre.x.round() as usize, centre.y.round() as usize);
    let a = render(&s, &c, &unshaded).unwrap().frame;
    let b = render(&s, &c, &shaded).unwrap().frame;
    assert_eq!(a.grey(u, v), b.grey(u, v));
    // Some other pixels (body, ground) do change.
    assert!(a.data != b.data);
}

#[test]
fn bad_input_is_a_typed_error() {
    let (s, c) = (scene(), camera(32, 24));
    let ok = RenderSettings::default();
    let with = |f: &dyn Fn(&mut RenderSettings)| {
        let mut x = ok;
        f(&mut x);
        render(&s, &c, &x)
    };
    assert!(matches!(
        with(&|x| x.supersampling = 0),
        Err(SynthError::InvalidSupersampling { n: 0, .. })
    ));
    assert!(matches!(
        with(&|x| x.supersampling = 1000),
        Err(SynthError::InvalidSupersampling { .. })
    ));
    assert!(matches!(
        with(&|x| x.noise_sigma = -1.0),
        Err(SynthError::NegativeSigma { .. })
    ));
    assert!(matches!(
        with(&|x| x.blur_sigma = -0.5),
        Err(SynthError::NegativeSigma { .. })
    ));
    assert!(matches!(
        with(&|x| x.blur_sigma = f64::NAN),
        Err(SynthError::NonFinite { .. })
    ));
    assert!(matches!(
        with(&|x| x.gain = f64::INFINITY),
        Err(SynthError::NonFinite { .. })
    ));
    assert!(
        with(&|x| x.gradient = Some(Gradient {
            from: 1.0,
            to: -0.5,
            angle: 0.0
        }))
        .is_err()
    );
    assert!(
        with(&|x| x.shading = Some(Shading {
            light_dir: Vector3::zeros(),
            ..Shading::default()
        }))
        .is_err()
    );

    let mut bad = scene();
    bad.robots[0].pose.theta = f64::NAN;
    assert!(matches!(
        render(&bad, &c, &ok),
        Err(SynthError::NonFinite { .. })
    ));
    let mut bad = scene();
    bad.robots[0].pose.x = f64::INFINITY;
    assert!(matches!(
        ground_truth(&bad, &c),
        Err(SynthError::NonFinite { .. })
    ));
    let mut bad = scene();
    bad.robots[0].faces[1].placement.width = -1.0;
    assert!(matches!(
        render(&bad, &c, &ok),
        Err(SynthError::NotPositive { .. })
    ));
    let mut bad = scene();
    bad.robots[0].body = Body::Cylinder {
        radius: 0.2,
        height: 0.0,
        albedo: 0.3,
    };
    assert!(matches!(
        render(&bad, &c, &ok),
        Err(SynthError::NotPositive { .. })
    ));
    let mut bad = scene();
    bad.background = 2.0;
    assert!(matches!(
        render(&bad, &c, &ok),
        Err(SynthError::OutOfRange { .. })
    ));
    let mut bad = scene();
    if let Some(g) = bad.ground.as_mut() {
        g.tile = 0.0;
    }
    assert!(render(&bad, &c, &ok).is_err());

    // Coordinates so large the projection would overflow are refused.
    let mut bad = scene();
    bad.robots[0].pose.x = 1e300;
    assert!(matches!(
        render(&bad, &c, &ok),
        Err(SynthError::TooLarge { .. })
    ));
    let huge_k = pose::Intrinsics::square_pixels(1e200, 1e200, 10.0, 10.0).unwrap();
    let id = nalgebra::Isometry3::identity();
    assert!(matches!(
        PosedCamera::new(huge_k, 20, 20, id),
        Err(SynthError::TooLarge { .. })
    ));
    let far = common::mount(-1e12, 0.3, 0.0, 0.0);
    let (w, h) = (c.width(), c.height());
    assert!(matches!(
        PosedCamera::on_robot(*c.intrinsics(), w, h, &far, &PlanarPose::default()),
        Err(SynthError::TooLarge { .. })
    ));
    assert!(matches!(
        PosedCamera::new(*c.intrinsics(), 20, 0, id),
        Err(SynthError::ZeroImageSize { .. })
    ));
    assert!(matches!(
        PosedCamera::new(*c.intrinsics(), 0, 0, id),
        Err(SynthError::ZeroImageSize { .. })
    ));
    let nan_pose = nalgebra::Isometry3::translation(f64::NAN, 0.0, 0.0);
    assert!(matches!(
        PosedCamera::new(*c.intrinsics(), w, h, nan_pose),
        Err(SynthError::NonFinite { .. })
    ));
    assert!(
        PosedCamera::look_at(
            *c.intrinsics(),
            w,
            h,
            Point3::origin(),
            Point3::new(f64::NAN, 0.0, 0.0),
            Vector3::z()
        )
        .is_err()
    );
    let mount = common::mount(0.1, f64::NAN, 0.0, 0.0);
    assert!(matches!(
        PosedCamera::on_robot(*c.intrinsics(), w, h, &mount, &PlanarPose::default()),
        Err(SynthError::NonFinite { .. })
    ));
}

#[test]
fn camera_inside_nothing_and_looking_at_the_sky_renders_background() {
    let s = scene();
    let mount = common::mount(0.0, 0.3, 0.0, -1.4); // looking almost straight up
    let c = common::camera(40, 30, 30.0, &mount, PlanarPose::new(-5.0, 0.0, 0.0)).unwrap();
    let f = render(&s, &c, &RenderSettings::default()).unwrap().frame;
    assert!(f.data.iter().all(|&x| x == 204)); // 0.8 * 255
}

/// One sub-frame is exactly `render`; sub-frames of a moving robot change the frame and keep
/// the middle view's truth; no sub-frame is an error.
#[test]
fn an_exposure_of_one_view_is_a_render_and_motion_blurs() {
    let settings = noisy(4);
    let cam = camera(160, 120);
    let still = scene();
    let one = render_exposure(&[(&still, &cam)], &settings).unwrap();
    let plain = render(&still, &cam, &settings).unwrap();
    assert_eq!(one.frame, plain.frame);
    assert_eq!(one.truth, plain.truth);
    let moved = |dy: f64| {
        let mut s = scene();
        s.robots[0].pose.y += dy;
        s
    };
    let scenes = [moved(-0.02), scene(), moved(0.02)];
    let views: Vec<(&Scene, &PosedCamera)> = scenes.iter().map(|s| (s, &cam)).collect();
    let blurred = render_exposure(&views, &settings).unwrap();
    assert_eq!(blurred.truth, plain.truth);
    assert_ne!(blurred.frame, plain.frame);
    assert!(render_exposure(&[], &settings).is_err());
}
