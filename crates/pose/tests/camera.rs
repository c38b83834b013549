//! Pinhole intrinsics, the OpenGL frustum and the projection Jacobians.

use nalgebra::{Point2, Point3, Vector3};
use pose::{Frustum, Intrinsics, Pose, PoseError};
use proptest::prelude::*;

fn frustum() -> impl Strategy<Value = Frustum> {
    (
        0.01f64..1.0,
        1.0f64..100.0,
        -1.0f64..-0.05,
        0.05f64..1.0,
        0.05f64..1.0,
        -1.0f64..-0.05,
        16u32..2000,
        16u32..2000,
    )
        .prop_map(|(near, far, l, r, t, b, width, height)| Frustum {
            near,
            far: near + far,
            left: l * near,
            right: r * near,
            top: t * near,
            bottom: b * near,
            width,
            height,
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// Spec 4.2: projecting through the OpenGL pipeline (projection matrix, clip, NDC,
    /// viewport) and through K gives the same pixel.
    #[test]
    fn frustum_pipeline_agrees_with_intrinsics(f in frustum(), sx in 0.0f64..1.0, sy in 0.0f64..1.0, sz in 0.0f64..1.0) {
        let k = f.intrinsics().unwrap();
        // A point inside the frustum: depth between near and far, inside the window.
        let z = f.near + sz * (f.far - f.near) * 0.999 + 1e-9;
        let x = (f.left + sx * (f.right - f.left)) * z / f.near;
        let y_up = f.bottom + sy * (f.top - f.bottom);
        let p = Point3::new(x, -y_up * z / f.near, z); // camera frame: y down
        let gl = f.project_gl(&p).unwrap();
        let pin = k.project(&p).unwrap();
        prop_assert!((gl - pin).norm() < 1e-7 * (1.0 + f64::from(f.width.max(f.height))), "gl {gl:?} pinhole {pin:?}");
    }

    #[test]
    fn pixel_normalized_round_trip(alpha in 100.0f64..2000.0, beta in 100.0f64..2000.0, theta in 1.2f64..1.9, u0 in 0.0f64..1000.0, v0 in 0.0f64..1000.0,
                                   u in -100.0f64..1100.0, v in -100.0f64..1100.0) {
        let k = Intrinsics::new(alpha, beta, theta, u0, v0).unwrap();
        let m = Point2::new(u, v);
        let back = k.normalized_to_pixel(&k.pixel_to_normalized(&m));
        prop_assert!((back - m).norm() < 1e-9);
        // The matrix and its parameters agree, and the matrix reads back.
        let km = k.matrix();
        let n = k.pixel_to_normalized(&m);
        let h = km * Vector3::new(n.x, n.y, 1.0);
        prop_assert!((Point2::new(h.x, h.y) - m).norm() < 1e-9);
        let k2 = Intrinsics::from_matrix(&km).unwrap();
        prop_assert!((k2.theta() - theta).abs() < 1e-12 && (k2.beta() - beta).abs() < 1e-9 * beta);
        // Back-projection lands on the ray.
        let p = k.back_project_at_depth(&m, 2.5);
        prop_assert!((k.project(&p).unwrap() - m).norm() < 1e-9);
    }

    #[test]
    fn projection_jacobians_match_finite_differences(theta in 1.3f64..1.8, w in prop::array::uniform3(-1.5f64..1.5),
                                                     p in prop::array::uniform3(-0.3f64..0.3)) {
        let k = Intrinsics::new(550.0, 540.0, theta, 320.0, 240.0).unwrap();
        let pose = Pose::new(Vector3::from(w), Vector3::new(0.1, -0.05, 1.5));
        let model = Point3::from(Vector3::from(p));
        let (m, j) = k.project_with_pose_jacobian(&pose, &model).unwrap();
        prop_assert!((m - k.project(&pose.transform_point(&model)).unwrap()).norm() < 1e-12);
        let x = pose.to_params();
        let h = 1e-6;
        for c in 0..6 {
            let mut d = x;
            d[c] += h;
            let plus = k.project(&Pose::from_params(&d).transform_point(&model)).unwrap();
            d[c] -= 2.0 * h;
            let minus = k.project(&Pose::from_params(&d).transform_point(&model)).unwrap();
            let fd = (plus - minus) / (2.0 * h);
            prop_assert!((fd - j.column(c)).norm() < 1e-5 * (1.0 + j.column(c).norm()), "column {c}: fd {fd:?} analytic {:?}", j.column(c));
        }
    }
}

#[test]
fn from_hfov_centres_the_principal_point() {
    let k = Intrinsics::from_hfov(60f64.to_radians(), 640, 480).unwrap();
    assert_eq!((k.u0(), k.v0()), (319.5, 239.5));
    assert!((k.alpha() - 320.0 / 30f64.to_radians().tan()).abs() < 1e-9);
    // A ray at half the field of view reaches the image edge, -0.5 (left edge of pixel 0).
    let edge = k
        .project(&Point3::new(-(30f64.to_radians().tan()), 0.0, 1.0))
        .unwrap();
    assert!((edge.x + 0.5).abs() < 1e-9);
}

#[test]
fn symmetric_frustum_matches_from_hfov() {
    let (w, h) = (640u32, 480u32);
    let near = 0.1;
    let half = near * 30f64.to_radians().tan();
    let vert = half * f64::from(h) / f64::from(w);
    let f = Frustum {
        near,
        far: 10.0,
        left: -half,
        right: half,
        top: vert,
        bottom: -vert,
        width: w,
        height: h,
    };
    let k = f.intrinsics().unwrap();
    let k2 = Intrinsics::from_hfov(60f64.to_radians(), w, h).unwrap();
    assert!((k.alpha() - k2.alpha()).abs() < 1e-9 && (k.beta() - k2.beta()).abs() < 1e-9);
    assert!((k.u0() - k2.u0()).abs() < 1e-9 && (k.v0() - k2.v0()).abs() < 1e-9);
}

#[test]
fn singular_intrinsics_are_rejected() {
    assert!(matches!(
        Intrinsics::new(0.0, 500.0, 1.57, 0.0, 0.0),
        Err(PoseError::InvalidIntrinsics { .. })
    ));
    assert!(matches!(
        Intrinsics::new(500.0, -1.0, 1.57, 0.0, 0.0),
        Err(PoseError::InvalidIntrinsics { .. })
    ));
    assert!(matches!(
        Intrinsics::new(500.0, 500.0, 0.0, 0.0, 0.0),
        Err(PoseError::InvalidIntrinsics { .. })
    ));
    assert!(matches!(
        Intrinsics::new(500.0, 500.0, 1.57, f64::NAN, 0.0),
        Err(PoseError::InvalidIntrinsics { .. })
    ));
    assert!(matches!(
        Intrinsics::from_hfov(0.0, 640, 480),
        Err(PoseError::InvalidFieldOfView { .. })
    ));
    assert!(matches!(
        Intrinsics::from_hfov(1.0, 0, 480),
        Err(PoseError::InvalidFieldOfView { .. })
    ));
    let mut k = Intrinsics::from_hfov(1.0, 640, 480).unwrap().matrix();
    k[(2, 0)] = 0.1;
    assert!(matches!(
        Intrinsics::from_matrix(&k),
        Err(PoseError::InvalidIntrinsics { .. })
    ));
    let bad = Frustum {
        near: 0.0,
        far: 1.0,
        left: -1.0,
        right: 1.0,
        top: 1.0,
        bottom: -1.0,
        width: 10,
        height: 10,
    };
    assert!(matches!(
        bad.intrinsics(),
        Err(PoseError::InvalidFrustum { .. })
    ));
    let flat = Frustum {
        near: 0.1,
        far: 1.0,
        left: 1.0,
        right: 1.0,
        top: 1.0,
        bottom: -1.0,
        width: 10,
        height: 10,
    };
    assert!(matches!(
        flat.intrinsics(),
        Err(PoseError::InvalidFrustum { .. })
    ));
}

#[test]
fn projecting_behind_the_camera_is_an_error() {
    let k = Intrinsics::from_hfov(1.0, 640, 480).unwrap();
    assert_eq!(
        k.project(&Point3::new(0.1, 0.1, -1.0)),
        Err(PoseError::PointBehindCamera { index: 0, z: -1.0 })
    );
    assert!(k.project(&Point3::new(0.1, 0.1, 0.0)).is_err());
    assert!(k.project(&Point3::new(0.1, 0.1, f64::NAN)).is_err());
}
